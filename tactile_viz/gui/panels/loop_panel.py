"""The Loop panel: Step, Run, Run to termination, Reset, the step reached and the history."""

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QSlider,
    QToolButton,
    QVBoxLayout,
)

from ..step_text import format_length, status_text  # noqa: F401 (format_length: tests)
from .base import MARGINS, blocked

START_TEXT = "Press Step or Run to start touching."


def wrapped_between_fields(text):
    """``text`` whose word wrap may break only between its `` | `` fields (no-break spaces
    inside them), so that a narrow panel never splits "recon error" from its value. The word
    joiner keeps a field ending in "-" (no value) from breaking there, before the "|"."""
    return "\u2060\u00a0| ".join(field.replace(" ", "\u00a0") for field in text.split(" | "))


LOOP_ACTIONS = ("step", "run", "finish", "reset")  # the ids of the panel's buttons' actions


def action_button(action):
    """A button that is a view of ``action`` (napari's style): its text, tooltip, enabled
    and checked state are the action's, and a click triggers the action."""
    button = QToolButton()
    button.setDefaultAction(action)
    button.setToolButtonStyle(Qt.ToolButtonTextOnly)
    button.setSizePolicy(QSizePolicy.Preferred, QSizePolicy.Fixed)
    if action.isCheckable():
        # The button follows the action; this makes setChecked on the button (as on a
        # QPushButton) reach the action too. No echo: setChecked to the same state is silent.
        button.toggled.connect(action.setChecked)
    return button


class LoopPanel(QGroupBox):
    """The buttons that step the session, the step shown and a slider over the steps taken.

    Parameters
    ----------
    actions : dict of str to QAction
        The window's actions ``step``, ``run``, ``finish`` and ``reset``
        (:data:`tactile_viz.gui.actions.ACTIONS`): the buttons ``step_button``,
        ``run_button``, ``finish_button`` and ``reset_button`` are views of them, so their
        text, tooltip, enabled and checked state are the actions' and a click triggers one.

    Signals
    -------
    scrubbed(int)
        The slider asks for step ``n`` of the session (1 is the first).
    """

    scrubbed = Signal(int)

    def __init__(self, actions, parent=None):
        super().__init__("Loop", parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(*MARGINS)
        row = QHBoxLayout()
        for name in LOOP_ACTIONS:
            button = action_button(actions[name])
            setattr(self, f"{name}_button", button)
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
        self.history_slider.valueChanged.connect(self.scrubbed)
        history = QHBoxLayout()
        history.addWidget(self.step_label)
        history.addWidget(self.history_slider, 1)
        layout.addLayout(history)
        layout.addWidget(self.status_label)

    def buttons(self):
        """``{action id: button}`` of the panel's buttons."""
        return {name: getattr(self, f"{name}_button") for name in LOOP_ACTIONS}

    def controls(self):
        """None: the buttons are enabled as their actions are (which the window manages with
        its scene-changing actions), and the slider by :meth:`set_running`."""
        return []

    def sync(self, scene):
        """Show the scene's latest step and its history, without emitting."""
        latest = scene.latest
        self.show_snapshot(latest, None if latest is None else scene.truth_size(latest))
        self.set_history(len(scene.snapshots))

    def show_snapshot(self, snapshot, size=None):
        """Show a step (None: a new session) in the labels; ``size``: see :func:`status_text`."""
        if snapshot is None:
            self.step_label.setText("step 0")
            self.status_label.setText(START_TEXT)
            return
        self.step_label.setText(f"step {snapshot.step}"
                                + (" (terminated)" if snapshot.terminated else ""))
        self.status_label.setText(wrapped_between_fields(status_text(snapshot, size)))

    def set_history(self, steps):
        """Let the slider cover ``steps`` steps (0: none) and point at the last."""
        with blocked(self.history_slider):
            if steps:
                self.history_slider.setRange(1, steps)
                self.history_slider.setValue(steps)
            else:
                self.history_slider.setRange(0, 0)

    def set_running(self, running, loading=False):
        """The slider is off while steps run or a session loads (the buttons follow their
        actions: the window's Run reads Pause while steps run)."""
        self.history_slider.setEnabled(not running and not loading)
