"""Loading a saved session: the replay runs in a worker thread, behind a progress dialog
that can cancel it. The worker touches neither Qt widgets nor VTK; the loaded session is
adopted by the scene on the GUI thread."""

import json
import threading
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import QProgressDialog
from superqt.utils import thread_worker

from ..engine.session import Session
from .status_bar import STATUS_SECONDS


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


@thread_worker(start_thread=False, ignore_errors=True)
def load_session_worker(path, cancel, progress):
    """Load (replay) a saved session in a worker; ``progress(done, total)`` after each
    step, :class:`LoadCancelled` once ``cancel`` is set. Errors (a cancel included) go to
    the worker's ``errored`` signal only, never re-raised in the GUI thread."""
    total = saved_step_count(path)
    progress(0, total or 0)

    def replayed(snapshot):
        if cancel.is_set():
            raise LoadCancelled()
        progress(snapshot.step, total or 0)

    return Session.load(path, callback=replayed)


class _Progress(QObject):
    """Emits ``changed(done, total)`` on the GUI thread when called from any thread."""

    changed = Signal(int, int)

    def __call__(self, done, total):
        self.changed.emit(int(done), int(total))


class SessionLoad(QObject):
    """One saved session being replayed in a worker, with a modal progress dialog whose
    Cancel stops the replay at the next step. The loaded session is adopted by ``scene`` on
    the GUI thread.

    Signals
    -------
    said(str, int)
        A status-bar message and how long it stays, ms: the session was loaded (and whether
        it replaced the priors), or the user cancelled.
    failed(object)
        The error of a replay that failed (not cancelled).
    finished()
        The worker is done, either way; the dialog is closed and deleted (``dialog`` is None).
    """

    said = Signal(str, int)
    failed = Signal(object)
    finished = Signal()

    def __init__(self, path, scene, parent):
        super().__init__(parent)
        self.path, self.scene = str(path), scene
        self.abandoned = False
        self._cancel = threading.Event()
        dialog = QProgressDialog(f"Replaying {Path(path).name}...", "Cancel", 0, 0, parent)
        dialog.setWindowTitle("Load session")
        dialog.setWindowModality(Qt.WindowModal)
        dialog.setMinimumDuration(0)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(self.cancel)
        self.dialog = dialog
        progress = _Progress(self)
        progress.changed.connect(self._on_progress)
        self.worker = load_session_worker(path, self._cancel, progress)
        self.worker.returned.connect(self._on_loaded)
        self.worker.errored.connect(self._on_failed)
        self.worker.finished.connect(self._on_finished)

    def start(self):
        self.dialog.show()
        self.worker.start()

    def cancel(self):
        """Stop the replay after the step in progress (it fails with LoadCancelled)."""
        self._cancel.set()

    def abandon(self):
        """Cancel, and drop whatever the worker still returns (the window is closing)."""
        self.abandoned = True
        self.cancel()

    def _on_progress(self, done, total):
        dialog = self.dialog
        if dialog is not None:
            dialog.setLabelText(f"Replaying step {done} of {total}..." if total
                                else "Replaying...")
            dialog.setMaximum(total)
            dialog.setValue(done)  # last: a modal dialog's setValue processes events

    def _on_loaded(self, session):
        if self.abandoned:
            return
        replaced = self.scene.adopt_session(session)
        message = f"loaded {self.path} ({session.step_count} steps)"
        if replaced:
            message += (f"; the priors were replaced by the session's {len(session.library)}: "
                        + ", ".join(session.library.names))
        self.said.emit(message, 3 * STATUS_SECONDS)

    def _on_failed(self, error):
        if self.abandoned:
            return
        if isinstance(error, LoadCancelled):
            self.said.emit("loading the session was cancelled; nothing changed", STATUS_SECONDS)
        else:
            self.failed.emit(error)

    def _on_finished(self):
        if self.dialog is not None:
            self.dialog.close()
            self.dialog.deleteLater()
            self.dialog = None
        self.finished.emit()
