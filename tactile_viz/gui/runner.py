"""Steps in a worker, drawn on the GUI thread no faster than the window can keep up.

The worker (superqt ``thread_worker``) steps a session, in the app's engine process
(:mod:`tactile_viz.app.engine_process`) or in its own thread, and yields
``(generation, snapshot)``; a stop flag is checked between steps, so *Pause* and closing the
window act after the step in progress. On the GUI thread a :class:`StepRunner` keeps only
the newest snapshot of the current session (snapshots of a session that is no longer
current are dropped) and hands it to ``draw`` from a single-shot timer: when drawing falls
behind the engine, the snapshots in between are skipped, never queued. Drawing is also
paced so that it takes at most ``duty`` of the wall time (in a thread the engine waits for
the interpreter while the window draws; in its process it shares the cores with the
software renderer).
"""

import threading
import time

from PySide6.QtCore import QObject, QThreadPool, QTimer, Signal
from superqt.utils import thread_worker

# Largest fraction of a run's wall time spent drawing. The window's drawing takes the cores
# from the engine process, so a run's overhead follows it. 0.07 since a run's renders are lit
# by one light (a draw about 75 ms instead of 100 ms for a novel object): about as many steps
# drawn a second as 0.1 drew before (with the engine in a thread 0.07 had drawn fewer steps
# without a measurable gain).
DRAW_DUTY = 0.07



def seconds_since(log, since):
    """Total seconds of the ``(start, seconds)`` entries of ``log`` that started at or after
    ``since`` (the newest are at the end)."""
    total = 0.0
    for began, seconds in reversed(log):
        if began < since:
            break
        total += seconds
    return total

class StepFailed(Exception):
    """A step raised a RuntimeError. superqt's generator worker takes a RuntimeError for its
    own deletion and drops it without reporting it or finishing, so it is passed on as this
    (same message, the original as its cause)."""


def stepped_here(session, count, stop, step_ends=None):
    """Step ``session`` in this thread ``count`` times (None: until it terminates) unless
    ``stop`` is set, yielding each snapshot (and appending the time each step ended to
    ``step_ends``, if given)."""
    done = 0
    while not stop.is_set() and not session.terminated and (count is None or done < count):
        snapshot = session.step()
        if step_ends is not None:
            step_ends.append(time.perf_counter())
        yield snapshot
        done += 1


@thread_worker(start_thread=False, ignore_errors=True)
def step_worker(session, count, stop, generation, step_ends=None, engine=None):
    """Step ``session`` ``count`` times (None: until it terminates) unless ``stop`` is set,
    in this worker's thread or, given an ``engine`` (:class:`EngineProcess`), in its
    process; yields ``(generation, snapshot)`` after each step (and appends the time each
    step ended to ``step_ends``, if given). A failed step goes to the worker's ``errored``
    signal only (superqt would also re-raise it in the GUI thread as an uncaught
    exception)."""
    snapshots = (stepped_here(session, count, stop, step_ends) if engine is None
                 else engine.steps(session, count, stop, step_ends))
    while True:
        try:
            snapshot = next(snapshots)
        except StopIteration:
            return
        except RuntimeError as error:
            raise StepFailed(str(error)) from error
        yield generation, snapshot


class StepRunner(QObject):
    """Runs a scene's session in a worker and draws its newest snapshot.

    Parameters
    ----------
    scene : tactile_viz.app.scene.Scene
    draw : callable
        ``draw(snapshot)`` on the GUI thread (the newest snapshot of the current session).
    duty : float
        Largest fraction of the wall time spent drawing while the worker runs.
    engine : EngineProcess, optional
        Steps in this process (see :mod:`tactile_viz.app.engine_process`); None: in the
        worker's thread.
    """

    started = Signal()
    finished = Signal()
    errored = Signal(object)

    def __init__(self, scene, draw, duty=DRAW_DUTY, parent=None, engine=None):
        super().__init__(parent)
        self.scene = scene
        self.engine = engine
        self.draw = draw
        self.duty = float(duty)
        self.worker = None
        self.generation = None
        self.pending = None
        self.drawn = 0  # snapshots drawn during runs
        self.received = 0  # snapshots received from the worker
        self.draw_seconds = []  # seconds of each draw() call (the viewport's part)
        self._stop = threading.Event()
        self._closing = False
        self._next_draw = 0.0
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.timeout.connect(self.flush)
        self.stop_requested_at = None
        self.step_ends = []  # perf_counter() at the end of each step of the current run
        self.finished_at = None  # perf_counter() when the run's end was handled
        # Drawing that a draw() leaves to later passes of the event loop (the viewport's
        # paint, the plots' draw_idle), counted in the pacing: a callable taking a
        # perf_counter() time and returning the seconds of such drawing begun since then.
        self.extra_seconds = lambda since: 0.0
        self._last_draw_began = None

    @property
    def running(self):
        return self.worker is not None

    def start(self, session, generation, count=None):
        """Step ``session`` (of scene generation ``generation``) ``count`` times (None: to
        termination). Returns False if a run is already in progress."""
        if self.running or self._closing:
            return False
        self._stop = threading.Event()
        self.generation = generation
        self.stop_requested_at = None
        self.step_ends = []
        worker = step_worker(session, count, self._stop, generation, self.step_ends,
                             self.engine)
        worker.yielded.connect(self._on_yielded)
        worker.errored.connect(self._on_errored)
        worker.finished.connect(self._on_finished)
        self.worker = worker
        self.started.emit()
        worker.start()
        return True

    def stop(self):
        """Stop after the step in progress (the worker checks between steps; it is not
        aborted, so that a run in the engine process brings the session's state back)."""
        if self.worker is not None and not self._stop.is_set():
            self.stop_requested_at = time.perf_counter()
            self._stop.set()
            if self.engine is not None:
                self.engine.request_stop()

    def shutdown(self, milliseconds=30_000):
        """Stop, drop whatever is pending and wait up to ``milliseconds`` for the step in
        progress to end (closing the window). True if the worker is done."""
        self._closing = True
        self._timer.stop()
        self.pending = None
        self.stop()
        done = True
        if self.worker is not None:
            done = QThreadPool.globalInstance().waitForDone(milliseconds)
            self.worker = None  # its queued finished signal may never be delivered now
        return done

    # ------------------------------------------------------------------ worker signals
    def _on_yielded(self, item):
        generation, snapshot = item
        if self._closing or not self.scene.is_current(generation):
            return  # a session that is no longer current: never drawn
        self.received += 1
        self.pending = snapshot
        if not self._timer.isActive():
            delay = max(0.0, self._next_draw - time.perf_counter())
            self._timer.start(int(delay * 1000))

    def _on_errored(self, error):
        if not self._closing:
            self.errored.emit(error)

    def _on_finished(self):
        self.worker = None
        if self._closing:
            return
        self.flush()  # the last step is always shown, at once
        self.finished_at = time.perf_counter()
        self.finished.emit()

    # ------------------------------------------------------------------ drawing
    def flush(self):
        """Draw the pending snapshot now (if any)."""
        self._timer.stop()
        snapshot, self.pending = self.pending, None
        if snapshot is None or self._closing:
            return
        if not self.scene.is_current(self.generation):
            return
        deferred = (0.0 if self._last_draw_began is None
                    else float(self.extra_seconds(self._last_draw_began)))
        began = time.perf_counter()
        self.draw(snapshot)
        ended = time.perf_counter()
        self._last_draw_began = began
        self.drawn += 1
        self.draw_seconds.append(ended - began)
        # Pace the next draw so that drawing (this one and everything the previous one left
        # to later passes: every paint and plot redraw since it) stays within `duty` of the
        # time; the worker waits for the interpreter while the GUI thread draws.
        seconds = ended - began + deferred
        self._next_draw = ended + seconds * (1.0 / self.duty - 1.0)
