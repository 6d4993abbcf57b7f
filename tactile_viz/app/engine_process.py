"""Steps sessions in a process of their own, so the engine never waits for the window.

In one process the engine's thread and the window's drawing (matplotlib, and VTK's calls
into a software renderer) take turns at one interpreter, and on a 2-core machine the
renderer's threads take the engine's core: drawing then adds its own time to a run. In a
process of its own the engine keeps a core and an interpreter, and the window draws on the
other core meanwhile.

The session stays where it was made (the app's model reads it as before); for a run its
pickled state (:meth:`Session.__getstate__ <tactile_viz.engine.session.Session>`: its
constructor's arguments, its filter and its checkpoint) goes to the engine process, every
snapshot comes back as it is made (and is appended to the session's list) and at the end
the session's :class:`~tactile_viz.engine.session.state.Checkpoint` comes back, what a step
changes (also after a failed step: then as before that step, which the session
restored). A session the process already holds (the one it ran last, not stepped elsewhere
since) is not sent again, and priors are sent once (by name, content, parameters and
learned flag; those the session sent last does not use are let go), so a run of a known
session costs a few bytes to start. Snapshots refer to their MAP shape's faces rather than
copy them.

Protocol, parent to child: ``("models", [(key, bytes), ...])``, ``("forget", [key, ...])``,
``("run", (class, state) bytes or None, count)``, ``("quit",)``; child to parent:
``("snapshot", Snapshot, seconds)`` after each step, ``("done", Checkpoint, error or
None)`` at the end.
"""

import atexit
import io
import logging
import multiprocessing
import os
import pickle
import queue
import signal
import threading
import time
import traceback
import weakref

from ..engine.errors import TactileVizError
from ..engine.shape.objects import ObjectModel

log = logging.getLogger(__name__)

# The engine yields the CPU to the window when both want it: on 2 cores a software render
# of the window's 2 threads beside the engine took 0.11-0.17 s instead of 0.07-0.12 s (the
# event loop blocked for up to 0.22 s), while the engine loses only the renders' share of
# a core (drawing is paced to a tenth of the time).
ENGINE_NICENESS = 10
POLL_SECONDS = 0.02  # how often a waiting run looks at its stop flag and at the process
ENGINES = ("process", "thread")  # where the app steps: this process's child, or a thread


class EngineProcessError(TactileVizError):
    """The engine process stopped or could not be started."""


def model_key(model):
    """What identifies a prior across processes: name, mesh content, parameters, flag."""
    return (model.name, model.content_hash, model.params, model.learned)


class _Pickler(pickle.Pickler):
    """Pickles models (and their faces arrays) as references to the other side's copies."""

    def __init__(self, file, keys, faces):
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self.keys, self.faces = keys, faces

    def persistent_id(self, obj):
        if isinstance(obj, ObjectModel):
            key = self.keys(obj)
            return None if key is None else ("model", key)
        key = self.faces.get(id(obj))
        return None if key is None else ("faces", key)


class _Unpickler(pickle.Unpickler):
    def __init__(self, file, models):
        super().__init__(file)
        self.models = models

    def persistent_load(self, pid):
        kind, key = pid
        model = self.models[key]
        return model if kind == "model" else model.mesh.faces


def _dumps(obj, keys, faces=None):
    buffer = io.BytesIO()
    _Pickler(buffer, keys, faces or {}).dump(obj)
    return buffer.getvalue()


def _loads(data, models):
    return _Unpickler(io.BytesIO(data), models).load()


def _read_back(session):
    """How many of the newest snapshots a step reads: the latest, and the last
    ``final_candidates`` ones, whose MAP priors a stopping novel session fits again
    (:meth:`~tactile_viz.engine.session.estimate.Estimator._recent_priors`)."""
    return 1 + max(0, int(getattr(session.params, "final_candidates", 0) or 0))


def _outgoing_state(session):
    """The session to send, as its class and pickled state, with the snapshots reduced to
    what a step reads (their count and the newest :func:`_read_back`)."""
    state = session.__getstate__()
    count = len(session.snapshots)
    keep = min(count, _read_back(session))
    state["snapshots"] = [None] * (count - keep) + list(session.snapshots[count - keep:])
    return type(session), state


def _incoming_session(cls, state):
    """The session :func:`_outgoing_state` sent."""
    session = cls.__new__(cls)
    session.__setstate__(state)
    return session


# ---------------------------------------------------------------------------- child
def serve(connection, stop, niceness=0):
    """The engine process: hold priors and the last session, run what the parent asks."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C in a terminal is the app's
    if niceness and hasattr(os, "nice"):
        os.nice(niceness)
    outbox = _Outbox(connection)
    models, keys, faces = {}, {}, {}
    session = None
    while True:
        try:
            message = connection.recv()
        except (EOFError, OSError):
            return
        kind = message[0]
        if kind == "quit":
            return
        if kind == "models":
            for key, data in message[1]:
                model = pickle.loads(data)
                models[key], keys[id(model)] = model, key
                faces[id(model.mesh.faces)] = key
        elif kind == "forget":
            for key in message[1]:
                model = models.pop(key)
                keys.pop(id(model), None)
                faces.pop(id(model.mesh.faces), None)  # (a renamed model shares its mesh)
        elif kind == "run":
            _, data, count = message
            if data is not None:
                session = _incoming_session(*_loads(data, models))
            _serve_run(outbox, session, count, stop, keys, faces)


class _Outbox:
    """Sends from a thread of its own: a step never waits for the parent to read (the
    parent reads between the window's drawing passes, and a pipe holds only 64 kB)."""

    def __init__(self, connection):
        self.connection = connection
        self.queue = queue.SimpleQueue()
        threading.Thread(target=self._send, name="outbox", daemon=True).start()

    def put(self, data):
        self.queue.put(data)

    def _send(self):
        while True:
            try:
                self.connection.send_bytes(self.queue.get())
            except (OSError, ValueError):
                return  # the parent is gone; the main loop ends on its next recv


def _serve_run(outbox, session, count, stop, keys, faces):
    done, error = 0, None
    key_of = lambda model: keys.get(id(model))  # noqa: E731 (a model made here: by value)
    keep = _read_back(session)
    while not stop.is_set() and not session.terminated and (count is None or done < count):
        try:
            snapshot = session.step()
        except Exception as caught:  # the session restored itself; the parent raises it
            error = caught
            break
        done += 1
        ended = time.perf_counter()  # the system's monotonic clock: the parent's too
        if len(session.snapshots) > keep:
            # The parent keeps them; a step reads the newest ``keep``.
            session.snapshots[-keep - 1] = None
        outbox.put(_dumps(("snapshot", snapshot, ended), key_of, faces))
    if error is not None:
        error = _portable(error)
    outbox.put(_dumps(("done", session.checkpoint(), error), key_of, faces))


def _portable(error):
    """``error`` if it pickles, else a RuntimeError with its message; the child's traceback
    goes with it as a note."""
    note = "in the engine process:\n" + "".join(traceback.format_exception(error))
    try:
        pickle.loads(pickle.dumps(error))
    except Exception:
        error = RuntimeError(f"{type(error).__name__}: {error}")
    error.add_note(note)
    return error


# ---------------------------------------------------------------------------- parent
class EngineProcess:
    """A process that steps sessions for this one (see the module's docstring).

    Parameters
    ----------
    context : str
        The multiprocessing start method; ``spawn`` (the default) starts a fresh
        interpreter, safe beside Qt's and VTK's threads.
    niceness : int, optional
        Added to the process's niceness (default :data:`ENGINE_NICENESS`) where the system
        has ``os.nice``.
    """

    def __init__(self, context="spawn", niceness=None):
        self._context = multiprocessing.get_context(context)
        self.niceness = ENGINE_NICENESS if niceness is None else int(niceness)
        self._process = None
        self._connection = None
        self._stop = None
        self._models = {}  # key -> this side's model, for every prior the child holds
        self._resident = None  # (weakref to the session the child holds, its step count)
        self._lock = threading.Lock()  # one run at a time

    @property
    def alive(self):
        return self._process is not None and self._process.is_alive()

    def start(self):
        """Start the process (it imports the engine meanwhile); nothing if it runs."""
        if self.alive:
            return
        self._forget()
        parent, child = self._context.Pipe(duplex=True)
        self._stop = self._context.Event()
        self._process = self._context.Process(
            target=serve, args=(child, self._stop, self.niceness), name="tactile_viz engine",
            daemon=True)
        try:
            self._process.start()
        except OSError as error:
            self._process = None
            raise EngineProcessError(f"could not start the engine process: {error}") from error
        child.close()
        self._connection = parent

    def close(self, timeout=1.0):
        """Stop the process: after the step in progress, or killed after ``timeout``."""
        if self._process is None:
            return
        if self._stop is not None:
            self._stop.set()
        try:
            self._connection.send(("quit",))
        except (OSError, ValueError):
            pass
        self._process.join(timeout)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout)
        self._forget()

    def _forget(self):
        if self._connection is not None:
            self._connection.close()
        self._process, self._connection, self._stop = None, None, None
        self._models, self._resident = {}, None

    def holds(self, session):
        """True if the process holds ``session`` as it is now (a run starts at once)."""
        resident = self._resident
        return (self.alive and resident is not None and resident[0]() is session
                and resident[1] == session.step_count)

    def request_stop(self):
        """End the run after the step in progress (any thread may call this)."""
        if self._stop is not None:
            self._stop.set()

    def steps(self, session, count=None, stop=None, step_ends=None):
        """Step ``session`` in the process ``count`` times (None: until it terminates),
        yielding each snapshot (already appended to ``session.snapshots``); ``stop`` (a
        ``threading.Event``) ends the run after the step in progress. At the end the
        session's state is the process's. ``step_ends``, if given, gets the
        ``time.perf_counter()`` at which each step ended in the process.

        Raises whatever a step raised (the session as before that step), or
        :class:`EngineProcessError` if the process stopped (the session as before the run).
        """
        with self._lock:
            before = len(session.snapshots)
            try:
                self.start()
                self._stop.clear()
                self._send_run(session, count)
                while (snapshot := self._take(session, self._receive(stop), step_ends)) is not None:
                    yield snapshot
            except (EOFError, OSError) as error:
                self._lost(session, before)
                raise EngineProcessError("the engine process stopped unexpectedly; the "
                                         "session is as it was before the run") from error
            except GeneratorExit:
                # The consumer went away mid-run: keep the session whole anyway.
                self.request_stop()
                try:
                    while self._take(session, self._receive(None)) is not None:
                        pass
                except (EOFError, OSError):
                    self._lost(session, before)
                except Exception:  # a step's error, with nobody left to show it
                    pass
                raise

    def _take(self, session, message, step_ends=None):
        """Apply a message of the process to ``session``: a snapshot is appended and
        returned; the final state is taken (its step's error raised) and None returned."""
        kind, *rest = message
        if kind == "snapshot":
            snapshot, ended = rest
            session.snapshots.append(snapshot)
            if step_ends is not None:
                step_ends.append(ended)
            return snapshot
        checkpoint, error = rest
        session.restore(checkpoint)
        self._resident = (weakref.ref(session), session.step_count)
        if error is not None:
            raise error
        return None

    def _lost(self, session, before):
        """The process died mid-run: the session as before the run, the process gone."""
        del session.snapshots[before:]
        self.close(timeout=0.1)

    def _send_run(self, session, count):
        if self.holds(session):
            self._connection.send(("run", None, count))
            return
        self._resident = None
        new, used = {}, set()

        def key_of(model):
            key = model_key(model)
            used.add(key)
            if key not in self._models:
                new.setdefault(key, model)
            return key

        data = _dumps(_outgoing_state(session), key_of)
        stale = [key for key in self._models if key not in used]
        if stale:  # priors of earlier sessions only: the process lets them go
            self._connection.send(("forget", stale))
            for key in stale:
                del self._models[key]
        if new:
            log.info("sending %d priors to the engine process", len(new))
            self._connection.send(("models", [(k, pickle.dumps(m, pickle.HIGHEST_PROTOCOL))
                                              for k, m in new.items()]))
            self._models.update(new)
        self._connection.send(("run", data, count))

    def _receive(self, stop):
        while True:
            if stop is not None and stop.is_set():
                self._stop.set()
            if self._connection.poll(POLL_SECONDS):
                break
            if not self._process.is_alive():
                raise EOFError("the engine process ended")
        return _loads(self._connection.recv_bytes(), self._models)


_shared = None


def shared_engine():
    """The app's one engine process (started on first use, stopped at exit)."""
    global _shared
    if _shared is None:
        _shared = EngineProcess()
        atexit.register(_shared.close)
    return _shared


__all__ = ["ENGINES", "EngineProcess", "EngineProcessError", "model_key", "shared_engine"]
