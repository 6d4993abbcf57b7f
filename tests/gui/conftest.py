"""Fixtures for the GUI tests (pytest-qt on a real X server).

The display comes from the pytest-xvfb plugin, which starts Xvfb for the test
session. pyvistaqt's QtInteractor cannot render with QT_QPA_PLATFORM=offscreen
("Render window is not current"), so the xcb platform is forced here, before
pytest-qt creates the QApplication.
"""

from __future__ import annotations

import gc
import os
import threading
import time

import numpy as np
import pytest

os.environ["QT_QPA_PLATFORM"] = "xcb"

try:
    import pyvistaqt  # noqa: F401
    from PySide6.QtCore import QCoreApplication, QEvent, QThread, QThreadPool
    from PySide6.QtGui import QGuiApplication, QWindow
    from PySide6.QtWidgets import QApplication, QWidget
except ImportError as exc:  # the gui extra is not installed: skip this folder
    pytest.skip(
        f"GUI tests need the gui extra (pip install -e '.[gui]'): {exc}",
        allow_module_level=True,
    )


def pytest_collection_modifyitems(config, items):
    """Every GUI test is ``slow`` (pytest -m "not slow" leaves this folder out)."""
    here = os.path.dirname(__file__)
    for item in items:
        if str(item.path).startswith(here + os.sep):
            item.add_marker(pytest.mark.slow)


def _flush_events(app: QCoreApplication) -> None:
    for _ in range(3):
        app.processEvents()
        QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)


def _settled_screenshot(plotter, app, timeout=10.0):
    """``plotter``'s image once two renders in a row give the same pixels (RGB, uint8).

    A read right after a resize or a data change can return a frame the X server has not
    finished (CI once read black and green where an opaque white legend stood); the
    pixels asserted on are the ones the window settles on.
    """
    deadline = time.monotonic() + timeout
    previous = None
    while True:
        app.processEvents()
        plotter.render()
        image = plotter.screenshot(return_img=True)[..., :3]
        if previous is not None and previous.shape == image.shape and np.array_equal(
                previous, image):
            return image
        if time.monotonic() > deadline:
            raise AssertionError(f"the viewport did not settle within {timeout} s")
        previous = image
        time.sleep(0.05)


def _top_level_widgets() -> list[QWidget]:
    """Top-level widgets, less stale wrappers.

    PySide can hand back the wrapper of a freed C++ object for a new one at the same
    address: pyvistaqt's fallback ``QOffscreenSurface`` came back as a top-level widget on
    CI, and ``isVisible`` then raised in every later test.
    """
    return [w for w in QApplication.topLevelWidgets() if isinstance(w, QWidget)]


def _open_windows() -> list[str]:
    widgets = [w for w in _top_level_widgets() if w.isVisible()]
    windows = [w for w in QGuiApplication.topLevelWindows()
               if isinstance(w, QWindow) and w.isVisible()]
    names = [f"{type(w).__name__}({w.windowTitle()!r})" for w in widgets]
    names += [f"QWindow {type(w).__name__}({w.title()!r})" for w in windows]
    return names


def _running_qthreads(app: QCoreApplication) -> list[QThread]:
    """Running QThreads other than the main one (found via their Python wrappers)."""
    main = app.thread()
    found = []
    for obj in gc.get_objects():
        try:
            if isinstance(obj, QThread) and obj is not main and obj.isRunning():
                found.append(obj)
        except RuntimeError:  # wrapper whose C++ object is already deleted
            continue
    return found


@pytest.fixture(scope="module")
def off_screen():
    """``pyvista.OFF_SCREEN`` for one module's plotters, restored after it: set at import,
    it held for the whole session and put the main window's view off screen too, whose
    screenshots then read garbage."""
    import pyvista as pv

    before, pv.OFF_SCREEN = pv.OFF_SCREEN, True
    yield
    pv.OFF_SCREEN = before


@pytest.fixture(scope="session")
def settled_screenshot(qapp):
    """``settled_screenshot(plotter)``: the plotter's pixels once they stop changing."""
    return lambda plotter: _settled_screenshot(plotter, qapp)


@pytest.fixture(autouse=True)
def no_leaked_windows_or_threads(qapp):
    """Fail a test that leaves a window open or a (Q)thread running.

    pytest-qt closes the widgets registered with qtbot.addWidget before
    fixture teardown, so everything a test opened must be closed by now.
    """
    threads_before = set(threading.enumerate())
    qthreads_before = {id(t) for t in _running_qthreads(qapp)}
    yield
    _flush_events(qapp)

    deadline = time.monotonic() + 2.0
    pool = QThreadPool.globalInstance()
    while True:
        # A thread Python did not start (an idle thread of Qt's pool that once logged) stays
        # listed as a _DummyThread for good; the pool's running work is checked instead.
        extra_threads = [
            t for t in threading.enumerate() if t not in threads_before and t.is_alive()
            and not isinstance(t, threading._DummyThread)
        ]
        qthreads = [t for t in _running_qthreads(qapp) if id(t) not in qthreads_before]
        busy = pool.activeThreadCount()
        if not (extra_threads or qthreads or busy) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
        _flush_events(qapp)

    windows = _open_windows()
    # Clean up so one leaking test does not make the following ones fail too.
    for w in _top_level_widgets():
        if w.isVisible():
            w.close()
    _flush_events(qapp)

    problems = []
    if windows:
        problems.append(f"top-level windows still open: {windows}")
    if extra_threads:
        problems.append(f"Python threads still alive: {[t.name for t in extra_threads]}")
    if qthreads:
        names = [f"{type(t).__name__}({t.objectName()!r})" for t in qthreads]
        problems.append(f"QThreads still running: {names}")
    if busy:
        problems.append(f"{busy} worker(s) of Qt's thread pool still running")
    if problems:
        pytest.fail("; ".join(problems))
