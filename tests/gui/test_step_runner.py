"""StepRunner with a fake session: coalescing, stale sessions, pause after the step."""

import time
from types import SimpleNamespace

import pytest

from tactile_viz.gui.runner import StepRunner

pytestmark = pytest.mark.gui


class FakeSession:
    """Steps that take ``seconds`` each (sleeping, so the GIL is free)."""

    def __init__(self, seconds=0.0, limit=1000):
        self.seconds = seconds
        self.limit = limit
        self.step_count = 0
        self.stepping = False

    @property
    def terminated(self):
        return self.step_count >= self.limit

    def step(self):
        self.stepping = True
        time.sleep(self.seconds)
        self.step_count += 1
        self.stepping = False
        return SimpleNamespace(step=self.step_count)


class FakeScene:
    def __init__(self):
        self.generation = 0

    def is_current(self, generation):
        return generation == self.generation


@pytest.fixture
def runner(qtbot):
    drawn = []
    scene = FakeScene()
    runner = StepRunner(scene, drawn.append)
    runner.drawn_snapshots = drawn
    yield runner
    runner.shutdown()


def _wait_done(qtbot, runner, timeout=10_000):
    qtbot.waitUntil(lambda: not runner.running, timeout=timeout)


def test_slow_drawing_draws_only_the_newest_snapshot(qtbot, runner):
    def slow_draw(snapshot):
        time.sleep(0.05)
        runner.drawn_snapshots.append(snapshot)

    runner.draw = slow_draw
    runner.start(FakeSession(seconds=0.002, limit=60), runner.scene.generation)
    _wait_done(qtbot, runner)
    steps = [snapshot.step for snapshot in runner.drawn_snapshots]
    assert runner.received == 60
    assert len(steps) < 30  # snapshots in between were skipped, not queued
    assert steps == sorted(set(steps)) and steps[-1] == 60  # the last step is always shown


def test_snapshots_of_a_stale_session_are_dropped(qtbot, runner):
    session = FakeSession(seconds=0.01, limit=20)
    runner.start(session, runner.scene.generation)
    runner.scene.generation += 1  # e.g. Reset while the worker is in a step
    _wait_done(qtbot, runner)
    assert session.step_count > 0
    assert runner.drawn_snapshots == [] and runner.received == 0


def test_pause_acts_after_the_step_in_progress(qtbot, runner):
    session = FakeSession(seconds=0.3)
    runner.start(session, runner.scene.generation)
    qtbot.waitUntil(lambda: session.step_count >= 2 and session.stepping, timeout=10_000)
    at_stop = session.step_count
    began = time.perf_counter()
    runner.stop()
    _wait_done(qtbot, runner)
    assert time.perf_counter() - began < 0.3 + 0.5
    assert session.step_count == at_stop + 1  # the step in progress, and no other
    assert runner.drawn_snapshots[-1].step == session.step_count


def test_shutdown_waits_for_the_step_in_progress_only(qtbot, runner):
    session = FakeSession(seconds=0.3)
    runner.start(session, runner.scene.generation)
    qtbot.waitUntil(lambda: session.step_count >= 1 and session.stepping, timeout=10_000)
    began = time.perf_counter()
    assert runner.shutdown()
    assert time.perf_counter() - began < 0.3 + 0.5 and not runner.running
    assert not runner.start(session, runner.scene.generation)  # closed for good


def test_deferred_drawing_counts_in_the_pacing(qtbot, runner):
    """Work a draw leaves to later event-loop passes (paints, plot redraws) is logged with
    its start time; the runner counts all of it since the previous draw."""
    log = []

    def draw(snapshot):
        runner.drawn_snapshots.append(snapshot)
        log.append((time.perf_counter(), 0.05))  # as if a 50 ms paint followed the draw

    runner.draw = draw
    runner.extra_seconds = lambda since: sum(s for b, s in log if b >= since)
    began = time.perf_counter()
    runner.start(FakeSession(seconds=0.01, limit=150), runner.scene.generation)
    _wait_done(qtbot, runner)
    elapsed = time.perf_counter() - began
    # Each draw costs 50 ms counted, so with duty 0.1 at most one draw per 0.45 s (plus the
    # first two and the last); counting only the draw calls would draw nearly every step.
    assert 2 <= runner.drawn <= elapsed / 0.45 + 3  # the first draw's cost counts at the second
    assert runner.drawn_snapshots[-1].step == 150


class FailingSession(FakeSession):
    """Its third step raises, as a failed engine step does."""

    def step(self):
        if self.step_count == 2:
            raise RuntimeError("the step failed")
        return super().step()


def test_a_failed_step_is_reported_once_and_not_raised(qtbot, runner):
    errors = []
    runner.errored.connect(errors.append)
    runner.start(FailingSession(), runner.scene.generation)
    _wait_done(qtbot, runner)
    qtbot.wait(50)  # pytest-qt fails the test if the error is re-raised in the event loop
    assert [str(error) for error in errors] == ["the step failed"]
    assert [snapshot.step for snapshot in runner.drawn_snapshots][-1] == 2
