"""The engine's modules import one another without a cycle: every import counts, also one
inside a function (the way a cycle is usually hidden)."""

import ast
import graphlib
from pathlib import Path

import tactile_viz.engine

ROOT = Path(tactile_viz.engine.__file__).parent
PACKAGE = "tactile_viz.engine"


def _module_name(path, root, package):
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join([package, *parts])


def _imported(node, module, is_package, modules):
    """The modules of ``modules`` that ``node`` (an Import or ImportFrom in ``module``)
    imports: ``from X import y`` imports the module X.y if there is one, else X. The
    packages holding ``module`` are left out (Python imports them before it anyway)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = node.module or ""
        if node.level:
            anchor = module.split(".")
            anchor = anchor[:len(anchor) - node.level + (1 if is_package else 0)]
            base = ".".join(anchor + ([base] if base else []))
        names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                 for alias in node.names]
    return {name for name in names if name in modules and name != module
            and not module.startswith(name + ".")}


def import_graph(root=ROOT, package=PACKAGE):
    """``{module: set of the package's modules it imports}`` of the modules under
    ``root``."""
    files = {_module_name(path, root, package): path for path in root.rglob("*.py")}
    graph = {}
    for module, path in files.items():
        is_package = path.name == "__init__.py"
        graph[module] = {name for node in ast.walk(ast.parse(path.read_text(), str(path)))
                         if isinstance(node, (ast.Import, ast.ImportFrom))
                         for name in _imported(node, module, is_package, files)}
    return graph


def import_cycle(graph):
    """A cycle of ``graph`` as a list of modules (first = last), or None."""
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as error:
        return error.args[1]
    return None


def test_the_graph_sees_every_import():
    graph = import_graph()
    assert f"{PACKAGE}.io.persistence" in graph[f"{PACKAGE}.session.loop"]
    assert f"{PACKAGE}.session.loop" in graph[f"{PACKAGE}.session"]
    assert len(graph) > 40 and sum(map(len, graph.values())) > 100


def test_a_cycle_through_an_import_inside_a_function_is_found(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .sub.b import f\n")
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "b.py").write_text("def f():\n    from ..a import g\n    return g\n")
    cycle = import_cycle(import_graph(package, "pkg"))
    assert cycle is not None and set(cycle) == {"pkg.a", "pkg.sub.b"}


def test_the_engine_has_no_import_cycle():
    cycle = import_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)
