"""The user commands (``tactile_viz.commands``) import only the engine, ``tactile_viz.cli``
and one another: never the benchmarks (``tactile_viz.experiments``, which import the
commands), the app or the GUI. Every import counts, also one inside a function."""

import ast
from pathlib import Path

import tactile_viz.commands

ROOT = Path(tactile_viz.commands.__file__).parent
ALLOWED = ("tactile_viz.commands", "tactile_viz.engine", "tactile_viz.cli")


def _imported(path):
    """The absolute names of everything ``path`` (a module of the package) imports."""
    module = "tactile_viz.commands" + ("" if path.stem == "__init__" else f".{path.stem}")
    package = module if path.stem == "__init__" else module.rpartition(".")[0]
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            names += [f"{base}.{alias.name}" for alias in node.names]
    return names


def test_the_commands_import_only_the_engine_and_the_cli():
    found = {path.name: _imported(path) for path in sorted(ROOT.glob("*.py"))}
    assert "tactile_viz.commands.library.prior_bar" in found["trial.py"]
    assert "tactile_viz.engine.session.RecordedSession" in found["replay.py"]
    outside = sorted(f"{name} -> {imported}" for name, names in found.items()
                     for imported in names if imported.startswith("tactile_viz")
                     and not imported.startswith(ALLOWED))
    assert not outside, "the commands import: " + ", ".join(outside)
