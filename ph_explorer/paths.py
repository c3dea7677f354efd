"""Where the shipped assets (scenarios, data, trained models, the example effects file) live.

In a source checkout they are the repository's assets/ folder; in an installed package they are
ph_explorer.assets (mapped by pyproject.toml).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

_REPO_ROOT = Path(__file__).resolve().parent.parent


def assets_dir() -> Path:
    """The shipped assets folder (scenarios/, data/, models/, effects_example.py)."""
    checkout = _REPO_ROOT / "assets"
    if (checkout / "__init__.py").is_file():
        return checkout
    return Path(str(resources.files("ph_explorer.assets")))


def scenarios_dir() -> Path:
    return assets_dir() / "scenarios"


def models_dir() -> Path:
    """The folder of shipped trained models (models/paper, ...)."""
    return assets_dir() / "models"


def default_model_dir() -> Path:
    return models_dir() / "paper"
