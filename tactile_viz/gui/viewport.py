"""The 3D view: a pyvistaqt ``QtInteractor`` that paints on request, logs its paints and
hands dropped files to the window (through the scene, checked like any file)."""

import os
import time
from collections import deque

import pyvista as pv
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import QWidget
from pyvistaqt import QtInteractor

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
OBSERVATION_SUFFIXES = (".csv", ".mcap", ".db3")  # recorded touches: CSV, ROS 2 bags
# The render waits this long after the scene update: with no delay its paint followed the
# update with no timer run in between (Qt delivers posted events first).
RENDER_DELAY_MS = 10
# Multisampling of the viewport when idle and while steps run: with Mesa's software
# renderer 4x multisampling doubles a render (0.13 s against 0.06 s for a novel scene at
# 1500x900), so a run draws without it and the view is smoothed again when it stops.
IDLE_MULTISAMPLES = 4
RUNNING_MULTISAMPLES = 0
# While steps run the scene is lit by one headlight instead of pyvista's light kit (five
# lights): a software render shades every fragment once per light, and one light took 22 ms
# of CPU against 39 ms for neptune's scene (34 against 54 ms for mug_2's, 716 x 825 pixels).
# The kit is back, with multisampling, when the run stops.


def is_mesh_path(path):
    return str(path).lower().endswith(MESH_SUFFIXES)


def is_droppable(path):
    return (bool(path) and os.path.isfile(path)
            and str(path).lower().endswith(MESH_SUFFIXES + OBSERVATION_SUFFIXES))


class Viewport(QtInteractor):
    """The 3D view: a QtInteractor whose file drops go to the window (and from there through
    the scene, checked like any file), not straight into the plotter as loose actors.

    A mesh file (:data:`MESH_SUFFIXES`) or recorded touches (:data:`OBSERVATION_SUFFIXES`)
    may be dropped; anything else is refused while it is dragged. Holding Shift at the drop
    asks for a mesh to be added as a prior instead of becoming the ground truth. While
    ``drops_enabled`` is False (steps running) every drag is refused.

    Signals
    -------
    files_dropped(list, bool)
        The droppable paths, and whether Shift was held (a mesh becomes a prior).
    drag_entered(list, bool)
        A drag entered carrying these droppable paths (none: refused); the bool says
        whether a drop would be accepted now.
    resized()
        The view's size changed (the overlays sized in pixels follow).
    """

    files_dropped = Signal(list, bool)
    drag_entered = Signal(list, bool)
    resized = Signal()

    def __init__(self, *args, **kwargs):
        # A view inside a window is drawn on screen whatever pyvista.OFF_SCREEN says: off
        # screen, its screenshots read whatever memory the window's buffer held.
        kwargs.setdefault("off_screen", False)
        super().__init__(*args, **kwargs)
        self.set_background("white")
        if getattr(self, "iren", None) is not None:
            self.clear_events_for_key("q")  # pyvista's 'q' would finalise the view
        self._idle_lights = None  # the light kit, while a run draws with a headlight
        self.last_paint_seconds = 0.0
        self.paint_log = deque(maxlen=10_000)  # (perf_counter at the start, seconds) per paint
        self.drops_enabled = True

    def schedule_render(self):
        """Render once, in a paint in a later pass of the event loop: not synchronously
        (that would be followed by a second render in the paint) and not in the pass that
        updated the scene, so that input and timers run between the two."""
        QTimer.singleShot(RENDER_DELAY_MS, self, self._request_paint)

    def _request_paint(self):
        QWidget.update(self)

    def set_running(self, running):
        """Multisampling, order-independent translucency and lights as they are while steps
        run (off, off and one headlight: a software render takes half the time) or idle
        (on, on and the light kit)."""
        samples = RUNNING_MULTISAMPLES if running else IDLE_MULTISAMPLES
        window = getattr(self, "render_window", None)
        if window is not None:
            self._set_lights(running)
        if window is not None and window.GetMultiSamples() != samples:
            window.SetMultiSamples(samples)
            # Translucent layers are blended in draw order rather than order-independently
            # while running (a third of a software render), and exactly again when idle.
            self.renderer.SetUseOIT(samples == IDLE_MULTISAMPLES)
            # Repaint in the next paint; Qt merges this with a pending step's paint.
            QWidget.update(self)

    def _set_lights(self, running):
        renderer = self.renderer
        if running and self._idle_lights is None:
            self._idle_lights = list(renderer.lights)
            renderer.remove_all_lights()
            renderer.add_light(pv.Light(light_type="headlight"))
        elif not running and self._idle_lights is not None:
            renderer.remove_all_lights()
            for light in self._idle_lights:
                renderer.add_light(light)
            self._idle_lights = None

    def paintGL(self):
        began = time.perf_counter()
        super().paintGL()
        self.last_paint_seconds = time.perf_counter() - began
        self.paint_log.append((began, self.last_paint_seconds))

    def resizeEvent(self, event):
        super().resizeEvent(event)
        self.resized.emit()

    @staticmethod
    def droppable_paths(mime_data):
        """The local files of a drag's data that may be dropped here, in order."""
        paths = [url.toLocalFile() for url in mime_data.urls()] if mime_data.hasUrls() else []
        return [path for path in paths if is_droppable(path)]

    def dragEnterEvent(self, event):
        paths = self.droppable_paths(event.mimeData())
        if paths and self.drops_enabled:
            event.acceptProposedAction()
        else:
            event.ignore()
        self.drag_entered.emit(paths, bool(paths) and self.drops_enabled)

    def dragMoveEvent(self, event):
        if self.drops_enabled and self.droppable_paths(event.mimeData()):
            event.acceptProposedAction()
        else:
            event.ignore()

    def dropEvent(self, event):
        paths = self.droppable_paths(event.mimeData())
        if paths and self.drops_enabled:
            event.acceptProposedAction()
            as_prior = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            self.files_dropped.emit(paths, as_prior)
        else:
            event.ignore()
