"""The engine process (tactile_viz.app.engine_process): the app's sessions stepped in a
process of their own, with the same results as in this one and nothing lost on failure."""

import numpy as np
import pytest

from tactile_viz.app.engine_process import EngineProcess, EngineProcessError
from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.io.observation_file import RecordedStep
from tactile_viz.engine.session import RecordedSession, Session, SessionError, make_truth


@pytest.fixture(scope="module")
def library(bundled):
    return PriorLibrary(bundled[name] for name in ["mug_1", "vase_1", "bottle_1"])


@pytest.fixture(scope="module")
def engine():
    process = EngineProcess()
    yield process
    process.close()


def _session(bundled, library, name="vase_2", seed=1):
    return Session.simulated(make_truth(bundled[name], rng=seed), library, "gpis-dhd", seed=seed)


def _same(first, second):
    assert [s.step for s in first] == [s.step for s in second]
    for a, b in zip(first, second):
        assert a.map_class == b.map_class and a.dhd == b.dhd and a.novel == b.novel
        assert np.array_equal(a.contacts, b.contacts)
        assert np.array_equal(a.map_translation, b.map_translation)


def test_steps_in_the_process_match_steps_here(bundled, library, engine):
    remote, local = _session(bundled, library), _session(bundled, library)
    yielded = list(engine.steps(remote, 6))
    local.run(max_steps=6)
    assert [id(s) for s in yielded] == [id(s) for s in remote.snapshots]
    assert remote.step_count == local.step_count <= 6
    _same(remote.snapshots, local.snapshots)
    # The process holds the session now: the next run continues it without sending it.
    assert engine.holds(remote)
    list(engine.steps(remote, 4))
    local.run(max_steps=4)
    _same(remote.snapshots, local.snapshots)
    # ... and the state that came back steps on here exactly as the process would.
    _same([remote.step()], [local.step()])
    assert not engine.holds(remote)  # stepped here since: sent again on the next run
    list(engine.steps(remote, 2))
    local.run(max_steps=2)
    _same(remote.snapshots, local.snapshots)


def test_snapshots_share_the_priors_faces(bundled, library, engine):
    session = _session(bundled, library, "mug_1", seed=0)
    last = list(engine.steps(session, 3))[-1]
    assert last.map_faces is library[last.map_class].mesh.faces


def test_stop_ends_the_run_after_the_step_in_progress(bundled, library, engine):
    import threading

    session, stop = _session(bundled, library), threading.Event()
    for snapshot in engine.steps(session, None, stop):
        if snapshot.step == 3:
            stop.set()
    assert session.step_count in (3, 4) and not session.terminated
    local = _session(bundled, library)
    local.run(max_steps=session.step_count + 2)
    list(engine.steps(session, 2))
    _same(session.snapshots, local.snapshots)


def test_an_abandoned_run_still_brings_the_state_back(bundled, library, engine):
    session = _session(bundled, library)
    steps = engine.steps(session, None)
    next(steps)
    steps.close()  # the consumer went away mid-run
    count = session.step_count
    assert 1 <= count < 10 and engine.holds(session)
    local = _session(bundled, library)
    local.run(max_steps=count + 1)
    list(engine.steps(session, 1))
    _same(session.snapshots, local.snapshots)


def test_a_failed_step_is_raised_and_the_session_kept(bundled, library, engine):
    source = _session(bundled, library)
    source.run(max_steps=2)
    steps = source.recorded_steps()
    broken = RecordedStep(steps[1].observations, np.array([[np.nan, 0.0, 0.0]]))
    session = RecordedSession([steps[0], broken, steps[1]], library, seed=1)
    with pytest.raises(SessionError, match="finite"):
        list(engine.steps(session, None))
    assert session.step_count == 1 and engine.holds(session)
    _same(session.snapshots, source.snapshots[:1])


def test_a_dead_process_loses_nothing_and_is_restarted(bundled, library):
    process = EngineProcess()
    try:
        session = _session(bundled, library)
        list(process.steps(session, 2))
        before = list(session.snapshots)
        with pytest.raises(EngineProcessError, match="stopped unexpectedly"):
            for snapshot in process.steps(session, None):
                if snapshot.step == 3:
                    process._process.kill()
        assert session.snapshots == before and not process.alive
        list(process.steps(session, 1))  # a new process, sent the session again
        local = _session(bundled, library)
        local.run(max_steps=3)
        _same(session.snapshots, local.snapshots)
    finally:
        process.close()


def test_priors_no_session_uses_are_let_go(bundled, library, engine):
    from tactile_viz.app.engine_process import model_key

    list(engine.steps(_session(bundled, library), 1))
    fewer = library.subset(["mug_1", "vase_1"])
    session = Session.simulated(make_truth(bundled["vase_2"], rng=1), fewer, "gpis-dhd", seed=1)
    list(engine.steps(session, 2))
    truth = model_key(bundled["vase_2"])  # the simulated object goes too
    assert set(engine._models) == {model_key(model) for model in fewer} | {truth}
    local = Session.simulated(make_truth(bundled["vase_2"], rng=1), fewer, "gpis-dhd", seed=1)
    local.run(max_steps=2)
    _same(session.snapshots, local.snapshots)
    list(engine.steps(_session(bundled, library), 1))  # sent again when used again
    assert set(engine._models) == {model_key(model) for model in library} | {truth}


def test_a_session_in_a_robot_scene_keeps_it_in_the_process(bundled, library, engine):
    from tactile_viz.engine.scene import Scene as RobotScene

    robot = RobotScene.on_table(-1.0, reach_angle_deg=60.0, tip_radius=0.2)

    def session():
        truth = make_truth(bundled["vase_2"], rng=3, scene=robot)
        return Session.simulated(truth, library, "gpis-dhd", seed=3, scene=robot)

    remote, local = session(), session()
    list(engine.steps(remote, 3))
    local.run(max_steps=3)
    assert remote.scene is robot  # the parent's session keeps its own scene
    _same(remote.snapshots, local.snapshots)  # the process stepped in the same scene


def test_a_novel_session_stops_in_the_process(bundled, library, engine):
    """The stop of a novel session reads the MAP priors of its last steps
    (``final_candidates``): the process keeps those snapshots, not only the latest."""
    from tactile_viz.engine.params import with_changes
    from tactile_viz.engine.session import session_preset

    # Every step judged novel (known only at the evidence's maximum), on any machine.
    params = with_changes(session_preset("recommended"), max_steps_known=3,
                          max_steps_novel=3, known_fraction=1.0)
    assert params.final_candidates > 0

    def session():
        return Session.simulated(make_truth(bundled["mug_2"], rng=[0, 0]), library, "gpis-dhd",
                       params, seed=0)

    remote, local = session(), session()
    list(engine.steps(remote, 1))
    list(engine.steps(remote, None))  # continued: the process holds the session
    local.run()
    assert remote.terminated and remote.latest.novel
    _same(remote.snapshots, local.snapshots)
    # Sent anew (stepped here since): the snapshots a step reads go with it.
    again = session()
    again.run(max_steps=2)
    list(engine.steps(again, None))
    assert again.terminated
    _same(again.snapshots, local.snapshots)
