"""The main window: a pyvista viewport, the Controls dock's panels and plots, on a :class:`Scene`.

The window owns no inference state and no settings of its own. The panels of
:mod:`tactile_viz.gui.panels` build the controls; the window connects their signals to the
scene's methods and, whenever one of the scene's signals fires, has the panels fill their
widgets from the scene (so the command line, a loaded session and a preset all show the same
way). Steps run in a worker thread (see :mod:`tactile_viz.gui.runner`) that yields one
immutable snapshot per step; only the newest snapshot of the current session is drawn, and
VTK is touched only on the GUI thread. While steps run, every control that would change the
scene is disabled.
"""

import json
import os
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np
from pyvistaqt import QtInteractor
from PySide6.QtCore import QByteArray, QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QDockWidget, QFileDialog, QLabel, QMainWindow, QMessageBox,
                               QProgressBar, QProgressDialog, QScrollArea, QVBoxLayout,
                               QWidget)
from superqt.utils import thread_worker

from ..app.engine_process import ENGINES, shared_engine
from ..engine.errors import TactileVizError
from ..engine.session import Session
from .layers import ViewportLayers
from .panels import ExplorationPanel, LayersPanel, LoopPanel, PriorsPanel, ScenePanel, status_text
from .panels.loop_panel import format_length
from .panels.base import blocked
from .plots import PlotsWidget
from .recording import Recorder, widget_frame
from .runner import StepRunner

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
OBSERVATION_SUFFIXES = (".csv",)  # recorded touches (kind,x,y,z,nx,ny,nz)
MESH_FILTER = "Meshes (*.obj *.ply *.stl *.off *.glb *.gltf);;All files (*)"
SETTINGS_ORGANIZATION = "tactile_viz"
SETTINGS_APPLICATION = "tactile_viz"
STATUS_SECONDS = 8000  # how long a status-bar message stays, ms
# During a run the plots are drawn this long after the viewport's paint, so that the event
# loop runs in between instead of blocking for both.
PLOTS_DELAY_MS = 30
# The render waits this long after the scene update: with no delay its paint followed the
# update with no timer run in between (Qt delivers posted events first).
RENDER_DELAY_MS = 10
PLOTS_WIDTH = 320  # the plots dock's width at first start, pixels
# Multisampling of the viewport when idle and while steps run: with Mesa's software
# renderer 4x multisampling doubles a render (0.13 s against 0.06 s for a novel scene at
# 1500x900), so a run draws without it and the view is smoothed again when it stops.
IDLE_MULTISAMPLES = 4
RUNNING_MULTISAMPLES = 0

# action name -> (label, shortcut, tooltip); the shortcuts are listed in Help > Keys.
ACTIONS = {
    "step": ("Step", "F6", "One step"),
    "run": ("Run", "F5", "Run continuously; press again to pause (after the step in progress)"),
    "finish": ("Run to termination", "Shift+F5", "Run until the DHD stop or the step cap"),
    "reset": ("Reset", "Ctrl+R", "Start a new session on the same scene"),
    "camera": ("Reset camera", "Home", "Frame the ground truth"),
    "iso": ("Isometric view", "Ctrl+0", "Look from the isometric direction"),
    "xy": ("Top view", "Ctrl+1", "Look down the z axis"),
    "xz": ("Front view", "Ctrl+2", "Look along the y axis"),
    "yz": ("Side view", "Ctrl+3", "Look along the x axis"),
    "screenshot": ("Save screenshot...", "F12", "Save a PNG of the whole window"),
    "record": ("Record steps...", "Ctrl+Shift+R", "Record the window at every drawn step to "
               "a GIF or MP4; press again to stop"),
    "open_truth": ("Open ground-truth mesh...", QKeySequence.StandardKey.Open, None),
    "load_library": ("Load prior library...", None, None),
    "save_library": ("Save prior library...", None, None),
    "load_session": ("Load session...", "Ctrl+L", None),
    "open_observations": ("Open observations...", "Ctrl+Shift+O",
                          "Step through recorded touches (CSV: kind,x,y,z,nx,ny,nz) in this "
                          "viewport"),
    "export": ("Export estimate...", "Ctrl+E", "Write observations.csv, map_shape.ply, "
               "reconstruction.ply and estimate.json of the current step to a folder"),
    "save_session": ("Save session...", QKeySequence.StandardKey.Save, None),
    "quit": ("Quit", QKeySequence.StandardKey.Quit, None),
    "keys": ("Keys", "F1", "The keyboard shortcuts"),
    "about": ("About tactile_viz", None, None),
}


class LoadCancelled(Exception):
    """Raised from the replay callback when the user cancels loading a session."""


def saved_step_count(path):
    """Number of steps recorded in a saved session (None if it cannot be read here; the
    loader then reports the actual fault)."""
    try:
        with np.load(path, allow_pickle=False) as stored:
            config = json.loads(stored["config"].tobytes().decode())
        return int(config["steps"])
    except Exception:  # noqa: BLE001 - only a progress hint
        return None


@thread_worker(start_thread=False, ignore_errors=True)
def load_session_worker(path, cancel, progress):
    """Load (replay) a saved session in a worker; ``progress(done, total)`` after each
    step, :class:`LoadCancelled` once ``cancel`` is set. Errors (a cancel included) go to
    the worker's ``errored`` signal only, never re-raised in the GUI thread."""
    total = saved_step_count(path)
    progress(0, total or 0)

    def replayed(snapshot):
        if cancel.is_set():
            raise LoadCancelled()
        progress(snapshot.step, total or 0)

    return Session.load(path, callback=replayed)


def _seconds_since(log, since):
    """Total seconds of the ``(start, seconds)`` entries of ``log`` that started at or after
    ``since`` (the newest are at the end)."""
    total = 0.0
    for began, seconds in reversed(log):
        if began < since:
            break
        total += seconds
    return total


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
        super().__init__(*args, **kwargs)
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
        return [path for path in paths if _is_droppable(path)]

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


def _step_cap(params):
    """The most steps a session with ``params`` takes (known or novel)."""
    return max(params.max_steps_known, params.max_steps_novel)


def _is_mesh_path(path):
    return str(path).lower().endswith(MESH_SUFFIXES)


def _is_droppable(path):
    return (bool(path) and os.path.isfile(path)
            and str(path).lower().endswith(MESH_SUFFIXES + OBSERVATION_SUFFIXES))


class _Progress(QWidget):
    """Emits ``changed(done, total)`` on the GUI thread when called from any thread."""

    changed = Signal(int, int)

    def __call__(self, done, total):
        self.changed.emit(int(done), int(total))


def _scrolled(groups):
    """A scroll area that stacks ``(group, stretch)`` pairs and never scrolls sideways (it
    scrolls down only in a window too small for the groups)."""
    panel = QWidget()
    layout = QVBoxLayout(panel)
    layout.setContentsMargins(4, 0, 4, 4)
    layout.setSpacing(4)
    for group, stretch in groups:
        layout.addWidget(group, stretch)
    scroll = QScrollArea()
    scroll.setWidget(panel)
    scroll.setWidgetResizable(True)
    scroll.setFrameShape(QScrollArea.NoFrame)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
    # As wide as the panel wants plus a vertical scroll bar: nothing clipped sideways.
    scroll.setMinimumWidth(panel.sizeHint().width()
                           + scroll.verticalScrollBar().sizeHint().width() + 4)
    return scroll


class MainWindow(QMainWindow):
    """The tactile_viz desktop window.

    Parameters
    ----------
    scene : tactile_viz.app.scene.Scene
    settings : QSettings, optional
        Where the window geometry, dock layout and last folders are kept (default: the
        user's tactile_viz settings).
    engine : {"process", "thread"}
        Where Step and Run step the session: the app's engine process (the default; the
        window draws meanwhile on another core, see
        :mod:`tactile_viz.app.engine_process`) or a worker thread of this process.
    """

    def __init__(self, scene, parent=None, settings=None, engine="process"):
        super().__init__(parent)
        self.scene = scene
        self.settings = settings if settings is not None else QSettings(
            QSettings.IniFormat, QSettings.UserScope, SETTINGS_ORGANIZATION,
            SETTINGS_APPLICATION)
        if engine not in ENGINES:
            raise ValueError(f"unknown engine {engine!r}; choose from {', '.join(ENGINES)}")
        self.engine = shared_engine() if engine == "process" else None
        self.runner = StepRunner(scene, self._draw, parent=self, engine=self.engine)
        self.runner.errored.connect(self.show_error)
        self.runner.finished.connect(self._on_run_finished)
        self.loader = None
        self._load_cancel = None
        self._load_dialog = None
        self.recorder = None
        self._plots_step = None
        self._drawing_run = False  # a draw of the runner's in progress
        self._plots_timer = QTimer(self)
        self._plots_timer.setSingleShot(True)
        self._plots_timer.setInterval(PLOTS_DELAY_MS)
        self._plots_timer.timeout.connect(self._flush_plots)
        self.setWindowTitle("tactile_viz")
        self.resize(1500, 900)
        self.plotter = Viewport(self, auto_update=False, multi_samples=IDLE_MULTISAMPLES)
        self.plotter.set_background("white")
        if getattr(self.plotter, "iren", None) is not None:
            self.plotter.clear_events_for_key("q")  # pyvista's 'q' would finalise the view
        self.plotter.files_dropped.connect(self._on_files_dropped)
        self.plotter.drag_entered.connect(self._on_drag_entered)
        self.setCentralWidget(self.plotter)
        self.layers = ViewportLayers(self.plotter)
        self.plotter.resized.connect(self.layers.relayout)
        self._build_actions()
        self._build_panel()
        self._build_plots()
        self._lay_out_plots()
        self._build_menu()
        self._build_toolbar()
        self._build_status_bar()
        self._restore_settings()
        self.runner.extra_seconds = lambda since: (_seconds_since(self.plots.draw_log, since)
                                                   + _seconds_since(self.plotter.paint_log,
                                                                    since))
        scene.truth_changed.connect(self._on_truth_changed)
        scene.library_changed.connect(lambda library: self.priors_panel.sync(self.scene))
        scene.settings_changed.connect(self._sync_settings)
        scene.session_reset.connect(self._on_session_reset)
        scene.stepped.connect(self._on_stepped)
        self.layers.show_truth(scene.truth, render=False)
        self.plotter.view_isometric()
        self.frame_truth()
        self._sync_controls()
        if scene.latest is not None:
            self._on_stepped(scene.latest)
        else:
            self._update_status(None)

    def frame_truth(self):
        """Point the camera at the ground truth (on a new object or pose, never per step);
        at everything shown when there is no truth (a recording)."""
        if self.scene.truth is not None and "truth" in self.layers.actors:
            self.plotter.reset_camera(bounds=self.layers.actors["truth"].GetBounds())
        else:
            self.plotter.reset_camera()
        self.plotter.render()

    # ------------------------------------------------------------------ building
    def _build_actions(self):
        slots = {
            "step": lambda: self.start(1), "run": self._on_run_toggled,
            "finish": lambda: self.start(None), "reset": self._on_reset,
            "camera": self.frame_truth, "iso": lambda: self._view("view_isometric"),
            "xy": lambda: self._view("view_xy"), "xz": lambda: self._view("view_xz"),
            "yz": lambda: self._view("view_yz"), "screenshot": self._on_save_screenshot,
            "record": self._on_record_toggled,
            "open_truth": self._open_truth_file, "load_library": self._on_load_library,
            "save_library": self._on_save_library, "load_session": self._on_load_session,
            "open_observations": self._on_open_observations, "export": self._on_export,
            "save_session": self._on_save_session, "quit": self.close,
            "keys": self._show_keys, "about": self._show_about,
        }
        self.actions = {}
        for name, (label, shortcut, tip) in ACTIONS.items():
            action = QAction(label, self)
            if shortcut is not None:
                action.setShortcut(QKeySequence(shortcut))
            if tip:
                action.setToolTip(f"{tip} ({action.shortcut().toString()})"
                                  if shortcut else tip)
            if name in ("run", "record"):
                action.setCheckable(True)
                action.toggled.connect(slots[name])
            else:
                action.triggered.connect(slots[name])
            self.actions[name] = action
            self.addAction(action)  # shortcuts work wherever the focus is in the window

    def _build_panel(self):
        tips = {name: self.actions[name].toolTip() for name in ("step", "run", "finish", "reset")}
        self.loop_panel = LoopPanel(tips)
        self.scene_panel = ScenePanel(self.scene.bundled_objects())
        self.priors_panel = PriorsPanel()
        self.exploration_panel = ExplorationPanel()
        self.layers_panel = LayersPanel()
        self.layers_panel.sync(self.layers.visible)
        self._connect_panels()
        self.panel_scroll = _scrolled([(self.scene_panel, 0), (self.priors_panel, 1),
                                       (self.exploration_panel, 0), (self.layers_panel, 0)])
        # The loop stays above the scrolled groups: it is what one needs most.
        controls = QWidget()
        column = QVBoxLayout(controls)
        column.setContentsMargins(4, 4, 4, 0)
        column.setSpacing(4)
        column.addWidget(self.loop_panel)
        column.addWidget(self.panel_scroll, 1)
        dock = QDockWidget("Controls", self)
        dock.setObjectName("controls")
        dock.setWidget(controls)
        # Closable too: View > Controls / Plots hides and shows it (else greyed out).
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable
                         | QDockWidget.DockWidgetClosable)
        self.addDockWidget(Qt.LeftDockWidgetArea, dock)
        self.controls_dock = dock

    def _connect_panels(self):
        loop = self.loop_panel
        loop.step_requested.connect(lambda: self.start(1))
        loop.run_toggled.connect(self._on_run_toggled)
        loop.finish_requested.connect(lambda: self.start(None))
        loop.reset_requested.connect(self._on_reset)
        loop.scrubbed.connect(self._on_scrub)
        truth = self.scene_panel
        truth.object_chosen.connect(self._on_object_chosen)
        truth.open_file_requested.connect(self._on_open_file_chosen)
        truth.pose_requested.connect(lambda seed: self._guarded(self.scene.randomize_pose, seed))
        priors = self.priors_panel
        priors.prior_toggled.connect(self._on_prior_toggled)
        priors.load_mesh_requested.connect(self._on_load_prior_mesh)
        priors.load_library_requested.connect(self._on_load_library)
        priors.save_library_requested.connect(self._on_save_library)
        priors.learn_requested.connect(self._on_learn)
        exploration = self.exploration_panel
        exploration.strategy_chosen.connect(
            lambda name: self._guarded(self.scene.set_strategy, name))
        exploration.preset_chosen.connect(lambda name: self._guarded(self.scene.set_preset, name))
        exploration.parameter_changed.connect(
            lambda name, value: self._guarded(self.scene.set_parameter, name, value))
        self.layers_panel.layer_toggled.connect(self.layers.set_visible)

    def _build_plots(self):
        self.plots = PlotsWidget()
        dock = QDockWidget("Plots", self)
        dock.setObjectName("plots")
        dock.setWidget(self.plots)
        # Closable too: View > Controls / Plots hides and shows it (else greyed out).
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable
                         | QDockWidget.DockWidgetClosable)
        self.addDockWidget(Qt.RightDockWidgetArea, dock)
        self.plots_dock = dock

    def _build_menu(self):
        file_menu = self.menuBar().addMenu("&File")
        for name in ("open_truth", "load_library", "save_library", None, "load_session",
                     "save_session", None, "open_observations", "export", None, "screenshot",
                     "record", None, "quit"):
            if name is None:
                file_menu.addSeparator()
            else:
                file_menu.addAction(self.actions[name])
        run_menu = self.menuBar().addMenu("&Run")
        for name in ("step", "run", "finish", "reset"):
            run_menu.addAction(self.actions[name])
        view_menu = self.menuBar().addMenu("&View")
        for name in ("camera", "iso", "xy", "xz", "yz"):
            view_menu.addAction(self.actions[name])
        view_menu.addSeparator()
        view_menu.addAction(self.controls_dock.toggleViewAction())
        view_menu.addAction(self.plots_dock.toggleViewAction())
        help_menu = self.menuBar().addMenu("&Help")
        help_menu.addAction(self.actions["keys"])
        help_menu.addAction(self.actions["about"])

    def _build_toolbar(self):
        toolbar = self.addToolBar("Main")
        toolbar.setObjectName("toolbar")
        for name in ("step", "run", "finish", "reset", None, "camera", "iso", "xy", "xz",
                     "yz", None, "screenshot", "record"):
            if name is None:
                toolbar.addSeparator()
            else:
                toolbar.addAction(self.actions[name])
        self.toolbar = toolbar

    def _build_status_bar(self):
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setFormat("step %v of %m")
        self.progress.setToolTip("Steps taken of the step cap (known or novel)")
        self.dhd_label = QLabel()
        self.dhd_label.setToolTip("Termination: the run stops when the DHD falls below eps. "
                                  "Both in scene units: eps (set in size units) times a "
                                  "sixth of the estimated object's longest side")
        self.statusBar().addPermanentWidget(self.dhd_label)
        self.statusBar().addPermanentWidget(self.progress)

    # ------------------------------------------------------------------ settings
    def _restore_settings(self):
        geometry = self.settings.value("window/geometry")
        if isinstance(geometry, QByteArray) and not geometry.isEmpty():
            self.restoreGeometry(geometry)
        state = self.settings.value("window/state")
        if isinstance(state, QByteArray) and not state.isEmpty():
            self.restoreState(state)
        else:  # the viewport gets the room the docks do not need
            self.resizeDocks([self.plots_dock], [PLOTS_WIDTH], Qt.Horizontal)

    def _save_settings(self):
        self.settings.setValue("window/geometry", self.saveGeometry())
        self.settings.setValue("window/state", self.saveState())
        self.settings.sync()

    def _folder(self, kind):
        folder = self.settings.value(f"folders/{kind}", "")
        return folder if isinstance(folder, str) and os.path.isdir(folder) else ""

    def _remember(self, kind, path):
        path = Path(path)
        self.settings.setValue(f"folders/{kind}", str(path if path.is_dir() else path.parent))

    # ------------------------------------------------------------------ running
    @property
    def running(self):
        return self.runner.running

    @property
    def loading(self):
        return self.loader is not None

    def start(self, count):
        """Run ``count`` steps (None: to termination) in the worker thread."""
        if self.running or self.loading:
            return
        try:
            session = self.scene.ensure_session()
        except TactileVizError as error:
            self.show_error(error)
            self._show_running(False)
            return
        if session.terminated:
            self.statusBar().showMessage("the session has terminated: Reset to start again",
                                         STATUS_SECONDS)
            self._show_running(False)
            return
        if count is None and self.engine is None:
            # The plots take the run's layout now (if they had not: a session stepped
            # before), before the worker competes for the interpreter.
            self.plots.set_run_steps(_step_cap(session.params), now=True)
        self.runner.start(session, self.scene.generation, count)
        if count is None and self.engine is not None:
            # In a later pass of the event loop, while the process takes the first steps
            # (a full draw, 0.1-0.35 s, is no part of the click's handling).
            self.plots.set_run_steps(_step_cap(session.params))
        self._show_running(True)

    def pause(self):
        """Stop after the step in progress."""
        self.runner.stop()

    def wait_for_worker(self, milliseconds=30_000):
        """Stop the worker after the step in progress and wait for it (closing)."""
        self._cancel_load()
        done = self.runner.shutdown(milliseconds)
        self.loader = None
        return done

    def _draw(self, snapshot):
        self._drawing_run = True
        try:
            self.scene.announce(snapshot)
        finally:
            self._drawing_run = False

    def _lay_out_plots(self):
        """A new session's plots: the priors' bars and the axes a run fills (the step axis
        to the cap), so that a run from the start is blitted from its first step."""
        self.plots.set_classes(self.scene.active_library().names)
        self.plots.set_run_steps(_step_cap(self.scene.params))

    def _on_run_finished(self):
        self._show_running(False)
        self.plots.set_run_steps(None)

    def _on_run_toggled(self, checked):
        if checked:
            self.start(None)
        else:
            self.pause()

    def _show_running(self, running):
        """Buttons, actions and the run toggle as they are while (not) running."""
        run = self.actions["run"]
        with blocked(run):
            run.setChecked(running)
            run.setText("Pause" if running else "Run")
        self._set_controls_enabled(not running and not self.loading)
        self.loop_panel.set_running(running, self.loading)
        run.setEnabled(not self.loading)
        self._set_multisamples(RUNNING_MULTISAMPLES if running else IDLE_MULTISAMPLES)

    def _set_multisamples(self, samples):
        window = getattr(self.plotter, "render_window", None)
        if window is not None and window.GetMultiSamples() != samples:
            window.SetMultiSamples(samples)
            # Translucent layers are blended in draw order rather than order-independently
            # while running (a third of a software render), and exactly again when idle.
            self.plotter.renderer.SetUseOIT(samples == IDLE_MULTISAMPLES)
            # Repaint in the next paint; Qt merges this with a pending step's paint.
            QWidget.update(self.plotter)

    def scene_controls(self):
        """Every widget and action that changes the scene (disabled while steps run)."""
        widgets = [control for panel in (self.loop_panel, self.scene_panel, self.priors_panel,
                                         self.exploration_panel) for control in panel.controls()]
        actions = [self.actions[name] for name in ("step", "finish", "reset", "open_truth",
                                                   "load_library", "save_library",
                                                   "load_session", "save_session",
                                                   "open_observations", "export")]
        return widgets + actions

    def _set_controls_enabled(self, enabled):
        for control in self.scene_controls():
            control.setEnabled(enabled)
        self.plotter.drops_enabled = enabled  # a dropped file changes the scene too
        if enabled:
            self.priors_panel.learn_button.setEnabled(self.scene.can_learn())

    def _idle(self, what="that"):
        """True when the scene may change; else says why in the status bar."""
        if self.running or self.loading:
            self.statusBar().showMessage(f"Pause first: {what} changes the scene",
                                         STATUS_SECONDS)
            return False
        return True

    def closeEvent(self, event):
        self.stop_recording()
        self._save_settings()
        self.wait_for_worker()
        self.plots.close()
        self.plotter.close()
        super().closeEvent(event)

    # ------------------------------------------------------------------ scene events
    def _sync_controls(self):
        """Fill every control from the scene."""
        self.scene_panel.sync(self.scene)
        self.priors_panel.sync(self.scene)
        self.exploration_panel.sync(self.scene)

    def _sync_settings(self):
        self.exploration_panel.sync(self.scene)

    def _on_truth_changed(self, truth):
        self.layers.show_truth(truth, render=False)
        self.frame_truth()
        self.scene_panel.sync(self.scene)

    def _on_session_reset(self):
        self.loop_panel.set_history(0)
        self.layers.clear_session(render=False)
        self.plotter.schedule_render()
        self._plots_timer.stop()
        self._plots_step = None
        self.plots.update_plots([])
        self._lay_out_plots()
        self._update_status(None)

    def _on_stepped(self, snapshot):
        self._show_step(snapshot)
        if self.recorder is not None:
            self.recorder.add(widget_frame(self))
        self.loop_panel.set_history(snapshot.step)

    def _show_step(self, snapshot):
        self.layers.models = self.scene.session.library
        self.layers.show_snapshot(snapshot, render=False)
        self.plotter.schedule_render()
        self._plots_step = snapshot.step
        if self.running or self._drawing_run:
            # In a later pass of the event loop (also for the run's last step, which the
            # run's end draws at once), so the loop is not blocked for the viewport and
            # the plots together.
            self._plots_timer.start()
        else:
            self.plots.set_run_steps(None)  # a step outside a run: fitted to the data
            self._flush_plots()
        self._update_status(snapshot)

    def _flush_plots(self):
        self._plots_timer.stop()
        step, self._plots_step = self._plots_step, None
        if step is not None:
            self.plots.update_plots(self.scene.snapshots[:step])

    def _on_scrub(self, step):
        """Show step ``step`` of the current session (1 is the first)."""
        snapshots = self.scene.snapshots
        if not self.running and 1 <= step <= len(snapshots):
            self._show_step(snapshots[step - 1])

    def _update_status(self, snapshot):
        # Lengths in scene units: the errors against the truth's size, the DHD against eps
        # scaled by the MAP object's (the priors' before a step), as the session does.
        scene = self.scene
        size, eps = scene.truth_size(snapshot), scene.eps_length(snapshot)
        self.loop_panel.show_snapshot(snapshot, size)
        self.plots.set_unit_name(scene.unit_name)
        self.plots.set_stop_lines(scene.error_threshold(snapshot), eps)
        learn_button = self.priors_panel.learn_button
        if snapshot is None:
            self.statusBar().showMessage("new session: press Step or Run to start touching",
                                         STATUS_SECONDS)
            learn_button.setEnabled(False)
            self._set_progress(0, scene.params.max_steps_known)
            self.dhd_label.setText(f"DHD - / eps {format_length(eps, size)}")
            return
        self.statusBar().showMessage(status_text(snapshot, size))
        params = scene.session_params
        cap = params.max_steps_novel if snapshot.novel else params.max_steps_known
        self._set_progress(snapshot.step, max(cap, snapshot.step))
        self.dhd_label.setText(f"DHD {format_length(snapshot.dhd, size)} / "
                               f"eps {format_length(eps, size)}")
        learn_button.setEnabled(not self.running and scene.can_learn())

    def _set_progress(self, value, maximum):
        """Without QProgressBar's synchronous repaint, which repaints the whole window (the
        viewport too) inside ``setValue``: the bar is painted in the next pass instead."""
        self.progress.setUpdatesEnabled(False)
        self.progress.setRange(0, maximum)
        self.progress.setValue(value)
        self.progress.setUpdatesEnabled(True)
        self.progress.update()

    # ------------------------------------------------------------------ controls
    def _on_prior_toggled(self, name, enabled):
        if not self._guarded(self.scene.set_prior_enabled, name, enabled):
            self.priors_panel.sync(self.scene)

    def _on_object_chosen(self, name):
        self._guarded(self.scene.set_truth_bundled, name)
        self.scene_panel.sync(self.scene)

    def _on_open_file_chosen(self):
        self._open_truth_file()
        self.scene_panel.sync(self.scene)

    def _open_truth_file(self):
        if self._idle("a new ground truth"):
            path, _ = QFileDialog.getOpenFileName(self, "Open ground-truth mesh",
                                                  self._folder("meshes"), MESH_FILTER)
            if path:
                self._remember("meshes", path)
                self.load_truth_file(path)
        self.scene_panel.sync(self.scene)

    def load_truth_file(self, path):
        """Use a mesh file as the ground truth (an error box, and no change, if it is bad)."""
        if self._idle("a new ground truth") and self._guarded(self.scene.set_truth_file, path):
            self.statusBar().showMessage(f"ground truth: {path}", STATUS_SECONDS)
            return True
        return False

    def add_prior_file(self, path):
        """Add a mesh file as a new prior (an error box, and no change, if it is bad or its
        name is taken)."""
        if self._idle("a new prior") and self._guarded(self.scene.add_prior_file, path):
            self.statusBar().showMessage(f"added the prior {self.scene.library.names[-1]!r}",
                                         STATUS_SECONDS)
            return True
        return False

    def _on_drag_entered(self, paths, accepted):
        """Say in the status bar what a drop would do (or why it is refused)."""
        if not paths:
            self.statusBar().showMessage("only mesh files (" + " ".join(MESH_SUFFIXES)
                                         + ") and recorded touches (.csv) can be dropped here",
                                         STATUS_SECONDS)
        elif not accepted:
            self._idle("a dropped file")  # says: Pause first
        elif not _is_mesh_path(paths[0]):
            self.statusBar().showMessage(f"drop to replay the touches recorded in "
                                         f"{Path(paths[0]).name}", STATUS_SECONDS)
        else:
            self.statusBar().showMessage(f"drop to use {Path(paths[0]).name} as the object; "
                                         "hold Shift to add it as a prior", STATUS_SECONDS)

    def _on_files_dropped(self, paths, as_prior=False):
        """Files dropped on the viewport, through the scene like the File menu's: recorded
        touches (.csv) are replayed; a mesh becomes the ground truth, or with ``as_prior``
        (Shift held) every dropped mesh is added as a prior."""
        if not paths or not self._idle("a dropped file"):
            return
        paths = [str(path) for path in paths]
        if as_prior and _is_mesh_path(paths[0]):
            for path in paths:
                if not (_is_mesh_path(path) and self.add_prior_file(path)):
                    break
            return
        if _is_mesh_path(paths[0]):
            done = self.load_truth_file(paths[0])
        else:
            done = self.open_observations(paths[0])
        if done and len(paths) > 1:
            self.statusBar().showMessage(f"{len(paths)} files dropped: used the first, "
                                         f"{Path(paths[0]).name}", STATUS_SECONDS)

    def _on_reset(self):
        if self._idle("Reset"):
            self.scene.reset()

    def _on_learn(self):
        if self._idle("Add learned shape"):
            try:
                model = self.scene.add_learned_shape()
            except (TactileVizError, ValueError) as error:
                self.show_error(error)
                return
            self.statusBar().showMessage(f"added the prior {model.name!r}; a new session "
                                         "starts with it", STATUS_SECONDS)

    def _on_load_prior_mesh(self):
        if not self._idle("a new prior"):
            return
        path, _ = QFileDialog.getOpenFileName(self, "Load a mesh as a prior",
                                              self._folder("meshes"), MESH_FILTER)
        if path:
            self._remember("meshes", path)
            self.add_prior_file(path)

    def _on_load_library(self):
        if not self._idle("a new library"):
            return
        folder = QFileDialog.getExistingDirectory(self, "Load a prior library folder",
                                                  self._folder("library"))
        if folder:
            self._remember("library", folder)
            if self._guarded(self.scene.load_library, folder):
                self.statusBar().showMessage(f"loaded {len(self.scene.library)} priors from "
                                             f"{folder}", STATUS_SECONDS)

    def _on_save_library(self):
        if not self._idle("saving"):
            return
        folder = QFileDialog.getExistingDirectory(self, "Save the prior library to a folder",
                                                  self._folder("library"))
        if folder:
            self._remember("library", folder)
            self.save_library(folder)

    def save_library(self, folder):
        if self._guarded(self.scene.save_library, folder):
            self.statusBar().showMessage(f"saved {len(self.scene.library)} priors to {folder}",
                                         STATUS_SECONDS)

    def _on_save_session(self):
        if not self._idle("saving"):
            return
        path, _ = QFileDialog.getSaveFileName(
            self, "Save session", os.path.join(self._folder("sessions"), "session.npz"),
            "Sessions (*.npz)")
        if path:
            self._remember("sessions", path)
            self.save_session(path)

    def save_session(self, path):
        if self._guarded(self.scene.save_session, path):
            self.statusBar().showMessage(f"saved the session ({self.scene.latest.step} steps) "
                                         f"to {path}", STATUS_SECONDS)

    def _on_open_observations(self):
        if not self._idle("opening observations"):
            return
        path, _ = QFileDialog.getOpenFileName(self, "Open observations",
                                              self._folder("observations"),
                                              "Observations (*.csv);;All files (*)")
        if path:
            self._remember("observations", path)
            self.open_observations(path)

    def open_observations(self, path):
        """Step through a recording of touches (an error box, and no change, if it is bad)."""
        if self._idle("opening observations") and self._guarded(self.scene.open_observations,
                                                                path):
            steps = len(self.scene.recording[1])
            self.statusBar().showMessage(f"replaying {path}: {steps} recorded steps; Step or "
                                         "Run to go through them", STATUS_SECONDS)
            return True
        return False

    def _on_export(self):
        if not self._idle("exporting"):
            return
        folder = QFileDialog.getExistingDirectory(self, "Export estimate to folder",
                                                  self._folder("exports"))
        if folder:
            self._remember("exports", folder)
            self.export(folder)

    def export(self, folder):
        """Write the current estimate and touches to ``folder``; says so in the status bar."""
        if self._guarded(self.scene.export, folder):
            self.statusBar().showMessage(f"exported step {self.scene.latest.step} to {folder}",
                                         STATUS_SECONDS)
            return True
        return False

    def _on_load_session(self):
        if not self._idle("loading a session"):
            return
        path, _ = QFileDialog.getOpenFileName(self, "Load session", self._folder("sessions"),
                                              "Sessions (*.npz)")
        if path:
            self._remember("sessions", path)
            self.load_session(path)

    def load_session(self, path):
        """Replay a saved session in a worker, with a progress dialog that can cancel it."""
        if not self._idle("loading a session"):
            return False
        self._load_cancel = cancel = threading.Event()
        dialog = QProgressDialog(f"Replaying {Path(path).name}...", "Cancel", 0, 0, self)
        dialog.setWindowTitle("Load session")
        dialog.setWindowModality(Qt.WindowModal)
        dialog.setMinimumDuration(0)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(self._cancel_load)
        self._load_dialog = dialog
        progress = _Progress(self)
        progress.changed.connect(self._on_load_progress)
        worker = load_session_worker(path, cancel, progress)
        worker.returned.connect(lambda session: self._on_session_loaded(path, session))
        worker.errored.connect(self._on_load_failed)
        worker.finished.connect(self._on_load_finished)
        self.loader = worker
        self._show_running(False)
        self.statusBar().showMessage(f"loading {path}...")
        dialog.show()
        worker.start()
        return True

    def _cancel_load(self):
        if self._load_cancel is not None:
            self._load_cancel.set()

    def _on_load_progress(self, done, total):
        dialog = self._load_dialog
        if dialog is not None:
            dialog.setLabelText(f"Replaying step {done} of {total}..." if total
                                else "Replaying...")
            dialog.setMaximum(total)
            dialog.setValue(done)  # last: a modal dialog's setValue processes events

    def _on_session_loaded(self, path, session):
        if self.loader is None:
            return  # closing
        replaced = self.scene.adopt_session(session)
        message = f"loaded {path} ({session.step_count} steps)"
        if replaced:
            message += (f"; the priors were replaced by the session's {len(session.library)}: "
                        + ", ".join(session.library.names))
        self.statusBar().showMessage(message, 3 * STATUS_SECONDS)

    def _on_load_failed(self, error):
        if self.loader is None:
            return
        if isinstance(error, LoadCancelled):
            self.statusBar().showMessage("loading the session was cancelled; nothing changed",
                                         STATUS_SECONDS)
        else:
            self.show_error(error)

    def _on_load_finished(self):
        self.loader = None
        self._load_cancel = None
        if self._load_dialog is not None:
            self._load_dialog.close()
            self._load_dialog.deleteLater()
            self._load_dialog = None
        self._show_running(self.running)

    def _on_save_screenshot(self):
        path, _ = QFileDialog.getSaveFileName(
            self, "Save screenshot", os.path.join(self._folder("screenshots"), "tactile_viz.png"),
            "PNG images (*.png)")
        if path:
            self._remember("screenshots", path)
            self.save_screenshot(path)

    def save_screenshot(self, path):
        """A PNG of the whole window (viewport, docks, plots)."""
        if self.grab().save(str(path)):
            self.statusBar().showMessage(f"saved a screenshot to {path}", STATUS_SECONDS)
            return True
        self.show_error(OSError(f"cannot write the screenshot {path}"))
        return False

    def _on_record_toggled(self, checked):
        if not checked:
            self.stop_recording()
            return
        path, _ = QFileDialog.getSaveFileName(
            self, "Record steps", os.path.join(self._folder("screenshots"), "tactile_viz.gif"),
            "Animated GIF (*.gif);;MP4 video (*.mp4)")
        if path:
            self._remember("screenshots", path)
        if not (path and self.start_recording(path)):
            self._show_recording(False)

    def start_recording(self, path):
        """Record the whole window at every drawn step to ``path`` (.gif or .mp4)."""
        self.stop_recording()
        try:
            self.recorder = Recorder(path)
        except OSError as error:
            self.show_error(error)
            return False
        self._show_recording(True)
        self.statusBar().showMessage(f"recording the drawn steps to {path}", STATUS_SECONDS)
        return True

    def stop_recording(self):
        """Finish the recording, if any; returns its path."""
        recorder, self.recorder = self.recorder, None
        self._show_recording(False)
        if recorder is None:
            return None
        path = recorder.close()
        self.statusBar().showMessage(f"saved {recorder.frames} frames to {path}", STATUS_SECONDS)
        return path

    def _show_recording(self, recording):
        with blocked(self.actions["record"]):
            self.actions["record"].setChecked(recording)

    def _view(self, method):
        getattr(self.plotter, method)(render=False)
        self.frame_truth()

    def _show_keys(self):
        rows = "".join(f"<tr><td><b>{self.actions[name].shortcut().toString()}</b></td>"
                       f"<td>{ACTIONS[name][0]}</td></tr>"
                       for name in ACTIONS if not self.actions[name].shortcut().isEmpty())
        QMessageBox.information(self, "Keys", "<table cellspacing=4>" + rows + "</table>"
                                "<p>In the viewport: drag to rotate, shift-drag to pan, "
                                "wheel to zoom; drop a mesh file to use it as the ground "
                                "truth (hold Shift to add it as a prior instead), or an "
                                "observation file (.csv) to replay it.</p>")

    def _show_about(self):
        QMessageBox.about(self, "About tactile_viz",
                          "tactile_viz: active tactile object recognition, pose estimation "
                          "and shape transfer (Zheng et al.).")

    def _guarded(self, function, *args):
        """Call a scene method; show the project's errors in a message box. True if it worked."""
        if not self._idle():
            self._sync_controls()
            return False
        try:
            function(*args)
        except (TactileVizError, ValueError, OSError) as error:
            self.show_error(error)
            self._sync_controls()
            return False
        return True

    def show_error(self, error):
        QMessageBox.critical(self, "tactile_viz", str(error))

