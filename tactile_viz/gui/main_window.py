"""The main window: a pyvista viewport, a control panel and plots, on a :class:`Scene`.

The window owns no inference state and no settings of its own: it calls the scene's methods
and, whenever one of the scene's signals fires, fills every control from the scene (so the
command line, a loaded session and a preset all show the same way). Steps run in a worker
thread (see :mod:`tactile_viz.gui.runner`) that yields one immutable snapshot per step; only
the newest snapshot of the current session is drawn, and VTK is touched only on the GUI
thread. While steps run, every control that would change the scene is disabled.
"""

import json
import os
import threading
import time
from collections import deque
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np
from pyvistaqt import QtInteractor
from PySide6.QtCore import QByteArray, QSettings, QSignalBlocker, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDockWidget, QDoubleSpinBox,
                               QFileDialog, QFormLayout, QGroupBox, QHBoxLayout, QLabel,
                               QListWidget, QListWidgetItem, QMainWindow, QMessageBox,
                               QProgressBar, QProgressDialog, QPushButton, QScrollArea,
                               QSizePolicy, QSlider, QSpinBox, QVBoxLayout, QWidget)
from superqt.utils import thread_worker

from ..engine.errors import TactileVizError
from ..engine.exploration import STRATEGIES
from ..engine.session import Session
from .layers import LAYERS, ViewportLayers
from .plots import PlotsWidget
from .recording import Recorder, widget_frame
from .runner import StepRunner

OPEN_FILE = "Open mesh file..."
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
MESH_FILTER = "Meshes (*.obj *.ply *.stl *.off *.glb *.gltf);;All files (*)"
SETTINGS_ORGANIZATION = "tactile_viz"
SETTINGS_APPLICATION = "tactile_viz"
STATUS_SECONDS = 8000  # how long a status-bar message stays, ms
# During a run the plots are drawn this long after the viewport's paint, so that the event
# loop runs in between instead of blocking for both.
PLOTS_DELAY_MS = 30
PLOTS_WIDTH = 320  # the plots dock's width at first start, pixels

# name -> (label, minimum, maximum, step, decimals, tooltip)
PARAMETERS = {
    "sigma_d": ("sigma_d", 1e-3, 100.0, 0.05, 3,
                "Std of the signed-distance likelihood. Larger forgives contacts off the "
                "prior surface (noise, novel shapes) but separates classes less sharply."),
    "sigma_n": ("sigma_n", 1e-3, 100.0, 0.1, 3,
                "Std of the normal likelihood. Larger trusts measured normals less."),
    "eps": ("eps (DHD)", 0.05, 10.0, 0.05, 2,
            "Termination: stop when every point of the estimated surface is within eps of "
            "a contact. Smaller covers the surface more densely at the cost of more steps."),
    "n_s": ("n_s", 1, 500, 1, 0,
            "Earlier contacts paired with each new one to propose particles. More pairs "
            "find the pose sooner but cost time per step."),
    "lam": ("lambda", 0.01, 1.0, 0.01, 2,
            "Sampling gate: new particles are proposed while the MAP fit is below this "
            "fraction of perfect. Higher samples more often (slower, more robust)."),
}

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


@thread_worker(start_thread=False)
def load_session_worker(path, cancel, progress):
    """Load (replay) a saved session in a worker; ``progress(done, total)`` after each
    step, :class:`LoadCancelled` once ``cancel`` is set."""
    total = saved_step_count(path)
    progress(0, total or 0)

    def replayed(snapshot):
        if cancel.is_set():
            raise LoadCancelled()
        progress(snapshot.step, total or 0)

    return Session.load(path, callback=replayed)


class Viewport(QtInteractor):
    """The 3D view: a QtInteractor whose file drops go to the window (and from there through
    the scene, checked like any file), not straight into the plotter as loose actors."""

    files_dropped = Signal(list)

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.last_paint_seconds = 0.0
        self.paint_log = deque(maxlen=10_000)  # (perf_counter at the start, seconds) per paint

    def schedule_render(self):
        """Render once, in the next paint (a synchronous render would be followed by a
        second one in that paint)."""
        QWidget.update(self)

    def paintGL(self):
        began = time.perf_counter()
        super().paintGL()
        self.last_paint_seconds = time.perf_counter() - began
        self.paint_log.append((began, self.last_paint_seconds))

    def dragEnterEvent(self, event):
        if any(_is_mesh_path(url.toLocalFile()) for url in event.mimeData().urls()):
            event.acceptProposedAction()
        else:
            event.ignore()

    def dragMoveEvent(self, event):
        self.dragEnterEvent(event)

    def dropEvent(self, event):
        paths = [url.toLocalFile() for url in event.mimeData().urls()]
        paths = [path for path in paths if _is_mesh_path(path)]
        if paths:
            event.acceptProposedAction()
            self.files_dropped.emit(paths)
        else:
            event.ignore()


def _is_mesh_path(path):
    return bool(path) and os.path.isfile(path) and path.lower().endswith(MESH_SUFFIXES)


class _Progress(QWidget):
    """Emits ``changed(done, total)`` on the GUI thread when called from any thread."""

    changed = Signal(int, int)

    def __call__(self, done, total):
        self.changed.emit(int(done), int(total))


class MainWindow(QMainWindow):
    """The tactile_viz desktop window.

    Parameters
    ----------
    scene : tactile_viz.app.scene.Scene
    settings : QSettings, optional
        Where the window geometry, dock layout and last folders are kept (default: the
        user's tactile_viz settings).
    """

    def __init__(self, scene, parent=None, settings=None):
        super().__init__(parent)
        self.scene = scene
        self.settings = settings if settings is not None else QSettings(
            QSettings.IniFormat, QSettings.UserScope, SETTINGS_ORGANIZATION,
            SETTINGS_APPLICATION)
        self.runner = StepRunner(scene, self._draw, parent=self)
        self.runner.errored.connect(self.show_error)
        self.runner.finished.connect(self._on_run_finished)
        self.loader = None
        self._load_cancel = None
        self._load_dialog = None
        self.recorder = None
        self._plots_step = None
        self._plots_timer = QTimer(self)
        self._plots_timer.setSingleShot(True)
        self._plots_timer.setInterval(PLOTS_DELAY_MS)
        self._plots_timer.timeout.connect(self._flush_plots)
        self.setWindowTitle("tactile_viz")
        self.resize(1500, 900)
        self.plotter = Viewport(self, auto_update=False)
        self.plotter.set_background("white")
        if getattr(self.plotter, "iren", None) is not None:
            self.plotter.clear_events_for_key("q")  # pyvista's 'q' would finalise the view
        self.plotter.files_dropped.connect(self._on_files_dropped)
        self.setCentralWidget(self.plotter)
        self.layers = ViewportLayers(self.plotter)
        self._build_actions()
        self._build_panel()
        self._build_plots()
        self._build_menu()
        self._build_toolbar()
        self._build_status_bar()
        self._restore_settings()
        self.runner.extra_seconds = lambda: (self.plots.last_draw_seconds
                                             + self.plotter.last_paint_seconds)
        scene.truth_changed.connect(self._on_truth_changed)
        scene.library_changed.connect(lambda library: self._fill_priors())
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
        """Point the camera at the ground truth (on a new object or pose, never per step)."""
        bounds = self.layers.actors["truth"].GetBounds()
        self.plotter.reset_camera(bounds=bounds)
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
        panel = QWidget()
        layout = QVBoxLayout(panel)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.setSpacing(4)
        # The loop first: it is what one needs most, and never below the fold.
        layout.addWidget(self._loop_group())
        layout.addWidget(self._scene_group())
        layout.addWidget(self._priors_group())
        layout.addWidget(self._exploration_group())
        layout.addWidget(self._layers_group())
        layout.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(panel)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
        # As wide as the panel wants plus a vertical scroll bar: nothing clipped sideways.
        scroll.setMinimumWidth(panel.sizeHint().width()
                               + scroll.verticalScrollBar().sizeHint().width() + 4)
        self.panel_scroll = scroll
        dock = QDockWidget("Controls", self)
        dock.setObjectName("controls")
        dock.setWidget(scroll)
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable)
        self.addDockWidget(Qt.LeftDockWidgetArea, dock)
        self.controls_dock = dock

    def _scene_group(self):
        group = QGroupBox("Scene")
        form = QFormLayout(group)
        form.setContentsMargins(6, 4, 6, 4)
        self.object_box = QComboBox()
        self.object_box.addItems(self.scene.bundled_objects() + [OPEN_FILE])
        self.object_box.setToolTip("The ground-truth object the sensor touches")
        self.object_box.activated.connect(self._on_object_chosen)
        self.seed_box = QSpinBox()
        self.seed_box.setRange(0, 1_000_000)
        self.seed_box.setToolTip("Seed of the random pose and of the session: Place at seed "
                                 "applies it")
        self.random_button = QPushButton("Random pose")
        self.random_button.clicked.connect(self._on_random_pose)
        self.place_button = QPushButton("Place at seed")
        self.place_button.clicked.connect(lambda: self._guarded(
            self.scene.randomize_pose, self.seed_box.value()))
        buttons = QHBoxLayout()
        buttons.addWidget(self.random_button)
        buttons.addWidget(self.place_button)
        form.addRow("object", self.object_box)
        form.addRow("seed", self.seed_box)
        form.addRow(buttons)
        return group

    def _priors_group(self):
        group = QGroupBox("Priors")
        layout = QVBoxLayout(group)
        layout.setContentsMargins(6, 4, 6, 4)
        self.prior_list = QListWidget()
        self.prior_list.setToolTip("Checked priors are the classes the filter considers")
        self.prior_list.setMaximumHeight(150)
        self.prior_list.itemChanged.connect(self._on_prior_toggled)
        layout.addWidget(self.prior_list)
        row = QHBoxLayout()
        self.prior_buttons = []
        for label, slot in (("Load mesh...", self._on_load_prior_mesh),
                            ("Load library...", self._on_load_library),
                            ("Save library...", self._on_save_library)):
            button = QPushButton(label)
            button.clicked.connect(slot)
            row.addWidget(button)
            self.prior_buttons.append(button)
        layout.addLayout(row)
        self.learn_button = QPushButton("Add learned shape")
        self.learn_button.setToolTip("Add the reconstructed novel shape to the priors")
        self.learn_button.clicked.connect(self._on_learn)
        layout.addWidget(self.learn_button)
        return group

    def _exploration_group(self):
        group = QGroupBox("Exploration")
        form = QFormLayout(group)
        form.setContentsMargins(6, 4, 6, 4)
        self.strategy_box = QComboBox()
        self.strategy_box.addItems(list(STRATEGIES))
        self.strategy_box.setToolTip("gpis-dhd: aim where the estimate is least covered "
                                     "(paper); rrt: random tangent steps (baseline)")
        self.strategy_box.activated.connect(
            lambda index: self._guarded(self.scene.set_strategy,
                                        self.strategy_box.itemText(index)))
        self.preset_box = QComboBox()
        self.preset_box.setToolTip("fast: coarser grids, fewer features; paper: the paper's "
                                   "values; refined: the paper's values plus MAP pose refinement; "
                                   "accurate: finer grids, neighbour bins, refinement")
        self.preset_box.activated.connect(
            lambda index: self._guarded(self.scene.set_preset, self.preset_box.itemText(index)))
        form.addRow("strategy", self.strategy_box)
        form.addRow("preset", self.preset_box)
        self.parameter_boxes = {}
        for name, (label, low, high, step, decimals, tip) in PARAMETERS.items():
            box = QSpinBox() if decimals == 0 else QDoubleSpinBox()
            if decimals:
                box.setDecimals(decimals)
            box.setRange(low, high)
            box.setSingleStep(step)
            box.setToolTip(tip)
            box.setKeyboardTracking(False)
            box.valueChanged.connect(lambda value, n=name: self._guarded(
                self.scene.set_parameter, n, value))
            form.addRow(label, box)
            self.parameter_boxes[name] = box
        return group

    def _loop_group(self):
        group = QGroupBox("Loop")
        layout = QVBoxLayout(group)
        layout.setContentsMargins(6, 4, 6, 4)
        row = QHBoxLayout()
        self.step_button = QPushButton("Step")
        self.step_button.clicked.connect(lambda: self.start(1))
        self.run_button = QPushButton("Run")
        self.run_button.setCheckable(True)
        self.run_button.toggled.connect(self._on_run_toggled)
        self.finish_button = QPushButton("Run to termination")
        self.finish_button.clicked.connect(lambda: self.start(None))
        self.reset_button = QPushButton("Reset")
        self.reset_button.clicked.connect(self._on_reset)
        for name, button in (("step", self.step_button), ("run", self.run_button),
                             ("finish", self.finish_button), ("reset", self.reset_button)):
            button.setToolTip(self.actions[name].toolTip())
            row.addWidget(button)
        layout.addLayout(row)
        self.step_label = QLabel("step 0")
        self.status_label = QLabel()
        self.status_label.setWordWrap(True)
        self.status_label.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)
        self.history_slider = QSlider(Qt.Horizontal)
        self.history_slider.setRange(0, 0)
        self.history_slider.setToolTip("Scrub through the steps taken so far (not while "
                                       "running); the next step continues from the last")
        self.history_slider.valueChanged.connect(self._on_scrub)
        layout.addWidget(self.step_label)
        layout.addWidget(self.history_slider)
        layout.addWidget(self.status_label)
        return group

    def _layers_group(self):
        group = QGroupBox("Layers")
        layout = QVBoxLayout(group)
        layout.setContentsMargins(6, 4, 6, 4)
        layout.setSpacing(0)
        self.layer_boxes = {}
        for name, (label, color) in LAYERS.items():
            box = QCheckBox(label)
            box.setChecked(self.layers.visible[name])
            shown = {"truth": "steelblue", "gpis": "teal"}.get(name, color)
            box.setStyleSheet(f"QCheckBox {{ color: {shown}; }}")
            box.toggled.connect(lambda checked, n=name: self.layers.set_visible(n, checked))
            layout.addWidget(box)
            self.layer_boxes[name] = box
        return group

    def _build_plots(self):
        self.plots = PlotsWidget()
        dock = QDockWidget("Plots", self)
        dock.setObjectName("plots")
        dock.setWidget(self.plots)
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable)
        self.addDockWidget(Qt.RightDockWidgetArea, dock)
        self.plots_dock = dock

    def _build_menu(self):
        file_menu = self.menuBar().addMenu("&File")
        for name in ("open_truth", "load_library", "save_library", None, "load_session",
                     "save_session", None, "screenshot", "record", None, "quit"):
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
        self.dhd_label.setToolTip("Termination: the run stops when the DHD falls below eps")
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
        self.runner.start(session, self.scene.generation, count)
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
        self.scene.announce(snapshot)

    def _on_run_finished(self):
        self._show_running(False)

    def _on_run_toggled(self, checked):
        if checked:
            self.start(None)
        else:
            self.pause()

    def _show_running(self, running):
        """Buttons, actions and the run toggle as they are while (not) running."""
        for toggle in (self.run_button, self.actions["run"]):
            toggle.blockSignals(True)
            toggle.setChecked(running)
            toggle.setText("Pause" if running else "Run")
            toggle.blockSignals(False)
        self._set_controls_enabled(not running and not self.loading)
        self.history_slider.setEnabled(not running and not self.loading)
        self.run_button.setEnabled(not self.loading)
        self.actions["run"].setEnabled(not self.loading)

    def scene_controls(self):
        """Every widget and action that changes the scene (disabled while steps run)."""
        widgets = [self.step_button, self.finish_button, self.reset_button, self.object_box,
                   self.seed_box, self.random_button, self.place_button, self.prior_list,
                   *self.prior_buttons, self.learn_button, self.strategy_box, self.preset_box,
                   *self.parameter_boxes.values()]
        actions = [self.actions[name] for name in ("step", "finish", "reset", "open_truth",
                                                   "load_library", "save_library",
                                                   "load_session", "save_session")]
        return widgets + actions

    def _set_controls_enabled(self, enabled):
        for control in self.scene_controls():
            control.setEnabled(enabled)
        if enabled:
            self.learn_button.setEnabled(self.scene.can_learn())

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
        self._show_truth_choice()
        self._fill_priors()
        self._sync_settings()

    def _show_truth_choice(self):
        name = self.scene.truth_model.name
        with _blocked(self.object_box, self.seed_box):
            if self.object_box.findText(name) < 0:
                self.object_box.insertItem(self.object_box.count() - 1, name)
            self.object_box.setCurrentText(name)
            self.seed_box.setValue(self.scene.seed)

    def _sync_settings(self):
        """Strategy, preset and parameter boxes as the scene has them."""
        with _blocked(self.strategy_box, self.preset_box, *self.parameter_boxes.values()):
            self.strategy_box.setCurrentText(self.scene.strategy)
            names = self.scene.preset_names()
            if [self.preset_box.itemText(i) for i in range(self.preset_box.count())] != names:
                self.preset_box.clear()
                self.preset_box.addItems(names)
            self.preset_box.setCurrentText(self.scene.preset)
            for name, box in self.parameter_boxes.items():
                box.setValue(self.scene.parameter(name))

    def _on_truth_changed(self, truth):
        self.layers.show_truth(truth, render=False)
        self.frame_truth()
        self._show_truth_choice()

    def _on_session_reset(self):
        with _blocked(self.history_slider):
            self.history_slider.setRange(0, 0)
        self.layers.clear_session(render=False)
        self.plotter.schedule_render()
        self._plots_timer.stop()
        self._plots_step = None
        self.plots.update_plots([])
        self._update_status(None)

    def _on_stepped(self, snapshot):
        self._show_step(snapshot)
        if self.recorder is not None:
            self.recorder.add(widget_frame(self))
        with _blocked(self.history_slider):
            self.history_slider.setRange(1, snapshot.step)
            self.history_slider.setValue(snapshot.step)

    def _show_step(self, snapshot):
        self.layers.models = self.scene.session.library
        self.layers.show_snapshot(snapshot, render=False)
        self.plotter.schedule_render()
        self._plots_step = snapshot.step
        if self.running:
            self._plots_timer.start()
        else:
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
        eps = self.scene.parameter("eps")
        if snapshot is None:
            self.step_label.setText("step 0")
            self.status_label.setText("Press Step or Run to start touching.")
            self.statusBar().showMessage("new session: press Step or Run to start touching",
                                         STATUS_SECONDS)
            self.learn_button.setEnabled(False)
            self._set_progress(0, self.scene.params.max_steps_known)
            self.dhd_label.setText(f"DHD - / eps {eps:.2f}")
            self.plots.set_eps(eps)
            return
        recon = "-" if snapshot.recon_error is None else f"{snapshot.recon_error:.2f}"
        seconds = sum(snapshot.timings.values())
        self.step_label.setText(f"step {snapshot.step}" + (" (terminated)" if snapshot.terminated else ""))
        text = (f"{'NOVEL' if snapshot.novel else 'known'} | MAP {snapshot.map_class} | "
                f"DHD {snapshot.dhd:.2f} | pose error {snapshot.pose_error:.2f} | "
                f"recon error {recon} | particles {snapshot.n_particles} | "
                f"last step {seconds:.2f} s")
        self.status_label.setText(text)
        self.statusBar().showMessage(text)
        params = self.scene.session.params if self.scene.session is not None else self.scene.params
        cap = params.max_steps_novel if snapshot.novel else params.max_steps_known
        self._set_progress(snapshot.step, max(cap, snapshot.step))
        self.dhd_label.setText(f"DHD {snapshot.dhd:.2f} / eps {params.eps:.2f}")
        self.plots.set_eps(params.eps)
        self.learn_button.setEnabled(not self.running and self.scene.can_learn())

    def _set_progress(self, value, maximum):
        """Without QProgressBar's synchronous repaint, which repaints the whole window (the
        viewport too) inside ``setValue``: the bar is painted in the next pass instead."""
        self.progress.setUpdatesEnabled(False)
        self.progress.setRange(0, maximum)
        self.progress.setValue(value)
        self.progress.setUpdatesEnabled(True)
        self.progress.update()

    # ------------------------------------------------------------------ controls
    def _fill_priors(self):
        with _blocked(self.prior_list):
            self.prior_list.clear()
            for name in self.scene.library.names:
                item = QListWidgetItem(name)
                item.setFlags(item.flags() | Qt.ItemIsUserCheckable)
                item.setCheckState(Qt.Checked if self.scene.enabled[name] else Qt.Unchecked)
                self.prior_list.addItem(item)

    def _on_prior_toggled(self, item):
        if not self._guarded(self.scene.set_prior_enabled, item.text(),
                             item.checkState() == Qt.Checked):
            self._fill_priors()

    def _on_object_chosen(self, index):
        text = self.object_box.itemText(index)
        if text == OPEN_FILE:
            self._open_truth_file()
        else:
            self._guarded(self.scene.set_truth_bundled, text)
        self._show_truth_choice()

    def _open_truth_file(self):
        if self._idle("a new ground truth"):
            path, _ = QFileDialog.getOpenFileName(self, "Open ground-truth mesh",
                                                  self._folder("meshes"), MESH_FILTER)
            if path:
                self._remember("meshes", path)
                self.load_truth_file(path)
        self._show_truth_choice()

    def load_truth_file(self, path):
        """Use a mesh file as the ground truth (an error box, and no change, if it is bad)."""
        if self._idle("a new ground truth") and self._guarded(self.scene.set_truth_file, path):
            self.statusBar().showMessage(f"ground truth: {path}", STATUS_SECONDS)

    def _on_files_dropped(self, paths):
        if len(paths) > 1:
            self.statusBar().showMessage(f"{len(paths)} files dropped: using the first",
                                         STATUS_SECONDS)
        self.load_truth_file(paths[0])

    def _on_random_pose(self):
        seed = int(np.random.default_rng().integers(1_000_000))
        self._guarded(self.scene.randomize_pose, seed)

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
            if self._guarded(self.scene.add_prior_file, path):
                self.statusBar().showMessage(f"added the prior {self.scene.library.names[-1]!r}",
                                             STATUS_SECONDS)

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
        with _blocked(self.actions["record"]):
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
                                "truth.</p>")

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


@contextmanager
def _blocked(*widgets):
    """Block the signals of some widgets within a ``with`` block (QSignalBlocker each)."""
    with ExitStack() as stack:
        for widget in widgets:
            stack.enter_context(QSignalBlocker(widget))
        yield
