"""The window's status bar: messages, and the gauges of the step reached (steps taken of the
cap, the DHD against eps)."""

from PySide6.QtWidgets import QLabel, QProgressBar, QStatusBar

from .panels import status_text
from .panels.loop_panel import format_length

STATUS_SECONDS = 8000  # how long a status-bar message stays, ms


class StatusBar(QStatusBar):
    """A QStatusBar with the step gauges: ``progress`` (step of the cap) and ``dhd_label``."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setFormat("step %v of %m")
        self.progress.setToolTip("Steps taken of the step cap (known or novel)")
        self.dhd_label = QLabel()
        self.dhd_label.setToolTip("Termination: the run stops when the DHD falls below eps. "
                                  "Both in scene units: eps (set in size units) times a "
                                  "sixth of the estimated object's longest side")
        self.addPermanentWidget(self.dhd_label)
        self.addPermanentWidget(self.progress)

    def show_snapshot(self, snapshot, scene):
        """The step's line and gauges (None: a new session). Lengths in scene units: the
        errors against the truth's size, the DHD against eps scaled by the MAP object's (the
        priors' before a step), as the session does."""
        size, eps = scene.truth_size(snapshot), scene.eps_length(snapshot)
        if snapshot is None:
            self.showMessage("new session: press Step or Run to start touching",
                             STATUS_SECONDS)
            self._set_progress(0, scene.params.max_steps_known)
            self.dhd_label.setText(f"DHD - / eps {format_length(eps, size)}")
            return
        self.showMessage(status_text(snapshot, size))
        params = scene.session_params
        cap = params.max_steps_novel if snapshot.novel else params.max_steps_known
        self._set_progress(snapshot.step, max(cap, snapshot.step))
        self.dhd_label.setText(f"DHD {format_length(snapshot.dhd, size)} / "
                               f"eps {format_length(eps, size)}")

    def _set_progress(self, value, maximum):
        """Without QProgressBar's synchronous repaint, which repaints the whole window (the
        viewport too) inside ``setValue``: the bar is painted in the next pass instead."""
        self.progress.setUpdatesEnabled(False)
        self.progress.setRange(0, maximum)
        self.progress.setValue(value)
        self.progress.setUpdatesEnabled(True)
        self.progress.update()
