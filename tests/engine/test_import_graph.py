"""The engine's modules import one another without a cycle and only downward through its
layers (:data:`LAYERS`), and nothing of tactile_viz outside the engine: every import
counts, also one inside a function (the way a cycle is usually hidden)."""

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


def _base(node, module, is_package):
    """The absolute name of X in ``from X import y`` (an ImportFrom in ``module``)."""
    base = node.module or ""
    if node.level:
        anchor = module.split(".")
        anchor = anchor[:len(anchor) - node.level + (1 if is_package else 0)]
        base = ".".join(anchor + ([base] if base else []))
    return base


def _imported(node, module, is_package, modules):
    """The modules of ``modules`` that ``node`` (an Import or ImportFrom in ``module``)
    imports: ``from X import y`` imports the module X.y if there is one, else X. The
    packages holding ``module`` are left out (Python imports them before it anyway)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = _base(node, module, is_package)
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


def _package(tmp_path, top, sub, module):
    """A package ``pkg`` of a module ``top`` and a subpackage ``sub`` holding ``module``,
    which imports ``top`` inside a function; ``top`` imports ``module``."""
    package = tmp_path / "pkg"
    (package / sub).mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / f"{top}.py").write_text(f"from .{sub}.{module} import f\n")
    (package / sub / "__init__.py").write_text("")
    (package / sub / f"{module}.py").write_text(
        f"def f():\n    from ..{top} import g\n    return g\n")
    return package


def test_a_cycle_through_an_import_inside_a_function_is_found(tmp_path):
    package = _package(tmp_path, "a", "sub", "b")
    cycle = import_cycle(import_graph(package, "pkg"))
    assert cycle is not None and set(cycle) == {"pkg.a", "pkg.sub.b"}


def test_the_engine_has_no_import_cycle():
    cycle = import_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


# The engine's layers, lowest first: a module imports only from its own layer and those
# below. A module is in the layer of the longest name here that is its own or a package's
# holding it ("" is tactile_viz.engine itself); io is split: its parts sit at three levels.
LAYERS = [
    ("errors",),  # the exceptions every layer raises
    ("transforms", "param_schema", "params", "presets", "scene"),  # plain values: frames, knobs
    ("io.files", "io.cache"),  # files on disk, atomic writes and the array cache: no objects
    ("shape",),  # objects: meshes, SDFs, prior libraries, symmetries, GPIS
    ("explore",),  # touches: observations, the simulated sensor, where to touch next
    ("belief",),  # the particle filter over class and pose, fed by the observations
    ("io",),  # recordings and a session's saved state, read and written
    ("session",),  # the loop that runs belief, exploration and shape estimate
    ("io.export", "io.bag_export"),  # a session's results written out
    ("",),  # the package: the public names of all of it
]

# The imports that go up a layer, (importer, imported); any other fails the test.
UPWARD = {
    # An ObjectModel builds and caches (by content hash) its feature points and their PPF
    # pair table, the filter's seeding data, with its other derived data: ppf.py is belief's
    # (prior_bank's too), so moving both modules into shape is more than a small move.
    ("shape.objects", "belief.features"),
    ("shape.objects", "belief.ppf"),
}


def _relative(module, package=PACKAGE):
    return module[len(package) + 1:] if module != package else ""


def layer_of(name, layers=LAYERS):
    """Index in ``layers`` of the module ``name`` (relative to the package)."""
    index, _ = max(((i, entry) for i, entries in enumerate(layers) for entry in entries
                    if entry == "" or name == entry or name.startswith(entry + ".")),
                   key=lambda found: len(found[1]))
    return index


def upward_imports(graph, layers=LAYERS, package=PACKAGE):
    """The imports of ``graph`` (module names relative to ``package``) that go up a layer."""
    return {(_relative(module, package), _relative(name, package))
            for module, names in graph.items() for name in names
            if layer_of(_relative(name, package), layers)
            > layer_of(_relative(module, package), layers)}


def test_every_layer_names_modules_that_exist():
    graph = import_graph()
    names = {_relative(module) for module in graph}
    assert {entry for entries in LAYERS for entry in entries} <= names
    assert len(graph) > 40 and "" in names


def test_an_upward_import_is_found(tmp_path):
    package = _package(tmp_path, "top", "low", "a")
    layers = [("low",), ("top",), ("",)]
    assert upward_imports(import_graph(package, "pkg"), layers, "pkg") == {("low.a", "top")}


def test_the_engine_imports_only_downward():
    upward = upward_imports(import_graph())
    new = sorted(upward - UPWARD)
    assert not new, "imports up a layer (tests/engine/test_import_graph.py's LAYERS): " + \
        ", ".join(f"{module} -> {name}" for module, name in new)
    assert UPWARD <= upward, f"no longer upward, remove from UPWARD: {sorted(UPWARD - upward)}"


def test_the_engine_imports_nothing_else_of_tactile_viz():
    """Not the app, the GUI, the CLI, the commands or the experiments: they import the
    engine."""
    outside = []
    for path in ROOT.rglob("*.py"):
        module = _module_name(path, ROOT, PACKAGE)
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _base(node, module, path.name == "__init__.py")
                names = [base] + [f"{base}.{alias.name}" for alias in node.names]
            else:
                continue
            outside += [f"{_relative(module)} -> {name}" for name in names
                        if name.startswith("tactile_viz.") and name != PACKAGE
                        and not name.startswith(PACKAGE + ".")]
    assert not outside, "the engine imports: " + ", ".join(sorted(outside))
