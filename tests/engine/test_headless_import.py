"""The engine and the app's model must import without any GUI toolkit (Qt, pyvista, VTK)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

BLOCKED = (
    "PySide6",
    "PyQt5",
    "PyQt6",
    "qtpy",
    "pyvista",
    "pyvistaqt",
    "vtk",
    "vtkmodules",
    "superqt",
)

SCRIPT = textwrap.dedent(
    """
    import importlib
    import importlib.abc
    import pkgutil
    import sys

    BLOCKED = set(sys.argv[1].split(","))

    class BlockGui(importlib.abc.MetaPathFinder):
        def find_spec(self, fullname, path=None, target=None):
            if fullname.split(".")[0] in BLOCKED:
                raise ImportError(f"blocked GUI import: {fullname}")
            return None

    sys.meta_path.insert(0, BlockGui())

    import tactile_viz.engine as engine
    import tactile_viz.app as app
    import tactile_viz.cli

    errors = []
    def onerror(name):
        errors.append(name)

    names = [engine.__name__, app.__name__, "tactile_viz.cli"]
    for package in (engine, app):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + ".",
                                          onerror=onerror):
            importlib.import_module(info.name)
            names.append(info.name)
    if errors:
        raise SystemExit(f"could not import: {errors}")
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
    if leaked:
        raise SystemExit(f"GUI modules in sys.modules: {leaked}")
    print("imported", len(names), "modules:", " ".join(names))
    """
)


def test_engine_and_app_model_import_without_gui_toolkits():
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, ",".join(BLOCKED)],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "imported" in proc.stdout
    assert "tactile_viz.app.scene" in proc.stdout.split()  # the app's model, moved from engine


def test_blocker_really_blocks():
    """Guard against a finder that silently lets the GUI imports through."""
    probe = SCRIPT.replace("import tactile_viz.engine as engine", "import pyvista")
    proc = subprocess.run(
        [sys.executable, "-c", probe, ",".join(BLOCKED)],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode != 0
    assert "blocked GUI import: pyvista" in proc.stderr

