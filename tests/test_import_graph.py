"""The package's modules import each other without cycles and only downwards, through the layers below
(imports inside functions and imports for type checking only count too): each layer can be read, and
loaded, on its own, with what lies under it."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "genr8_dist"

#: The layers, lowest first: a module may import its own layer's modules and those of layers below,
#: never one above. A module's layer is that of the longest name here it is or lies under (the
#: package's own ``__init__``, the public names, is the top).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "rng", "resources", "tomlfile", "files", "fields", "meshings"),   # importing only these
    ("environment",),                   # the simulated environment: forces, boundaries, physics
    ("hemls", "scaffold", "forms"),     # the language, growth in an environment, the surface
    ("fitness", "export"),              # criteria over a surface; files and pictures of one
    ("grammar",),                       # universes: grammar, mapping, hooks, trust, discovery
    ("phenotype",),                     # what a universe's texts develop into
    ("run_universe",),                  # the universe a configuration names, and its phenotype
    ("config",),                        # RunConfig
    ("evolution",),                     # evaluation, operators, the island
    ("store",),                         # the run store
    ("history", "distributed"),         # reading a run; running one on Ray
    ("studio",),                        # the browser studio
    ("cli",),                           # the genr8 command
    ("",),                              # genr8_dist/__init__.py
)


def _module(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    me = _module(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join([*parts[: len(parts) - node.level + 1], base])
            names = [base, *(f"{base}.{a.name}" for a in node.names)]
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != me:
                found.add(name)
    return found


def _graph() -> dict[str, set[str]]:
    paths = sorted(PACKAGE.rglob("*.py"))
    modules = {_module(p) for p in paths}
    return {_module(p): _imports(p, modules) for p in paths}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt.startswith(node + ".") or graph.get(nxt) is None:
                continue
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _edges() -> dict[str, set[str]]:
    # a package's __init__ re-exports its modules: an import of a module's own package (or a parent)
    # from inside it is the same layer, so those edges are left out
    return {m: {i for i in imports if not m.startswith(i + ".")} for m, imports in _graph().items()}


def _layer(module: str) -> int:
    name = module.removeprefix("genr8_dist").removeprefix(".")
    best, where = -1, -1
    for level, names in enumerate(LAYERS):
        for prefix in names:
            if (name == prefix or name.startswith(prefix + ".") or prefix == "") and len(prefix) > best:
                best, where = len(prefix), level
    return where


def test_the_package_has_no_import_cycle():
    cycles = _cycles(_edges())
    assert not cycles, "modules importing each other: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_a_cycle_is_found_through_any_kind_of_import():
    # the finder the test above trusts: a planted ring of three, with a module hanging off it
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_every_module_has_a_layer():
    missing = [m for m in _graph() if m != "genr8_dist" and _layer(m) == len(LAYERS) - 1]
    assert not missing, f"add to tests/test_import_graph.py's LAYERS: {', '.join(sorted(missing))}"


def test_imports_only_run_downwards():
    upward = sorted(f"{m} (layer {_layer(m)}) imports {i} (layer {_layer(i)})"
                    for m, imports in _edges().items() for i in imports if _layer(i) > _layer(m))
    assert not upward, "imports up the layers:\n" + "\n".join(upward)


def test_no_handler_swallows_base_exception():
    # KeyboardInterrupt and SystemExit end the program: a handler of BaseException may only clean up
    # and raise it again
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ExceptHandler) and node.type is not None \
                    and "BaseException" in ast.unparse(node.type):
                last = node.body[-1]
                if not (isinstance(last, ast.Raise) and last.exc is None):
                    found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    assert not found, "catches BaseException: " + ", ".join(found)
