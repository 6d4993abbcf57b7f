"""The Layers panel: one check box per viewport layer."""

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QGridLayout, QGroupBox

from ..layers import LAYERS
from .base import MARGINS, blocked

# Label colours readable on a light panel, where a layer's own colour is too light.
SHOWN_COLORS = {"truth": "steelblue", "table": "saddlebrown", "gpis": "teal",
                "target": "darkgoldenrod", "tip": "chocolate"}


class LayersPanel(QGroupBox):
    """Which viewport layers are shown.

    Signals
    -------
    layer_toggled(str, bool)
        A layer's name and whether it is now shown.
    """

    layer_toggled = Signal(str, bool)

    def __init__(self, parent=None):
        super().__init__("Layers", parent)
        layout = QGridLayout(self)  # two columns: the Controls dock fits a 720-pixel screen
        layout.setContentsMargins(*MARGINS)
        layout.setSpacing(0)
        self.layer_boxes = {}
        rows = (len(LAYERS) + 1) // 2
        for index, (name, (label, color)) in enumerate(LAYERS.items()):
            box = QCheckBox(label)
            box.setStyleSheet(f"QCheckBox {{ color: {SHOWN_COLORS.get(name, color)}; }}")
            box.toggled.connect(lambda checked, n=name: self.layer_toggled.emit(n, checked))
            layout.addWidget(box, index % rows, index // rows)
            self.layer_boxes[name] = box

    def sync(self, visible):
        """Check the boxes as ``visible`` (layer name -> bool) has them, without emitting.

        Parameters
        ----------
        visible : mapping of str to bool
            E.g. :attr:`tactile_viz.gui.layers.ViewportLayers.visible`.
        """
        with blocked(*self.layer_boxes.values()):
            for name, box in self.layer_boxes.items():
                box.setChecked(bool(visible[name]))
