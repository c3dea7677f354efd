"""The package's layout holds: arrows point one way, viser stays in the app, effects stay in effects/.

Read from the source with ast (nothing is imported), so a test fails on the line that breaks the rule.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from ph_explorer.effects import DEFAULT_CATALOG

PACKAGE = Path(__file__).resolve().parent.parent / "ph_explorer"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imported_names(path: Path) -> list[tuple[str, int]]:
    """Every module an import statement names (anywhere in the file), with its line."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            found.append((base, node.lineno))
            # `from ph_explorer.models import design` imports the module ph_explorer.models.least_squares.
            found += [(f"{base}.{alias.name}", node.lineno) for alias in node.names if f"{base}.{alias.name}" in MODULES]
    return found


def internal_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports (a name resolves to the longest module prefix)."""
    graph: dict[str, set[str]] = {}
    for name, path in MODULES.items():
        targets = set()
        for imported, _ in imported_names(path):
            parts = imported.split(".")
            for cut in range(len(parts), 0, -1):
                candidate = ".".join(parts[:cut])
                if candidate in MODULES:
                    if candidate != name:
                        targets.add(candidate)
                    break
        graph[name] = targets
    return graph


def is_package_init(name: str) -> bool:
    return name in MODULES and MODULES[name].name == "__init__.py"


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of imports between modules, or None. A package's __init__ re-exporting its own
    submodules is not an edge back to it (importing a submodule runs the parent's __init__ first)."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for target in sorted(graph[node]):
            if is_package_init(target) and node.startswith(target + "."):
                continue  # a submodule importing its own package's __init__ (usually a sibling)
            if state.get(target) == 1:
                return stack[stack.index(target) :] + [target]
            if state.get(target) is None:
                cycle = visit(target)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_there_is_no_import_cycle():
    graph = internal_graph()
    assert {"ph_explorer.diagnosis.loop", "ph_explorer.cli", "ph_explorer.app.server"} <= set(graph)
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_the_cycle_finder_finds_a_cycle():
    # The rule above must be able to fail.
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_viser_is_imported_only_in_the_app():
    offenders = [
        f"{path.relative_to(PACKAGE.parent)}:{line}"
        for name, path in MODULES.items()
        if not name.startswith("ph_explorer.app")
        for imported, line in imported_names(path)
        if imported == "viser" or imported.startswith("viser.")
    ]
    assert not offenders, offenders


# The layers, lowest first: a module may import its own layer and those below, never one above.
# The basic modules (geometry, campaign, kinematics, harmonics, metrics, errors, paths, blas, task_runner) and
# the package's own __init__ are the floor. The app and the command line translate: both sit on
# top, and the app never imports the command line (test below).
LAYERS = ("io", "effects", "twin", "models", "uncertainty", "paper", "diagnosis", "planning", "figures", "app", "cli")
BASIC = {"geometry", "campaign", "kinematics", "harmonics", "metrics", "errors", "paths", "blas", "task_runner"}


def layer_of(name: str) -> int:
    """The rank of a module's layer: -1 for the floor, else its index in LAYERS."""
    parts = name.split(".")
    if len(parts) == 1 or parts[1] in BASIC:
        return -1
    room = "cli" if parts[1] == "__main__" else parts[1]
    assert room in LAYERS, f"{name} sits in no layer: add its room to LAYERS or move it"
    return LAYERS.index(room)


def layer_offenders(graph: dict[str, set[str]]) -> list[str]:
    return [
        f"{name} ({LAYERS[layer_of(name)] if layer_of(name) >= 0 else 'floor'}) imports {target}"
        for name, targets in sorted(graph.items())
        for target in sorted(targets)
        if layer_of(target) > layer_of(name) and not (name.startswith("ph_explorer.cli") and target.startswith("ph_explorer.app"))
    ]


def test_every_import_follows_the_layer_order():
    graph = internal_graph()
    assert {layer_of(name) for name in graph} >= set(range(len(LAYERS) - 1)), "a layer has no module"
    assert not layer_offenders(graph), layer_offenders(graph)


def test_the_layer_rule_can_fail():
    assert layer_offenders({"ph_explorer.models.hybrid": {"ph_explorer.diagnosis.results"}}) == [
        "ph_explorer.models.hybrid (models) imports ph_explorer.diagnosis.results"
    ]
    assert layer_offenders({"ph_explorer.geometry": {"ph_explorer.io.reader"}}) == [
        "ph_explorer.geometry (floor) imports ph_explorer.io.reader"
    ]
    assert not layer_offenders({"ph_explorer.figures.polar": {"ph_explorer.diagnosis.results", "ph_explorer.geometry"}})


def test_no_two_modules_share_a_name():
    """A module's file name says what it is, once: `design.py` in two rooms reads as one thing."""
    seen: dict[str, list[str]] = {}
    for name, path in MODULES.items():
        if path.name not in ("__init__.py", "__main__.py"):
            seen.setdefault(path.stem, []).append(name)
    packages = {name.rpartition(".")[2] for name in MODULES if is_package_init(name)}
    shared = {stem: names for stem, names in seen.items() if len(names) > 1 or stem in packages}
    assert not shared, shared


def test_experiment_code_stays_out_of_the_product():
    """What only a benchmark uses lives with the benchmarks; nothing in the package imports them."""
    offenders = [
        f"{path.relative_to(PACKAGE.parent)}:{line} imports {imported}"
        for path in MODULES.values()
        for imported, line in imported_names(path)
        if imported == "benchmarks" or imported.startswith("benchmarks.")
    ]
    assert not offenders, offenders


EXPERIMENTS = ("benchmarks.carried", "benchmarks.stacking")  # the experiment code only a benchmark uses


def test_the_test_suite_leaves_the_experiment_code_to_its_own_checks():
    """tests/ tests the product; the experiment code is checked beside it (benchmarks/experiment_checks.py)."""
    offenders = [
        f"{path.relative_to(PACKAGE.parent)}:{line} imports {imported}"
        for path in sorted((PACKAGE.parent / "tests").glob("*.py"))
        for imported, line in imported_names(path)
        if any(imported == name or imported.startswith(f"{name}.") for name in EXPERIMENTS)
    ]
    assert not offenders, offenders


def docstring_lengths(path: Path) -> list[tuple[int, int]]:
    """(line, number of lines) of every docstring in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=True)
            if doc is not None:
                found.append((getattr(node, "lineno", 1), len(doc.splitlines())))
    return found


DOCSTRING_LINES = 12  # the method belongs on its page in docs/, the docstring links to it


@pytest.mark.parametrize("name", sorted(MODULES))
def test_docstrings_stay_short(name):
    long = [f"line {line}: {count} lines" for line, count in docstring_lengths(MODULES[name]) if count > DOCSTRING_LINES]
    assert not long, f"{name}: {long}"


def test_arrows_point_one_way_core_below_app_and_cli():
    """The core never imports the app or the command line; the app never imports the command line."""
    offenders = []
    for name, path in MODULES.items():
        for imported, line in imported_names(path):
            # `python -m ph_explorer` runs the command line: __main__ stands with it.
            core = not name.startswith(("ph_explorer.app", "ph_explorer.cli", "ph_explorer.__main__"))
            if (core and imported.startswith(("ph_explorer.app", "ph_explorer.cli"))) or (
                name.startswith("ph_explorer.app") and imported.startswith("ph_explorer.cli")
            ):
                offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {imported}")
    assert not offenders, offenders


def effect_id_literals(path: Path, ids: set[str]) -> list[str]:
    """String literals in the file that name an effect id (docstrings aside)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    # Ids that are plain words ("noise", "drift") only count as a whole literal; ids with an
    # underscore ("b_axis_cyclic") are never a word of ordinary text.
    compound = [re.compile(rf"\b{re.escape(i)}\b") for i in ids if "_" in i]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            text = node.value
            if text in ids or any(p.search(text) for p in compound):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {text!r}")
    return found


def test_no_effect_id_is_written_in_the_diagnosis_or_the_app():
    ids = set(DEFAULT_CATALOG)
    paths = [p for name, p in MODULES.items() if name.startswith(("ph_explorer.diagnosis", "ph_explorer.app"))]
    assert len(paths) >= 5
    offenders = [hit for path in paths for hit in effect_id_literals(path, ids)]
    assert not offenders, offenders


def test_the_effect_id_rule_can_fail(tmp_path):
    sample = tmp_path / "ph_explorer" / "app" / "sample.py"
    sample.parent.mkdir(parents=True)
    sample.write_text('"""Mentions b_axis_cyclic in a docstring: allowed."""\nX = "b_axis_cyclic"\nY = "noise floor"\nZ = "drift"\n')
    global PACKAGE
    saved, PACKAGE = PACKAGE, tmp_path / "ph_explorer"
    try:
        hits = effect_id_literals(sample, set(DEFAULT_CATALOG))
    finally:
        PACKAGE = saved
    assert [h.split(" ", 1)[1] for h in hits] == ["'b_axis_cyclic'", "'drift'"]


@pytest.mark.parametrize("name", sorted(MODULES))
def test_modules_stay_readable(name):
    """One job per module: none is over ~400 lines (a module that holds one job that cannot be cut
    is listed here with the reason)."""
    allowed = {}
    lines = len(MODULES[name].read_text(encoding="utf-8").splitlines())
    assert lines <= allowed.get(name, 420), f"{name} has {lines} lines"


def test_every_subpackage_is_installed() -> None:
    """pyproject lists the packages a wheel holds: a subpackage missing there imports in the
    editable checkout and fails in an installed one."""
    import tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"])
    present = {module_name(p) for p in PACKAGE.rglob("__init__.py")}
    assert present - listed == set()
