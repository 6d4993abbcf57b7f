"""The Exploration panel: strategy, preset and the main parameters of a session.

A length parameter is in size units (a sixth of an object's longest side, see
:mod:`tactile_viz.engine.params`): its label and tooltip say so, from the parameters' field
metadata (:func:`tactile_viz.app.scene.knob_length_power`).
"""

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QComboBox, QDoubleSpinBox, QGridLayout, QGroupBox, QLabel, QSpinBox

from ...app.scene import KNOBS, LOADED_PRESET, knob_length_power, knob_size_reference
from ...engine.explore.exploration import STRATEGIES
from ...engine.params import declaration
from ...engine.presets import SESSION_PRESETS
from .base import MARGINS, blocked

# The main knobs: name -> Knob(label, step, decimals), the scene's one list of them. Their
# range, default and doc come from the parameters' declarations; a length's unit is added.
PARAMETERS = KNOBS


class ExplorationPanel(QGroupBox):
    """Strategy, preset and one spin box per main parameter.

    Signals
    -------
    strategy_chosen(str)
    preset_chosen(str)
    parameter_changed(str, object)
        A parameter's name and its new value (an int for ``n_s``, else a float).
    """

    strategy_chosen = Signal(str)
    preset_chosen = Signal(str)
    parameter_changed = Signal(str, object)

    def __init__(self, parent=None):
        super().__init__("Exploration", parent)
        grid = QGridLayout(self)  # label, box, label, box: fits a 720-pixel screen
        grid.setContentsMargins(*MARGINS)
        grid.setVerticalSpacing(2)
        self.strategy_box = QComboBox()
        self.strategy_box.addItems(list(STRATEGIES))
        self.strategy_box.setToolTip("gpis-dhd: aim where the estimate is least covered "
                                     "(paper); rrt: random tangent steps (baseline)")
        self.strategy_box.activated.connect(
            lambda index: self.strategy_chosen.emit(self.strategy_box.itemText(index)))
        self.preset_box = QComboBox()
        self.preset_box.setToolTip("recommended: the project's configuration (the default); "
                                   "paper: the paper exactly; fast: coarser grids, fewer "
                                   "features; refined: recommended plus MAP pose refinement; "
                                   "accurate: finer grids, neighbour bins, refinement")
        # Wide enough for every preset's name from the start (the box is filled by sync,
        # after the dock has taken its width: "recommended" showed as "recommer").
        self.preset_box.addItems([*SESSION_PRESETS, LOADED_PRESET])
        self.preset_box.setMinimumWidth(self.preset_box.sizeHint().width())
        self.preset_box.removeItem(len(SESSION_PRESETS))
        self.preset_box.activated.connect(
            lambda index: self.preset_chosen.emit(self.preset_box.itemText(index)))
        rows = [("strategy", self.strategy_box), ("preset", self.preset_box)]
        self.parameter_boxes = {}
        for name, knob in PARAMETERS.items():
            known = declaration(name)
            box = _parameter_box(known.low, known.high, knob.step, knob.decimals,
                                 parameter_tooltip(name))
            box.valueChanged.connect(
                lambda value, n=name: self.parameter_changed.emit(n, value))
            rows.append((parameter_label(name), box))
            self.parameter_boxes[name] = box
        for index, (label, box) in enumerate(rows):
            row, column = divmod(index, 2)
            grid.addWidget(QLabel(label), row, 2 * column)
            grid.addWidget(box, row, 2 * column + 1)
        grid.setColumnStretch(1, 1)
        grid.setColumnStretch(3, 1)

    def controls(self):
        """The widgets that change the scene."""
        return [self.strategy_box, self.preset_box, *self.parameter_boxes.values()]

    def sync(self, scene):
        """Show the scene's strategy, presets and parameters, without emitting."""
        with blocked(self.strategy_box, self.preset_box, *self.parameter_boxes.values()):
            self.strategy_box.setCurrentText(scene.strategy)
            names = scene.preset_names()
            if [self.preset_box.itemText(i) for i in range(self.preset_box.count())] != names:
                self.preset_box.clear()
                self.preset_box.addItems(names)
            self.preset_box.setCurrentText(scene.preset)
            for name, box in self.parameter_boxes.items():
                box.setValue(scene.parameter(name))


def unit_text(power):
    """The unit of a length of power ``power`` in size units ("" for 0: not a length)."""
    if power == 0:
        return ""
    if power == 1:
        return "size units"
    if power > 0:
        return f"size units^{power}"
    return "1/size unit" if power == -1 else f"1/size units^{-power}"


def parameter_label(name):
    """The label of a parameter's spin box: its name, and its unit when it is a length."""
    unit = unit_text(knob_length_power(name))
    return PARAMETERS[name].label + (f" [{unit}]" if unit else "")


def parameter_tooltip(name):
    """A parameter's tooltip, with what its unit is when it is a length."""
    tip, power = declaration(name).doc.replace("``", ""), knob_length_power(name)
    if power == 0:
        return tip
    return (f"{tip}\n\nIn {unit_text(power)}: one size unit is a sixth of "
            f"{knob_size_reference(name)} (0.6 = 10% of its size; on the paper's objects, "
            "6 long, one scene unit).")


def _parameter_box(low, high, step, decimals, tip):
    box = QSpinBox() if decimals == 0 else QDoubleSpinBox()
    if decimals:
        box.setDecimals(decimals)
    box.setRange(low, high)
    box.setSingleStep(step)
    box.setToolTip(tip)
    box.setKeyboardTracking(False)
    return box
