"""The main window: a pyvista viewport, a control panel and plots, on a :class:`Scene`.

The window owns no inference state: it calls the scene's methods and redraws when the
scene's signals fire. Steps run in a worker thread (superqt ``thread_worker``) that yields
one immutable snapshot per step; VTK is touched only on the GUI thread.
"""

import numpy as np
from pyvistaqt import QtInteractor
from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDockWidget, QDoubleSpinBox,
                               QFileDialog, QFormLayout, QGroupBox, QHBoxLayout, QLabel,
                               QListWidget, QListWidgetItem, QMainWindow, QMessageBox,
                               QPushButton, QScrollArea, QSpinBox, QVBoxLayout, QWidget)
from superqt.utils import thread_worker

from ..engine.errors import TactileVizError
from ..engine.session import SESSION_PRESETS
from .layers import LAYERS, ViewportLayers
from .plots import PlotsWidget

OPEN_FILE = "Open mesh file..."
MESH_FILTER = "Meshes (*.obj *.ply *.stl *.off *.glb *.gltf);;All files (*)"

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


@thread_worker
def run_steps(session, count):
    """Step a session ``count`` times (None: until it terminates), yielding snapshots."""
    done = 0
    while not session.terminated and (count is None or done < count):
        snapshot = session.step()
        done += 1
        yield snapshot


class MainWindow(QMainWindow):
    """The tactile_viz desktop window.

    Parameters
    ----------
    scene : tactile_viz.app.scene.Scene
    """

    def __init__(self, scene, parent=None):
        super().__init__(parent)
        self.scene = scene
        self.worker = None
        self.setWindowTitle("tactile_viz")
        self.resize(1500, 900)
        self.plotter = QtInteractor(self)
        self.plotter.set_background("white")
        self.setCentralWidget(self.plotter)
        self.layers = ViewportLayers(self.plotter)
        self._build_panel()
        self._build_plots()
        self._build_menu()
        scene.truth_changed.connect(self._on_truth_changed)
        scene.library_changed.connect(lambda library: self._fill_priors())
        scene.session_reset.connect(self._on_session_reset)
        scene.stepped.connect(self._on_stepped)
        self.layers.show_truth(scene.truth)
        self.plotter.view_isometric()
        self.frame_truth()
        self._update_status(None)

    def frame_truth(self):
        """Point the camera at the ground truth (on a new object or pose, never per step)."""
        bounds = self.layers.actors["truth"].GetBounds()
        self.plotter.reset_camera(bounds=bounds)
        self.plotter.render()

    # ------------------------------------------------------------------ building
    def _build_panel(self):
        panel = QWidget()
        layout = QVBoxLayout(panel)
        layout.addWidget(self._scene_group())
        layout.addWidget(self._priors_group())
        layout.addWidget(self._exploration_group())
        layout.addWidget(self._loop_group())
        layout.addWidget(self._layers_group())
        layout.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(panel)
        scroll.setWidgetResizable(True)
        dock = QDockWidget("Controls", self)
        dock.setObjectName("controls")
        dock.setWidget(scroll)
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable)
        self.addDockWidget(Qt.LeftDockWidgetArea, dock)

    def _scene_group(self):
        group = QGroupBox("Scene")
        form = QFormLayout(group)
        self.object_box = QComboBox()
        self.object_box.addItems(self.scene.bundled_objects() + [OPEN_FILE])
        self.object_box.setCurrentText(self.scene.truth_model.name)
        self.object_box.setToolTip("The ground-truth object the sensor touches")
        self.object_box.activated.connect(self._on_object_chosen)
        self.seed_box = QSpinBox()
        self.seed_box.setRange(0, 1_000_000)
        self.seed_box.setValue(self.scene.seed)
        self.seed_box.setToolTip("Seed of the random pose and of the session")
        random_button = QPushButton("Random pose")
        random_button.clicked.connect(self._on_random_pose)
        apply_button = QPushButton("Place at seed")
        apply_button.clicked.connect(lambda: self._guarded(
            self.scene.randomize_pose, self.seed_box.value()))
        buttons = QHBoxLayout()
        buttons.addWidget(random_button)
        buttons.addWidget(apply_button)
        form.addRow("object", self.object_box)
        form.addRow("seed", self.seed_box)
        form.addRow(buttons)
        return group

    def _priors_group(self):
        group = QGroupBox("Priors")
        layout = QVBoxLayout(group)
        self.prior_list = QListWidget()
        self.prior_list.setToolTip("Checked priors are the classes the filter considers")
        self.prior_list.itemChanged.connect(self._on_prior_toggled)
        layout.addWidget(self.prior_list)
        row = QHBoxLayout()
        for label, slot in (("Load mesh...", self._on_load_prior_mesh),
                            ("Load library...", self._on_load_library),
                            ("Save library...", self._on_save_library)):
            button = QPushButton(label)
            button.clicked.connect(slot)
            row.addWidget(button)
        layout.addLayout(row)
        self.learn_button = QPushButton("Add learned shape")
        self.learn_button.setToolTip("Add the reconstructed novel shape to the priors")
        self.learn_button.clicked.connect(lambda: self._guarded(self.scene.add_learned_shape))
        layout.addWidget(self.learn_button)
        self._fill_priors()
        return group

    def _exploration_group(self):
        group = QGroupBox("Exploration")
        form = QFormLayout(group)
        self.strategy_box = QComboBox()
        self.strategy_box.addItems(["gpis-dhd", "rrt"])
        self.strategy_box.setToolTip("gpis-dhd: aim where the estimate is least covered "
                                     "(paper); rrt: random tangent steps (baseline)")
        self.strategy_box.currentTextChanged.connect(
            lambda text: self._guarded(self.scene.set_strategy, text))
        self.preset_box = QComboBox()
        self.preset_box.addItems(list(SESSION_PRESETS))
        self.preset_box.setCurrentText(self.scene.preset)
        self.preset_box.setToolTip("fast: coarser grids, fewer features; paper: the paper's "
                                   "values; refined: the paper's values plus MAP pose refinement; "
                                   "accurate: finer grids, neighbour bins, refinement")
        self.preset_box.currentTextChanged.connect(self._on_preset)
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
        self._show_parameters()
        return group

    def _loop_group(self):
        group = QGroupBox("Loop")
        layout = QVBoxLayout(group)
        row = QHBoxLayout()
        self.step_button = QPushButton("Step")
        self.step_button.clicked.connect(lambda: self.start(1))
        self.run_button = QPushButton("Run")
        self.run_button.setCheckable(True)
        self.run_button.setToolTip("Run continuously; press again to pause")
        self.run_button.toggled.connect(self._on_run_toggled)
        self.finish_button = QPushButton("Run to termination")
        self.finish_button.clicked.connect(lambda: self.start(None))
        self.reset_button = QPushButton("Reset")
        self.reset_button.clicked.connect(self._on_reset)
        for button in (self.step_button, self.run_button, self.finish_button, self.reset_button):
            row.addWidget(button)
        layout.addLayout(row)
        self.step_label = QLabel("step 0")
        self.status_label = QLabel()
        self.status_label.setWordWrap(True)
        layout.addWidget(self.step_label)
        layout.addWidget(self.status_label)
        return group

    def _layers_group(self):
        group = QGroupBox("Layers")
        layout = QVBoxLayout(group)
        self.layer_boxes = {}
        for name, (label, color) in LAYERS.items():
            box = QCheckBox(label)
            box.setChecked(True)
            box.setStyleSheet(f"QCheckBox {{ color: {color if name != 'truth' else 'steelblue'}; }}")
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

    def _build_menu(self):
        file_menu = self.menuBar().addMenu("&File")
        actions = [
            ("Open ground-truth mesh...", self._open_truth_file, QKeySequence.StandardKey.Open),
            ("Load prior library...", self._on_load_library, None),
            ("Save prior library...", self._on_save_library, None),
            ("Load session...", self._on_load_session, None),
            ("Save session...", self._on_save_session, QKeySequence.StandardKey.Save),
            ("Save screenshot...", self._on_save_screenshot, None),
            ("Quit", self.close, QKeySequence.StandardKey.Quit),
        ]
        for label, slot, shortcut in actions:
            action = QAction(label, self)
            if shortcut is not None:
                action.setShortcut(shortcut)
            action.triggered.connect(slot)
            file_menu.addAction(action)

    # ------------------------------------------------------------------ running
    @property
    def running(self):
        return self.worker is not None

    def start(self, count):
        """Run ``count`` steps (None: to termination) in the worker thread."""
        if self.running:
            return
        try:
            session = self.scene.ensure_session()
        except TactileVizError as error:
            self.show_error(error)
            self.run_button.setChecked(False)
            return
        if session.terminated:
            self.statusBar().showMessage("the session has terminated: Reset to start again", 5000)
            self.run_button.setChecked(False)
            return
        worker = run_steps(session, count)
        worker.yielded.connect(self._on_yielded)
        worker.errored.connect(self.show_error)
        worker.finished.connect(self._on_worker_finished)
        self.worker = worker
        self._set_controls_enabled(False)
        worker.start()

    def _on_yielded(self, snapshot):
        self.scene.announce(snapshot)

    def pause(self):
        """Stop after the step in progress."""
        if self.worker is not None:
            self.worker.quit()

    def wait_for_worker(self, milliseconds=60_000):
        """Block until the worker is done (used when closing)."""
        if self.worker is not None:
            self.worker.quit()
            self.worker.await_workers(milliseconds)
            self.worker = None  # its queued finished signal may never be delivered now

    def _on_worker_finished(self):
        self.worker = None
        self._set_controls_enabled(True)
        self.run_button.blockSignals(True)
        self.run_button.setChecked(False)
        self.run_button.blockSignals(False)

    def _on_run_toggled(self, checked):
        if checked:
            self.start(None)
        else:
            self.pause()

    def _set_controls_enabled(self, enabled):
        for widget in (self.step_button, self.finish_button, self.reset_button,
                       self.object_box, self.prior_list, self.strategy_box, self.preset_box,
                       self.learn_button, *self.parameter_boxes.values()):
            widget.setEnabled(enabled)
        if enabled:
            self.learn_button.setEnabled(self.scene.can_learn())

    def closeEvent(self, event):
        self.wait_for_worker()
        self.plots.close()
        self.plotter.close()
        super().closeEvent(event)

    # ------------------------------------------------------------------ scene events
    def _on_truth_changed(self, truth):
        self.layers.show_truth(truth)
        self.frame_truth()
        self.object_box.setCurrentText(truth.model.name if self.object_box.findText(
            truth.model.name) >= 0 else self.object_box.currentText())
        self.seed_box.setValue(self.scene.seed)

    def _on_session_reset(self):
        self.layers.clear_session()
        self.plots.update_plots([])
        self._update_status(None)

    def _on_stepped(self, snapshot):
        self.layers.show_snapshot(snapshot)
        self.plots.update_plots(self.scene.snapshots)
        self._update_status(snapshot)

    def _update_status(self, snapshot):
        if snapshot is None:
            self.step_label.setText("step 0")
            self.status_label.setText("Press Step or Run to start touching.")
            self.learn_button.setEnabled(False)
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
        self.learn_button.setEnabled(not self.running and self.scene.can_learn())

    # ------------------------------------------------------------------ controls
    def _fill_priors(self):
        self.prior_list.blockSignals(True)
        self.prior_list.clear()
        for name in self.scene.library.names:
            item = QListWidgetItem(name)
            item.setFlags(item.flags() | Qt.ItemIsUserCheckable)
            item.setCheckState(Qt.Checked if self.scene.enabled[name] else Qt.Unchecked)
            self.prior_list.addItem(item)
        self.prior_list.blockSignals(False)

    def _on_prior_toggled(self, item):
        self._guarded(self.scene.set_prior_enabled, item.text(),
                      item.checkState() == Qt.Checked)

    def _on_object_chosen(self, index):
        text = self.object_box.itemText(index)
        if text == OPEN_FILE:
            self._open_truth_file()
        else:
            self._guarded(self.scene.set_truth_bundled, text)

    def _open_truth_file(self):
        path, _ = QFileDialog.getOpenFileName(self, "Open ground-truth mesh", "", MESH_FILTER)
        if path:
            self.load_truth_file(path)
        self.object_box.setCurrentText(self.scene.truth_model.name)

    def load_truth_file(self, path):
        """Use a mesh file as the ground truth (an error box, and no change, if it is bad)."""
        self._guarded(self.scene.set_truth_file, path)

    def _on_random_pose(self):
        seed = int(np.random.default_rng().integers(1_000_000))
        self.seed_box.setValue(seed)
        self._guarded(self.scene.randomize_pose, seed)

    def _on_preset(self, name):
        if self._guarded(self.scene.set_preset, name):
            self._show_parameters()

    def _show_parameters(self):
        for name, box in self.parameter_boxes.items():
            box.blockSignals(True)
            box.setValue(self.scene.parameter(name))
            box.blockSignals(False)

    def _on_reset(self):
        self.scene.reset()

    def _on_load_prior_mesh(self):
        path, _ = QFileDialog.getOpenFileName(self, "Load a mesh as a prior", "", MESH_FILTER)
        if path:
            self._guarded(self.scene.add_prior_file, path)

    def _on_load_library(self):
        folder = QFileDialog.getExistingDirectory(self, "Load a prior library folder")
        if folder:
            self._guarded(self.scene.load_library, folder)

    def _on_save_library(self):
        folder = QFileDialog.getExistingDirectory(self, "Save the prior library to a folder")
        if folder:
            self._guarded(self.scene.save_library, folder)

    def _on_save_session(self):
        path, _ = QFileDialog.getSaveFileName(self, "Save session", "session.npz",
                                              "Sessions (*.npz)")
        if path:
            self._guarded(self.scene.save_session, path)

    def _on_load_session(self):
        path, _ = QFileDialog.getOpenFileName(self, "Load session", "", "Sessions (*.npz)")
        if path:
            self._guarded(self.scene.load_session, path)

    def _on_save_screenshot(self):
        path, _ = QFileDialog.getSaveFileName(self, "Save screenshot", "tactile_viz.png",
                                              "PNG images (*.png)")
        if path:
            self.plotter.screenshot(path)

    def _guarded(self, function, *args):
        """Call a scene method; show the project's errors in a message box. True if it worked."""
        try:
            function(*args)
        except (TactileVizError, ValueError, OSError) as error:
            self.show_error(error)
            self._show_parameters()
            return False
        return True

    def show_error(self, error):
        QMessageBox.critical(self, "tactile_viz", str(error))
