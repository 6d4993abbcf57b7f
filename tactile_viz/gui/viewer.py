"""Minimal main window: one object mesh in a pyvistaqt interactor.

The full application window comes later; this is the smallest useful viewer
and the base the GUI smoke tests exercise.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
import trimesh
from pyvistaqt import QtInteractor
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence
from PySide6.QtWidgets import QMainWindow, QWidget

BACKGROUND = "white"
MESH_COLOR = "lightsteelblue"


def trimesh_to_polydata(mesh: trimesh.Trimesh) -> pv.PolyData:
    """Convert a triangle mesh to a ``pv.PolyData`` (VTK face layout)."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces])
    return pv.PolyData(np.asarray(mesh.vertices, dtype=np.float64), cells.ravel())


class ViewerWindow(QMainWindow):
    """Main window showing a single object mesh."""

    def __init__(
        self,
        mesh: trimesh.Trimesh,
        name: str = "object",
        parent: QWidget | None = None,
    ) -> None:
        super().__init__(parent)
        self.setWindowTitle(f"tactile_viz - {name}")
        self.resize(900, 700)

        self.plotter = QtInteractor(self)
        self.plotter.set_background(BACKGROUND)
        self.setCentralWidget(self.plotter)

        self.mesh_actor = self.plotter.add_mesh(
            trimesh_to_polydata(mesh), color=MESH_COLOR, smooth_shading=True, name="object"
        )
        self.plotter.reset_camera()

        file_menu = self.menuBar().addMenu("&File")
        quit_action = QAction("&Quit", self)
        quit_action.setShortcut(QKeySequence.StandardKey.Quit)
        quit_action.triggered.connect(self.close)
        file_menu.addAction(quit_action)
        self.quit_action = quit_action

        self.statusBar().showMessage(
            f"{name}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces"
        )

    def screenshot(self, filename: str | None = None) -> np.ndarray:
        """Render the viewport and return it as an RGB array (optionally save a PNG)."""
        self.plotter.render()
        return self.plotter.screenshot(filename, return_img=True)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt API)
        self.plotter.close()
        super().closeEvent(event)
