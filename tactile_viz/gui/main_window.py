"""The main window: a pyvista viewport, the Controls dock's panels and plots, on a :class:`Scene`.

The window owns no inference state and no settings of its own. The panels of
:mod:`tactile_viz.gui.panels` build the controls; the window connects their signals to the
scene's methods and, whenever one of the scene's signals fires, has the panels fill their
widgets from the scene (so the command line, a loaded session and a preset all show the same
way). Steps run in a worker thread (see :mod:`tactile_viz.gui.runner`) that yields one
immutable snapshot per step; only the newest snapshot of the current session is drawn, and
VTK is touched only on the GUI thread. While steps run, every control that would change the
scene is disabled.

The commands (menus, toolbar, shortcuts, file dialogs, drops) are the table of
:mod:`tactile_viz.gui.actions`; the 3D view is :mod:`tactile_viz.gui.viewport`; a saved
session is replayed by :mod:`tactile_viz.gui.session_loader`.
"""

from PySide6.QtCore import QByteArray, QSettings, Qt, QTimer
from PySide6.QtWidgets import QDockWidget, QMainWindow, QMessageBox, QVBoxLayout, QWidget

from ..app.engine_process import ENGINES, shared_engine
from ..engine.errors import TactileVizError
from . import actions as commands, recording
from .layers import ViewportLayers
from .panels import ExplorationPanel, LayersPanel, LoopPanel, PriorsPanel, ScenePanel
from .panels.base import blocked, scrolled
from .plots import PlotsWidget
from .recording import widget_frame
from .runner import StepRunner, seconds_since
from .session_loader import SessionLoad
from .status_bar import STATUS_SECONDS, StatusBar
from .viewport import IDLE_MULTISAMPLES, RUNNING_MULTISAMPLES, Viewport  # noqa: F401 (tests)

SETTINGS_ORGANIZATION = "tactile_viz"
SETTINGS_APPLICATION = "tactile_viz"
# During a run the plots are drawn this long after the viewport's paint, so that the event
# loop runs in between instead of blocking for both.
PLOTS_DELAY_MS = 30
PLOTS_WIDTH = 320  # the plots dock's width at first start, pixels


def _step_cap(params):
    """The most steps a session with ``params`` takes (known or novel)."""
    return max(params.max_steps_known, params.max_steps_novel)


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
        self.loader = None  # a SessionLoad while a saved session is replayed
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
        self.plotter.files_dropped.connect(
            lambda paths, as_prior: commands.drop_files(self, paths, as_prior))
        self.plotter.drag_entered.connect(
            lambda paths, accepted: commands.drag_entered(self, paths, accepted))
        self.setCentralWidget(self.plotter)
        self.layers = ViewportLayers(self.plotter, scene.reference_size)
        self._framed_nothing = False  # the camera framed a scene with nothing shown yet
        self.plotter.resized.connect(self.layers.relayout)
        self.actions = commands.create_actions(self)
        self._build_panel()
        self._build_plots()
        self._lay_out_plots()
        self._build_menus()
        self._build_status_bar()
        self._restore_settings()
        self.runner.extra_seconds = lambda since: (seconds_since(self.plots.draw_log, since)
                                                   + seconds_since(self.plotter.paint_log,
                                                                   since))
        scene.truth_changed.connect(self._on_truth_changed)
        scene.library_changed.connect(lambda library: self.priors_panel.sync(self.scene))
        scene.settings_changed.connect(self._sync_settings)
        scene.session_reset.connect(self._on_session_reset)
        scene.stepped.connect(self._on_stepped)
        self.layers.show_truth(scene.truth, render=False)
        self.layers.show_scene(scene.robot_scene, scene.truth, render=False)
        self.plotter.view_isometric()
        self.frame_truth()
        self._sync_controls()
        if scene.latest is not None:
            self._on_stepped(scene.latest)
        else:
            self._update_status(None)

    def frame_truth(self, render=True):
        """Point the camera at the ground truth (on a new object or pose, never per step);
        at everything shown when there is no truth (a recording), at a box as long as the
        scene's length scale when nothing is shown yet (then again at the first step). The
        clipping range holds everything drawn."""
        self._framed_nothing = not self.layers.framed()
        self.plotter.reset_camera(bounds=self.layers.bounds(), render=False)
        self.layers.fit_clipping_range()
        if render:
            self.plotter.render()

    def look(self, method):
        """Look along an axis (``method``: the plotter's view_xy, view_isometric, ...)."""
        getattr(self.plotter, method)(render=False)
        self.frame_truth()

    # ------------------------------------------------------------------ building
    def _build_panel(self):
        self.loop_panel = LoopPanel(self.actions)
        self.scene_panel = ScenePanel(self.scene.bundled_objects())
        self.priors_panel = PriorsPanel()
        self.exploration_panel = ExplorationPanel()
        self.layers_panel = LayersPanel()
        self.layers_panel.sync(self.layers.visible)
        self._connect_panels()
        self.panel_scroll = scrolled([(self.scene_panel, 0), (self.priors_panel, 1),
                                      (self.exploration_panel, 0), (self.layers_panel, 0)])
        # The loop stays above the scrolled groups: it is what one needs most.
        controls = QWidget()
        column = QVBoxLayout(controls)
        column.setContentsMargins(4, 4, 4, 0)
        column.setSpacing(4)
        column.addWidget(self.loop_panel)
        column.addWidget(self.panel_scroll, 1)
        self.controls_dock = self._dock("Controls", "controls", controls, Qt.LeftDockWidgetArea)

    def _dock(self, title, name, widget, area):
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        # Closable too: View > Controls / Plots hides and shows it (else greyed out).
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable
                         | QDockWidget.DockWidgetClosable)
        self.addDockWidget(area, dock)
        return dock

    def _connect_panels(self):
        self.loop_panel.scrubbed.connect(self._on_scrub)  # its buttons are the actions'
        truth = self.scene_panel
        truth.object_chosen.connect(self._on_object_chosen)
        truth.open_file_requested.connect(lambda: commands.open_truth_file(self))
        truth.pose_requested.connect(lambda seed: self.guarded(self.scene.randomize_pose, seed))
        priors = self.priors_panel
        priors.prior_toggled.connect(self._on_prior_toggled)
        priors.load_mesh_requested.connect(lambda: commands.OPEN_PRIOR_FILE(self))
        priors.load_library_requested.connect(lambda: commands.OPEN_LIBRARY(self))
        priors.save_library_requested.connect(lambda: commands.SAVE_LIBRARY_TO(self))
        priors.learn_requested.connect(self._on_learn)
        exploration = self.exploration_panel
        exploration.strategy_chosen.connect(
            lambda name: self.guarded(self.scene.set_strategy, name))
        exploration.preset_chosen.connect(lambda name: self.guarded(self.scene.set_preset, name))
        exploration.parameter_changed.connect(
            lambda name, value: self.guarded(self.scene.set_parameter, name, value))
        self.layers_panel.layer_toggled.connect(self.layers.set_visible)

    def _build_plots(self):
        self.plots = PlotsWidget()
        self.plots_dock = self._dock("Plots", "plots", self.plots, Qt.RightDockWidgetArea)

    def _build_menus(self):
        """The menus and the toolbar, from the table of :mod:`tactile_viz.gui.actions`."""
        def fill(container, names):
            for name in names:
                if name is None:
                    container.addSeparator()
                else:
                    container.addAction(self.actions[name])

        for menu_id, title in commands.MENUS:
            menu = self.menuBar().addMenu(title)
            fill(menu, commands.placed(menu_id))
            if menu_id == "view":
                menu.addSeparator()
                menu.addAction(self.controls_dock.toggleViewAction())
                menu.addAction(self.plots_dock.toggleViewAction())
        self.toolbar = self.addToolBar("Main")
        self.toolbar.setObjectName("toolbar")
        fill(self.toolbar, commands.placed("toolbar"))

    def _build_status_bar(self):
        self.setStatusBar(StatusBar())
        self.progress, self.dhd_label = self.statusBar().progress, self.statusBar().dhd_label

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

    def run_toggled(self, checked):
        if checked:
            self.start(None)
        else:
            self.pause()

    def wait_for_worker(self, milliseconds=30_000):
        """Stop the worker after the step in progress and wait for it (closing)."""
        if self.loader is not None:
            self.loader.abandon()
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

    def _show_running(self, running):
        """Buttons, actions and the run toggle as they are while (not) running."""
        run = self.actions["run"]
        with blocked(run):
            run.setChecked(running)
            run.setText("Pause" if running else "Run")
        self._set_controls_enabled(not running and not self.loading)
        self.loop_panel.set_running(running, self.loading)
        run.setEnabled(not self.loading)
        self.plotter.set_running(running)

    def scene_controls(self):
        """Every widget and action that changes the scene (disabled while steps run)."""
        widgets = [control for panel in (self.loop_panel, self.scene_panel, self.priors_panel,
                                         self.exploration_panel) for control in panel.controls()]
        return widgets + [self.actions[name] for name in commands.scene_actions()]

    def _set_controls_enabled(self, enabled):
        for control in self.scene_controls():
            control.setEnabled(enabled)
        self.plotter.drops_enabled = enabled  # a dropped file changes the scene too
        if enabled:
            self.priors_panel.learn_button.setEnabled(self.scene.can_learn())

    def idle(self, what="that"):
        """True when the scene may change; else says why in the status bar."""
        if self.running or self.loading:
            self.statusBar().showMessage(f"Pause first: {what} changes the scene",
                                         STATUS_SECONDS)
            return False
        return True

    def guarded(self, function, *args):
        """Call a scene method; show the project's errors in a message box. True if it worked."""
        if not self.idle():
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

    def closeEvent(self, event):
        self.runner.stop()  # first: saving and closing below take time the engine would step on
        self.stop_recording()
        self._save_settings()
        self.wait_for_worker()
        self.plots.close()
        self.plotter.close()
        # pyvistaqt keeps its GL context's surface, which Qt frees with the widget; a Python
        # wrapper still alive then is what PySide hands out for the next object at that
        # address (a dock's toggle action once came back as a QOffscreenSurface).
        forget = getattr(self.plotter, "_forget_context", None)
        if forget is not None:
            forget()
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
        self.layers.show_scene(self.scene.robot_scene, truth, render=False)
        self.frame_truth()
        self.scene_panel.sync(self.scene)

    def _on_session_reset(self):
        self.layers.set_scene_length(self.scene.reference_size)
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
        if self._framed_nothing:  # a recording's first step: nothing was there to frame
            self.frame_truth(render=False)
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
        scene = self.scene
        self.loop_panel.show_snapshot(snapshot, scene.truth_size(snapshot))
        self.plots.set_unit_name(scene.unit_name)
        self.plots.set_stop_lines(scene.error_threshold(snapshot), scene.eps_length(snapshot))
        self.statusBar().show_snapshot(snapshot, scene)
        self.priors_panel.learn_button.setEnabled(snapshot is not None and not self.running
                                                  and scene.can_learn())

    # ------------------------------------------------------------------ controls
    def _on_prior_toggled(self, name, enabled):
        if not self.guarded(self.scene.set_prior_enabled, name, enabled):
            self.priors_panel.sync(self.scene)

    def _on_object_chosen(self, name):
        self.guarded(self.scene.set_truth_bundled, name)
        self.scene_panel.sync(self.scene)

    def reset_session(self):
        if self.idle("Reset"):
            self.scene.reset()

    def _on_learn(self):
        if self.idle("Add learned shape"):
            try:
                model = self.scene.add_learned_shape()
            except (TactileVizError, ValueError) as error:
                self.show_error(error)
                return
            self.statusBar().showMessage(f"added the prior {model.name!r}; a new session "
                                         "starts with it", STATUS_SECONDS)

    # ------------------------------------------------------------------ files
    # The scene calls of the file commands, dialogs and drops (see actions): each is a
    # method taking a path, True if it worked; an error box, and no change, if it did not.
    load_truth_file = commands.LOAD_TRUTH  # a mesh file as the ground truth
    add_prior_file = commands.ADD_PRIOR  # a mesh file as a new prior
    load_library = commands.LOAD_LIBRARY
    save_library = commands.SAVE_LIBRARY
    save_session = commands.SAVE_SESSION
    open_observations = commands.OPEN_OBSERVATIONS  # step through recorded touches
    export = commands.EXPORT  # the current estimate and touches to a folder
    save_screenshot = commands.save_screenshot  # a PNG of the whole window

    def load_session(self, path):
        """Replay a saved session in a worker, with a progress dialog that can cancel it."""
        if not self.idle("loading a session"):
            return False
        self.loader = loader = SessionLoad(path, self.scene, self)
        loader.said.connect(self.statusBar().showMessage)
        loader.failed.connect(lambda error: self.show_error(error))
        loader.finished.connect(lambda: self._on_load_finished(loader))
        self._show_running(False)
        self.statusBar().showMessage(f"loading {path}...")
        self.loader.start()
        return True

    def _on_load_finished(self, loader):
        loader.deleteLater()
        self.loader = None
        self._show_running(self.running)

    # Recording the drawn steps (see recording): the record action checked meanwhile.
    start_recording = recording.start_recording
    stop_recording = recording.stop_recording
    show_recording = recording.show_recording
