"""The Scene panel: which object is the ground truth and the seed of its pose."""

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QComboBox, QFormLayout, QGroupBox, QHBoxLayout, QPushButton, QSpinBox

from .base import MARGINS, blocked

OPEN_FILE = "Open mesh file..."
NO_OBJECT = "(recording)"  # shown, greyed, while recorded touches replace the object


class ScenePanel(QGroupBox):
    """Object and seed of the ground truth.

    Parameters
    ----------
    objects : list of str
        The bundled objects offered (an entry to open a mesh file follows them).

    Signals
    -------
    object_chosen(str)
        A bundled object was picked.
    open_file_requested()
        The user asked for a mesh file as the ground truth.
    pose_requested(int)
        Place the truth at the pose of this seed (Random pose draws the seed).
    """

    object_chosen = Signal(str)
    open_file_requested = Signal()
    pose_requested = Signal(int)

    def __init__(self, objects, parent=None):
        super().__init__("Scene", parent)
        form = QFormLayout(self)
        form.setContentsMargins(*MARGINS)
        self.object_box = QComboBox()
        self.object_box.addItems(list(objects) + [OPEN_FILE])
        self.object_box.setToolTip("The ground-truth object the sensor touches")
        self.object_box.setPlaceholderText(NO_OBJECT)
        self.object_box.activated.connect(self._on_object_activated)
        self.seed_box = QSpinBox()
        self.seed_box.setRange(0, 1_000_000)
        self.seed_box.setToolTip("Seed of the random pose and of the session: Place at seed "
                                 "applies it")
        self.random_button = QPushButton("Random pose")
        self.random_button.clicked.connect(self._on_random)
        self.place_button = QPushButton("Place at seed")
        self.place_button.clicked.connect(lambda: self.pose_requested.emit(self.seed_box.value()))
        seed_row = QHBoxLayout()
        seed_row.addWidget(self.seed_box, 1)
        seed_row.addWidget(self.random_button)
        seed_row.addWidget(self.place_button)
        form.addRow("object", self.object_box)
        form.addRow("seed", seed_row)

    def controls(self):
        """The widgets that change the scene."""
        return [self.object_box, self.seed_box, self.random_button, self.place_button]

    def sync(self, scene):
        """Show the scene's truth object and seed, without emitting any signal; no object
        (:data:`NO_OBJECT`) while a recording replaces the truth."""
        with blocked(self.object_box, self.seed_box):
            if scene.truth is None:
                self.object_box.setCurrentIndex(-1)  # the placeholder text
            else:
                name = scene.truth_model.name
                if self.object_box.findText(name) < 0:
                    self.object_box.insertItem(self.object_box.count() - 1, name)
                self.object_box.setCurrentText(name)
            self.seed_box.setValue(scene.seed)

    def _on_object_activated(self, index):
        text = self.object_box.itemText(index)
        if text == OPEN_FILE:
            self.open_file_requested.emit()
        else:
            self.object_chosen.emit(text)

    def _on_random(self):
        self.pose_requested.emit(int(np.random.default_rng().integers(1_000_000)))
