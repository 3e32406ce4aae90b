"""The import rules of the two packages (issue 12), by an AST walk of the sources.

- ``jaxtube`` (the engine) never imports ``fitting`` (the workbench);
- ``fitting`` imports ``jaxtube`` only through its public namespace (``import jaxtube``,
  ``from jaxtube import X`` with a public ``X``);
- nothing in ``fitting`` but its command line (``fitting/_cli/``) imports the command line;
- ``fitting/continuum`` (the independent reference solver) imports neither package;
- no import cycle inside either package (imports inside functions count: a cycle dodged by
  a function-level import is still a cycle);
- no module of either package is over 500 lines.

No module is imported here (no JAX): the rules are read from the source text.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jaxtube", "fitting")
MAX_LINES = 500


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _sources(package: str) -> dict[str, Path]:
    """``{module name: file}`` of every module of ``package``."""
    return {_module_name(path): path for path in sorted((ROOT / package).rglob("*.py"))
            if ".venv" not in path.parts}


ALL_MODULES = {name: path for package in PACKAGES for name, path in _sources(package).items()}


def _imports(name: str, path: Path) -> list[tuple[int, str]]:
    """``(line, absolute module name)`` of every import in the file, anywhere in it. For
    ``from M import x`` both ``M`` and ``M.x`` are listed when ``M.x`` is a module."""
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            found.append((node.lineno, target))
            for alias in node.names:
                if f"{target}.{alias.name}" in ALL_MODULES:
                    found.append((node.lineno, f"{target}.{alias.name}"))
    return found


def _where(path: Path, line: int) -> str:
    return f"{path.relative_to(ROOT)}:{line}"


def _in(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def test_jaxtube_never_imports_fitting():
    bad = []
    for name, path in _sources("jaxtube").items():
        for line, target in _imports(name, path):
            if _in(target, "fitting"):
                bad.append(f"{_where(path, line)} imports {target}")
    assert bad == []


def test_fitting_uses_only_the_public_jaxtube_namespace():
    bad = []
    for name, path in _sources("fitting").items():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                bad += [f"{_where(path, node.lineno)} imports {a.name}" for a in node.names
                        if _in(a.name, "jaxtube") and a.name != "jaxtube"]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module and _in(
                    node.module, "jaxtube"):
                if node.module != "jaxtube":
                    bad.append(f"{_where(path, node.lineno)} imports from {node.module}")
                bad += [f"{_where(path, node.lineno)} imports jaxtube.{a.name}"
                        for a in node.names if a.name.startswith("_")]
    assert bad == []


def test_only_the_cli_imports_the_cli():
    bad = [f"{_where(path, line)} imports {target}"
           for name, path in _sources("fitting").items() if not _in(name, "fitting._cli")
           for line, target in _imports(name, path) if _in(target, "fitting._cli")]
    assert bad == []


def test_continuum_reference_imports_neither_package():
    modules = {n: p for n, p in _sources("fitting").items() if _in(n, "fitting.continuum")}
    assert modules, "fitting/continuum is missing"
    bad = [f"{_where(path, line)} imports {target}"
           for name, path in modules.items() for line, target in _imports(name, path)
           if _in(target, "jaxtube") or (_in(target, "fitting")
                                         and not _in(target, "fitting.continuum"))]
    assert bad == []


def _import_graph(package: str) -> dict[str, set[str]]:
    """Edges ``importer -> imported`` between modules of ``package``. Importing ``a.b.c``
    also runs the ``__init__`` of ``a.b``, unless the importer is inside ``a.b`` already
    (a package is initialised before its modules); the top package is always initialised."""
    modules = _sources(package)
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for _, target in _imports(name, path):
            if target not in modules:
                continue
            parts = target.split(".")
            for k in range(2, len(parts) + 1):
                prefix = ".".join(parts[:k])
                if prefix in modules and prefix != name and not (
                        k < len(parts) and _in(name, prefix)):
                    graph[name].add(prefix)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_cycle_finder_finds_a_cycle():
    """The detector itself: a three-module loop, a self-contained tree, a package and its
    module."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == []


@pytest.mark.parametrize("package", [
    "jaxtube", "fitting"])
def test_no_import_cycle_inside_a_package(package):
    assert _cycles(_import_graph(package)) == []


@pytest.mark.parametrize("package", [
    "jaxtube", "fitting"])
def test_no_module_over_500_lines(package):
    long = {str(path.relative_to(ROOT)): count for path in _sources(package).values()
            if (count := len(path.read_text().splitlines())) > MAX_LINES}
    assert long == {}


LAZY_ALLOWED = ("tqdm", "matplotlib", "klujax", "distributed")  # optional, loaded on use


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_inside_a_function_except_lazy_optional_libraries(package):
    """Imports hidden in functions to dodge a cycle are not allowed (move the code instead)."""
    bad = []
    for path in _sources(package).values():
        tree = ast.parse(path.read_text(), filename=str(path))
        for function in ast.walk(tree):
            if not isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(function):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                         [node.module or "."] if isinstance(node, ast.ImportFrom) else [])
                bad += [f"{_where(path, node.lineno)} imports {n}" for n in names
                        if not any(_in(n, lazy) for lazy in LAZY_ALLOWED)]
    assert bad == []
