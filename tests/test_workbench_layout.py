"""The house rules of the workbench (issue 12), checked on the source by an AST walk.

- ``jaxtube`` (the engine) never imports ``fitting``;
- ``fitting`` imports ``jaxtube`` only through its public namespace (``jaxtube/__init__.py``);
- nothing in ``fitting`` but its command line imports ``fitting._cli``;
- ``fitting.continuum`` (the independent reference solver) imports neither package;
- no import cycles between the modules of ``fitting``;
- no import inside a function, except the lazy imports of optional heavy libraries
  (``tqdm``, ``matplotlib``);
- no module of ``fitting`` over 500 lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 500
LAZY_ALLOWED = ("tqdm", "matplotlib")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules(package: str) -> dict[str, Path]:
    return {_module_name(path): path for path in sorted((ROOT / package).rglob("*.py"))}


def _imports(name: str, path: Path):
    """``(imported module, line, inside a function)`` of every import in a module; relative
    imports resolved, ``from package import name`` giving ``package.name`` as well."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    functions = [node for node in ast.walk(tree)
                 if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]
    inside = {id(child) for function in functions for child in ast.walk(function)}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno, id(node) in inside) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            found.append((base, node.lineno, id(node) in inside))
            found += [(f"{base}.{alias.name}", node.lineno, id(node) in inside)
                      for alias in node.names]
    return found


FITTING = _modules("fitting")
JAXTUBE = _modules("jaxtube")


def _violations(modules, rule) -> list[str]:
    return [f"{path.relative_to(ROOT)}:{line}: {target}"
            for name, path in modules.items()
            for target, line, in_function in _imports(name, path)
            if rule(name, target, in_function)]


def _is(target: str, package: str) -> bool:
    return target == package or target.startswith(package + ".")


def test_the_engine_never_imports_the_workbench():
    assert _violations(JAXTUBE, lambda name, target, _: _is(target, "fitting")) == []


def test_the_workbench_uses_only_the_public_namespace_of_the_engine():
    def private(name, target, _):
        return _is(target, "jaxtube") and target.count(".") >= 1 and target.split(".")[1][0] == "_"

    assert _violations(FITTING, private) == []


def test_only_the_command_line_imports_the_command_line():
    assert _violations(FITTING, lambda name, target, _: _is(target, "fitting._cli")
                       and not _is(name, "fitting._cli")) == []


def test_the_continuum_reference_imports_neither_package():
    continuum = {name: path for name, path in FITTING.items()
                 if _is(name, "fitting.continuum")}
    assert continuum
    assert _violations(continuum, lambda name, target, _: _is(target, "jaxtube") or (
        _is(target, "fitting") and not _is(target, "fitting.continuum"))) == []


def test_no_import_inside_a_function_except_lazy_optional_libraries():
    assert _violations(FITTING, lambda name, target, in_function: in_function and not any(
        _is(target, lazy) for lazy in LAZY_ALLOWED)) == []


def test_no_import_cycle_inside_the_workbench():
    graph = {name: {target for target, _, _ in _imports(name, path)
                    if target in FITTING and target != name}
             for name, path in FITTING.items()}
    # A package's __init__ re-exports its modules; importing a module of a package runs
    # that __init__ first, so an edge into a package's module also enters the package.
    for name in list(graph):
        for target in list(graph[name]):
            parent = target.rpartition(".")[0]
            if parent in FITTING and not _is(name, parent):
                graph[name].add(parent)
    cycles, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        for target in sorted(graph[node]):
            if state.get(target) == "open":
                cycles.append(" -> ".join(stack[stack.index(target):] + [target]))
            elif target not in state:
                visit(target, stack + [target])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert cycles == []


@pytest.mark.parametrize("name", sorted(FITTING))
def test_no_module_over_500_lines(name):
    lines = len(FITTING[name].read_text().splitlines())
    assert lines <= MAX_LINES, f"{FITTING[name].relative_to(ROOT)}: {lines} lines"
