"""Where the shipped assets (scenarios, data, the example effects file) and trained models live.

In a source checkout they are the repository's assets/ and model/ folders; in an installed
package they are ph_explorer.assets and ph_explorer.model (mapped by pyproject.toml).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

_REPO_ROOT = Path(__file__).resolve().parent.parent


def _located(name: str) -> Path:
    checkout = _REPO_ROOT / name
    if (checkout / "__init__.py").is_file():
        return checkout
    return Path(str(resources.files(f"ph_explorer.{name}")))


def assets_dir() -> Path:
    """The shipped assets folder (scenarios/, data/, effects_example.py)."""
    return _located("assets")


def scenarios_dir() -> Path:
    return assets_dir() / "scenarios"


def models_dir() -> Path:
    """The folder of shipped trained models (model/paper, ...)."""
    return _located("model")


def default_model_dir() -> Path:
    return models_dir() / "paper"
