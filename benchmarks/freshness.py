"""Which of results.json's figures describe this checkout: `python -m benchmarks --stale`.

A section's figures depend on the modules its benchmark can import: read with ast, every import
statement anywhere in a file (a lazy import counts), from the section's module (or, for the
sections benchmarks/run.py measures itself, its function there) and run.py's own imports. Each
section is stamped with the commit it was measured at (results.json "updated", else the full run's
"commit"). Its figures describe this checkout when none of those ph_explorer modules' code differs
between that commit and the working tree (compared as syntax trees without docstrings: a docstring,
a comment or a layout changes no figure): a change elsewhere (the explorer, the CLI, the text a
verdict is worded in) leaves them measured. A benchmarks module that changed is named beside: the
code measured is the same, the way its figures are made may not be.
"""

from __future__ import annotations

import ast
import functools
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("ph_explorer", "benchmarks")
RUNNER = "benchmarks.run"
# Each section's roots: its module, or "run:FUNCTION" for a section run.py measures in FUNCTION;
# beside it, the command line for a section that times `python -m ph_explorer` in a process of its own.
COMMAND = "ph_explorer.__main__"
SECTION_ROOTS: dict[str, str | tuple[str, ...]] = {
    "data_efficiency": "run:run_data_efficiency",
    "speed": ("run:run_speed", COMMAND),
    "scale": ("run:run_speed", COMMAND),
    "diagnosis_calibration": "benchmarks.calibration",
    "hidden_effects": "benchmarks.hidden_effects",
    "population": "benchmarks.population",
    "population_unknown": "benchmarks.unknown_population",
    "adaptive_campaign": "benchmarks.adaptive_campaign",
    "verdict_speed": ("benchmarks.population", COMMAND),
    "deciding": "benchmarks.deciding",
    "uncertainty_coverage": "benchmarks.uncertainty_coverage",
    "large_campaign": "benchmarks.large_campaign",
    "fleet": "benchmarks.fleet",
    "peers": "benchmarks.peers",
}


def _git(root: Path, *args: str, stdin: str | None = None) -> str:
    return subprocess.run(["git", *args], cwd=root, input=stdin, capture_output=True, text=True, check=True).stdout


def sources(commit: str | None = None, root: Path = ROOT) -> tuple[dict[str, str], set[str]]:
    """Module name -> source of the two packages, at a commit (None: the working tree), and which
    of the modules are packages (an __init__.py)."""
    if commit is None:
        paths = [str(p.relative_to(root)) for package in PACKAGES for p in sorted((root / package).rglob("*.py"))]
        read = {path: (root / path).read_text(encoding="utf-8") for path in paths}
    else:
        listed = [line.split("\t") for line in _git(root, "ls-tree", "-r", commit, "--", *PACKAGES).splitlines()]
        blobs = [(entry.split()[2], path) for entry, path in listed if path.endswith(".py")]
        # One `git cat-file --batch` for every blob: "<sha> blob <size>\n<content>\n" each.
        batch = _git(root, "cat-file", "--batch", stdin="".join(f"{sha}\n" for sha, _ in blobs)).encode()
        read, at = {}, 0
        for _, path in blobs:
            header_end = batch.index(b"\n", at)
            size = int(batch[at:header_end].split()[2])
            read[path] = batch[header_end + 1 : header_end + 1 + size].decode("utf-8")
            at = header_end + 2 + size
    known = {path[:-3].replace("/", ".").removesuffix(".__init__"): text for path, text in read.items()}
    return known, {path[:-12].replace("/", ".") for path in read if path.endswith("/__init__.py")}


@functools.cache
def code_of(source: str | None) -> str | None:
    """A module's code, its docstrings, comments and layout aside: its syntax tree without them."""
    if source is None:
        return None
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body:
            first = body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree)


@functools.cache
def _imports_in(source: str, module: str, is_package: bool) -> frozenset[str]:
    """The modules a file's import statements name, anywhere in it (parsed once per text)."""
    return frozenset(_named(list(ast.walk(ast.parse(source))), module, is_package))


def _named(nodes: list[ast.AST], module: str, is_package: bool) -> set[str]:
    """The modules the import statements among nodes name (a `from X import y` names X and X.y)."""
    package = module if is_package else module.rpartition(".")[0]
    named: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            named |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            named |= {base} | {f"{base}.{alias.name}" for alias in node.names}
    return named


def _resolved(names: set[str], known: dict[str, str]) -> set[str]:
    """The known modules that importing names runs: each module and the packages above it."""
    out = set()
    for name in names:
        parts = name.split(".")
        out |= {".".join(parts[:cut]) for cut in range(1, len(parts) + 1) if ".".join(parts[:cut]) in known}
    return out


def closure(roots: set[str], known: dict[str, str], is_package: dict[str, bool]) -> set[str]:
    """Every known module that importing roots can run."""
    seen: set[str] = set()
    todo = list(_resolved(roots, known))
    while todo:
        module = todo.pop()
        if module in seen:
            continue
        seen.add(module)
        todo += _resolved(set(_imports_in(known[module], module, is_package[module])), known) - seen
    return seen


def section_modules(section: str, known: dict[str, str], packages: set[str]) -> set[str]:
    """The modules a section's figures depend on (the module docstring); packages: which are packages."""
    is_package = {m: m in packages for m in known}
    runner = ast.parse(known[RUNNER])
    roots = _named([n for n in runner.body if isinstance(n, (ast.Import, ast.ImportFrom))], RUNNER, False)
    given = SECTION_ROOTS[section]
    for root in (given,) if isinstance(given, str) else given:
        if root.startswith("run:"):
            function = next(n for n in runner.body if isinstance(n, ast.FunctionDef) and n.name == root[4:])
            roots |= _named(list(ast.walk(function)), RUNNER, False)
        else:
            roots.add(root)
    return closure(roots, known, is_package)


@dataclass(frozen=True)
class SectionState:
    """One section's figures against this checkout."""

    section: str
    commit: str
    date: str
    changed: tuple[str, ...]  # ph_explorer modules it depends on that differ since its commit
    benchmark_changed: tuple[str, ...]  # benchmarks modules likewise
    depends: int = 0  # the ph_explorer modules it depends on
    known: bool = True  # False: measured on uncommitted changes or at a commit this clone lacks

    def line(self) -> str:
        at = f"{self.section}: measured {self.date} at {self.commit}"
        if not self.known:
            return f"{at}: unknown (uncommitted changes, or a commit this clone does not hold)"
        state = "describes this checkout"
        if self.changed:
            state = f"stale, {len(self.changed)} of the {self.depends} ph_explorer modules it depends on changed since: " + _few(
                self.changed
            )
        if self.benchmark_changed:
            state += "; its benchmark changed since: " + _few(self.benchmark_changed)
        return f"{at}: {state}"


def _few(modules: tuple[str, ...], shown: int = 4) -> str:
    names = ", ".join(m.split(".", 1)[-1] for m in modules[:shown])
    return names + (f" and {len(modules) - shown} more" if len(modules) > shown else "")


def states(results: dict[str, Any], root: Path = ROOT) -> list[SectionState]:
    """Each section of results.json that holds figures, against the working tree of root."""
    now, packages = sources(root=root)
    stamps = {
        name: {"commit": results.get("commit", "unknown"), "date": results.get("date", "?")} for name in SECTION_ROOTS if name in results
    }
    stamps |= {name: stamp for name, stamp in results.get("updated", {}).items() if name in SECTION_ROOTS}
    cache: dict[str, tuple[dict[str, str], set[str]] | None] = {}
    out = []
    for name, stamp in stamps.items():
        commit = str(stamp.get("commit", "unknown"))
        if commit not in cache:
            try:
                cache[commit] = None if "+" in commit or commit == "unknown" else sources(commit, root)
            except (OSError, subprocess.CalledProcessError):
                cache[commit] = None
        held = cache[commit]
        if held is None:
            out.append(SectionState(name, commit, str(stamp.get("date", "?")), (), (), known=False))
            continue
        then, then_packages = held
        depends = section_modules(name, now, packages) | section_modules(name, then, then_packages)
        differ = sorted(m for m in depends if code_of(now.get(m)) != code_of(then.get(m)))
        out.append(
            SectionState(
                name,
                commit,
                str(stamp.get("date", "?")),
                tuple(m for m in differ if m.startswith("ph_explorer")),
                tuple(m for m in differ if m.startswith("benchmarks")),
                sum(m.startswith("ph_explorer") for m in depends),
            )
        )
    return out
