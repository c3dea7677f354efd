"""The documentation site builds with mkdocs --strict: a broken link, a missing page or a reference
to a name the code no longer has fails here, as the README's links to the site would."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_the_site_builds_strictly(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    site = tmp_path / "site"
    # The generated pages hold what the code and the results hold, not a hand copy.
    benchmarks = (site / "benchmarks" / "index.html").read_text(encoding="utf-8")
    assert re.search(r"\d+\.\d+", benchmarks)
    # the verdicts' promises carry the population's measured rates, written from results.json
    diagnosis = (site / "diagnosis" / "index.html").read_text(encoding="utf-8")
    assert "verdict-rates" not in diagnosis
    population = json.loads((ROOT / "benchmarks" / "results.json").read_text(encoding="utf-8"))["population"]
    healthy = population["healthy"]["verdicts"]
    assert f"{healthy.get('none', 0)} of {sum(healthy.values())}" in diagnosis
    cli = (site / "cli" / "index.html").read_text(encoding="utf-8")
    assert all(command in cli for command in ("inspect", "simulate", "train", "evaluate", "diagnose", "design", "serve"))


def test_the_readme_stays_short_and_holds_the_two_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    assert "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/ph-explorer serve" in readme
    assert 'python3 -m venv .venv && .venv/bin/pip install ".[test]" && .venv/bin/python -m pytest' in readme


def test_the_readme_links_resolve():
    """Every relative link of the README names a file of the repository (GitHub shows them)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = [t.split("#")[0] for t in re.findall(r"\]\(([^)\s]+)\)", readme) if not re.match(r"[a-z]+:", t)]
    assert targets, "the README links to its docs"
    missing = [t for t in targets if t and not (ROOT / t).exists()]
    assert not missing, missing
