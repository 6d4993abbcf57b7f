"""The Priors panel: which prior classes the filter considers, and the library's files."""

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QGroupBox,
    QHBoxLayout,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
)

from .base import MARGINS, blocked

PRIORS_MIN_HEIGHT = 70  # pixels: four rows


class PriorsPanel(QGroupBox):
    """The prior list (checked: used by the filter) and its buttons.

    Signals
    -------
    prior_toggled(str, bool)
        A prior was checked (True) or unchecked.
    load_mesh_requested(), load_library_requested(), save_library_requested()
        The buttons under the list.
    learn_requested()
        Add the reconstructed novel shape to the priors.
    """

    prior_toggled = Signal(str, bool)
    load_mesh_requested = Signal()
    load_library_requested = Signal()
    save_library_requested = Signal()
    learn_requested = Signal()

    def __init__(self, parent=None):
        super().__init__("Priors", parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(*MARGINS)
        self.prior_list = QListWidget()
        self.prior_list.setToolTip("Checked priors are the classes the filter considers")
        # The list takes the dock's spare height (it scrolls itself below that).
        self.prior_list.setMinimumHeight(PRIORS_MIN_HEIGHT)
        self.prior_list.setSizePolicy(QSizePolicy.Preferred, QSizePolicy.Ignored)
        self.prior_list.itemChanged.connect(
            lambda item: self.prior_toggled.emit(item.text(), item.checkState() == Qt.Checked))
        layout.addWidget(self.prior_list)
        row = QHBoxLayout()
        self.prior_buttons = []
        for label, signal in (("Load mesh...", self.load_mesh_requested),
                              ("Load library...", self.load_library_requested),
                              ("Save library...", self.save_library_requested)):
            button = QPushButton(label)
            button.clicked.connect(signal)
            row.addWidget(button)
            self.prior_buttons.append(button)
        layout.addLayout(row)
        self.learn_button = QPushButton("Add learned shape")
        self.learn_button.setToolTip("Add the reconstructed novel shape to the priors")
        self.learn_button.clicked.connect(self.learn_requested)
        layout.addWidget(self.learn_button)

    def controls(self):
        """The widgets that change the scene."""
        return [self.prior_list, *self.prior_buttons, self.learn_button]

    def sync(self, scene):
        """List the scene's priors, checked as the scene has them, without emitting."""
        with blocked(self.prior_list):
            self.prior_list.clear()
            for name in scene.library.names:
                item = QListWidgetItem(name)
                item.setFlags(item.flags() | Qt.ItemIsUserCheckable)
                item.setCheckState(Qt.Checked if scene.enabled[name] else Qt.Unchecked)
                self.prior_list.addItem(item)
