"""The window's status bar: messages, the step's short summary, the sensor noise and the
preset, and the gauges of the step reached (the last step's time, the DHD against eps, steps
taken of the cap).

Each piece has a label of its own, sized to its text, so none is cut by another; only the
summary (left, where messages show too) gives way, elided with the whole text in its
tooltip. The Loop panel's status line has every field (:mod:`tactile_viz.gui.step_text`).
"""

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QProgressBar, QSizePolicy, QStatusBar

from .step_text import format_length, noise_text, preset_text, summary_text

STATUS_SECONDS = 8000  # how long a status-bar message stays, ms
NOISE_TIP = ("Sensor noise, which the simulated sensor adds and the model assumes: the "
             "contacts' position standard deviation (scene units) and their normals' "
             "(degrees); outliers: the simulated sensor's share of wrong contacts "
             "(--position-noise, --normal-noise, --outliers)")
PRESET_TIP = ("The session's parameter preset (Exploration panel); \"(changed)\": some of "
              "its parameters were set by hand")


class ElidedLabel(QLabel):
    """A label that takes the room left and elides its text to it ("..." at the end), the
    whole text in its tooltip; :attr:`full_text` is the text set."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.full_text = ""
        self.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)
        self.setMinimumWidth(0)

    def set_full_text(self, text):
        """Show ``text``, elided to the label's width."""
        self.full_text = text
        self.setToolTip(text)
        self._elide()

    def resizeEvent(self, event):
        super().resizeEvent(event)
        self._elide()

    def _elide(self):
        width = self.contentsRect().width()
        self.setText(self.fontMetrics().elidedText(self.full_text, Qt.ElideRight, width))


def _label(tip):
    label = QLabel()
    label.setToolTip(tip)
    return label


class StatusBar(QStatusBar):
    """A QStatusBar with the step's summary (``summary_label``), the sensor noise
    (``noise_label``), the preset (``preset_label``), the last step's time
    (``time_label``), the DHD against eps (``dhd_label``) and the step of the cap
    (``progress``)."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.summary_label = ElidedLabel()
        self.addWidget(self.summary_label, 1)  # hidden while a message shows
        self.noise_label = _label(NOISE_TIP)
        self.preset_label = _label(PRESET_TIP)
        self.time_label = _label("Wall time of the last step")
        self.dhd_label = _label("Termination: the run stops when the DHD falls below eps. "
                                "Both in scene units: eps (set in size units) times a "
                                "sixth of the estimated object's longest side")
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(160)
        self.progress.setFormat("step %v of %m")
        self.progress.setToolTip("Steps taken of the step cap (known or novel)")
        for widget in self.labels()[1:] + [self.progress]:
            self.addPermanentWidget(widget)

    def labels(self):
        """The status bar's labels, left to right."""
        return [self.summary_label, self.noise_label, self.preset_label, self.time_label,
                self.dhd_label]

    def show_snapshot(self, snapshot, scene):
        """The step's summary and gauges (None: a new session), and the scene's noise and
        preset. Lengths in scene units: the errors against the truth's size, the DHD
        against eps scaled by the MAP object's (the priors' before a step), as the session
        does."""
        size, eps = scene.truth_size(snapshot), scene.eps_length(snapshot)
        self._show_settings(scene, size)
        eps_text = f"eps {format_length(eps, size)}"
        if snapshot is None:
            self.showMessage("new session: press Step or Run to start touching",
                             STATUS_SECONDS)
            self.summary_label.set_full_text("")
            self.time_label.setText("last step -")
            self._set_progress(0, scene.params.max_steps_known)
            self.dhd_label.setText(f"DHD - / {eps_text}")
            return
        self.clearMessage()  # the step is newer than any message
        self.summary_label.set_full_text(summary_text(snapshot, size))
        self.time_label.setText(f"last step {sum(snapshot.timings.values()):.2f} s")
        params = scene.session_params
        cap = params.max_steps_novel if snapshot.novel else params.max_steps_known
        self._set_progress(snapshot.step, max(cap, snapshot.step))
        self.dhd_label.setText(f"DHD {format_length(snapshot.dhd, size)} / {eps_text}")

    def _show_settings(self, scene, size):
        """The noise and preset of the session (the scene's before one is made)."""
        session = scene.session
        noise = getattr(session, "sensor_noise", scene.sensor_noise)
        outliers = getattr(session, "sensor_outliers", scene.sensor_outliers)
        self.noise_label.setText(noise_text(noise, outliers, scene.unit_name, size))
        self.preset_label.setText(preset_text(scene.preset, bool(scene.overrides)))

    def _set_progress(self, value, maximum):
        """Without QProgressBar's synchronous repaint, which repaints the whole window (the
        viewport too) inside ``setValue``: the bar is painted in the next pass instead."""
        self.progress.setUpdatesEnabled(False)
        self.progress.setRange(0, maximum)
        self.progress.setValue(value)
        self.progress.setUpdatesEnabled(True)
        self.progress.update()
