"""The package's shape: the import graph (imports inside functions counted) has no cycle, and every
arrow runs down the documented order of packages (README, "Layout")."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.helpers.paths import PACKAGE

# Lowest first: a package may import its own floor and those below, never one above.
FLOORS = [
    {"core", "_moved", "compiled", "interrupts"},
    {"character", "schema"},
    {"guard", "atomic"},
    {"sim", "events", "scenario"},
    {"cameras", "editing", "usd", "groundtruth", "exchange"},
    {"render"},
    {"jobs"},
    {"dataset"},
    {"cli"},
    {"__main__"},
]


def _module(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _unit(module: str) -> str | None:
    """The package (or top-level module) of ``usdcrowd.x.y``: ``x``; None for usdcrowd itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def import_graph(level=_unit) -> dict[str, set[str]]:
    """``{unit: units it imports}``, from every import statement of every module (``level`` names the unit
    a module belongs to: its top package by default, itself for the module graph)."""
    modules = {_module(p): p for p in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else [])) if node.level else node.module
                targets = [f"{target}.{a.name}" for a in node.names] + [target]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            for t in targets:
                if not t or not t.startswith("usdcrowd"):
                    continue
                while t not in modules and "." in t:
                    t = t.rsplit(".", 1)[0]
                if level is not _unit and name.startswith(t + ".") and modules[t].name == "__init__.py":
                    continue                # a module's own package's face: not an import of a sibling
                a, b = level(name), level(t)
                if a and b and a != b:
                    graph.setdefault(a, set()).add(b)
    return graph


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """A path that comes back to where it started, or None."""
    state: dict[str, int] = {}

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path + [nxt]
            if nxt not in state:
                found = visit(nxt, path + [nxt])
                if found:
                    return found
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node, [node])
            if found:
                return found
    return None


def test_no_module_imports_one_that_imports_it_back():
    circle = _circle(import_graph(level=lambda m: m))
    assert circle is None, " -> ".join(circle)


def test_every_package_has_a_floor():
    units = {_unit(_module(p)) for p in PACKAGE.rglob("*.py")} - {None}
    placed = set().union(*FLOORS)
    assert units <= placed, f"not on a floor of tests/project/test_structure.py: {sorted(units - placed)}"


def test_imports_run_down_the_floors_and_never_in_a_circle():
    floor = {unit: k for k, units in enumerate(FLOORS) for unit in units}
    graph = import_graph()
    upward = sorted(f"{a} -> {b}" for a, bs in graph.items() for b in bs if floor[b] > floor[a])
    assert not upward, upward
    circle = _circle(graph)                 # within a floor
    assert circle is None, " -> ".join(circle)


def test_modules_that_moved_still_import_by_their_old_names_with_a_warning():
    import importlib
    import sys
    import warnings

    from usdcrowd._moved import MOVED

    for old, new in MOVED.items():
        sys.modules.pop(old, None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            module = importlib.import_module(old)
        assert module is importlib.import_module(new), old
        assert any(issubclass(w.category, DeprecationWarning) and new in str(w.message) for w in caught), old


# Functions still over MAX_LINES, each at its length today: the list only shrinks (split one, remove it
# here) and none may grow; a new long function says why in its docstring ("Long because ...").
MAX_LINES = 80
STILL_LONG: dict[str, int] = {}       # functions over MAX_LINES allowed to stay so while they are split


def test_no_function_grows_past_80_lines_without_saying_why():
    found = {}
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_LINES and "Long because" not in (ast.get_docstring(node) or ""):
                    found[f"{path.relative_to(PACKAGE).as_posix()}:{node.name}"] = length
    grown = {k: v for k, v in found.items() if v > STILL_LONG.get(k, MAX_LINES)}
    assert not grown, f"longer than {MAX_LINES} lines (split them, or say why in the docstring): {grown}"


def test_the_tests_mirror_the_packages():
    """Each folder of tests/ is one of the package's subpackages (or the repository's, or shared code), and
    no test reaches another through sys.path or conftest imports."""
    from tests.helpers.paths import TESTS

    subpackages = {p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("__init__.py") for p in [p.parent]}
    folders = {p.parent.relative_to(TESTS).as_posix() for p in TESTS.rglob("test_*.py")}
    assert folders <= subpackages | {"project"}, sorted(folders - subpackages - {"project"})
    import re

    reaching = re.compile(r"sys\.path\s*(?:\.insert|\.append|\[)|^\s*from conftest import", re.M)
    assert not [p for p in TESTS.rglob("*.py") if reaching.search(p.read_text())]
