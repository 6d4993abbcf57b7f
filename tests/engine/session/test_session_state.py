"""A session's state is explicit objects (tactile_viz.engine.session.state): a checkpoint
gives back every container of the exploration state, also a field added later, and a
pickled session holds its set-up, its filter and its checkpoint, not its attributes."""

import pickle
from dataclasses import dataclass, field, fields

import numpy as np
import pytest

from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.errors import SessionError
from tactile_viz.engine.session import (
    Aim,
    BelowTangentPlane,
    ExplorationState,
    RecordedSession,
    Session,
    make_truth,
)
from tactile_viz.engine.session.planner import Planner
from tactile_viz.engine.session.state import Checkpoint


@dataclass
class NotedState(ExplorationState):
    """The exploration state with a dict field, as a later change may add one."""

    notes: dict = field(default_factory=dict)


def _noted(state):
    return NotedState(**{item.name: getattr(state, item.name) for item in fields(state)})


@pytest.fixture(scope="module")
def library(bundled):
    return PriorLibrary(bundled[name] for name in ["mug_1", "bottle_1", "vase_1"])


def test_a_copy_shares_no_container_with_its_original():
    estimate = BelowTangentPlane(np.zeros(3), np.array([0.0, 0.0, 1.0]), lambda p: p[:, 0])
    state = NotedState(target=Aim(np.zeros(3), np.array([0.0, 0.0, 1.0]), estimate),
                       notes={"seen": [1]}, moves_rng={"state": {"key": 1}})
    copy = state.copy()
    copy.notes["seen"].append(2)
    copy.notes["new"] = 3
    copy.moves_rng["state"]["key"] = 2
    copy.given_up.append(np.ones(3))
    copy.target.position[0] = 5.0
    assert state.notes == {"seen": [1]} and state.moves_rng == {"state": {"key": 1}}
    assert state.given_up == [] and state.target.position[0] == 0.0
    # The estimate (a callable of points) is shared: a step replaces it, never changes it.
    assert copy.target.estimate is estimate and copy.target.estimate.outside is estimate.outside


def test_a_dict_field_survives_the_rollback_of_a_failed_step(bundled, library, monkeypatch):
    session = Session.simulated(make_truth(bundled["mug_1"], rng=1), library, seed=1)
    session.run(max_steps=2)
    session.state = _noted(session.state)
    given_up = list(session.state.given_up)

    def broken(*args, **kwargs):
        session.state.notes["touched"] = True
        session.state.given_up.append(np.zeros(3))
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(Planner, "stop_test", broken)  # after the filter update
    with pytest.raises(RuntimeError, match="simulated"):
        session.step()
    assert isinstance(session.state, NotedState) and session.state.notes == {}
    assert len(session.state.given_up) == len(given_up) and session.step_count == 2


def test_a_checkpoint_restored_twice_gives_the_same_state(bundled, library):
    session = Session.simulated(make_truth(bundled["mug_1"], rng=2), library, seed=2)
    session.run(max_steps=2)
    saved = session.checkpoint()
    assert isinstance(saved, Checkpoint) and saved.steps == 2
    first = session.step()
    session.restore(saved)
    session.state.given_up.append(np.zeros(3))  # must not reach the checkpoint
    session.restore(saved)
    again = session.step()
    np.testing.assert_array_equal(first.contacts, again.contacts)
    np.testing.assert_array_equal(first.map_translation, again.map_translation)


def test_a_pickled_session_steps_on_as_the_original(bundled, library):
    session = Session.simulated(make_truth(bundled["vase_1"], rng=3), library, seed=3)
    session.run(max_steps=3)
    state = session.__getstate__()
    assert set(state) == {"setup", "filter", "snapshots", "checkpoint"}
    assert set(state["setup"]) == {"truth", "library", "strategy", "params", "seed",
                                   "sensor_noise", "sensor_outliers", "scene"}
    copy = pickle.loads(pickle.dumps(session))
    assert copy.step_count == 3 and copy.params == session.params
    for _ in range(2):
        a, b = session.step(), copy.step()
        np.testing.assert_array_equal(a.contacts, b.contacts)
        assert a.map_class == b.map_class and a.dhd == b.dhd


def test_a_pickled_recording_keeps_its_place(bundled, library):
    source = Session.simulated(make_truth(bundled["mug_1"], rng=4), library, seed=4)
    source.run(max_steps=4)
    recording = RecordedSession(source.recorded_steps(), library, seed=4, source="test")
    recording.step()
    recording.step()
    copy = pickle.loads(pickle.dumps(recording))
    assert copy.replayed == recording.replayed == 2 and copy.source == "test"
    np.testing.assert_array_equal(copy.step().contacts, recording.step().contacts)
    np.testing.assert_array_equal(copy.latest.contacts, source.snapshots[2].contacts)


def test_a_session_takes_no_truth_and_a_simulated_one_is_built_apart(bundled, library):
    robot = Session(library, seed=1)
    assert robot.truth is None and robot.evaluator is None and robot.sensor is None
    assert set(robot.setup()) == {"library", "strategy", "params", "seed", "sensor_noise",
                                  "sensor", "scene"}
    truth = make_truth(bundled["mug_1"], rng=1)
    simulated = Session.simulated(truth, library, seed=1, sensor_outliers=0.1)
    assert simulated.sensor is simulated.simulator and simulated.truth is truth
    assert simulated.sensor_outliers == 0.1 and simulated.evaluator.truth is truth
    rebuilt = Session.from_setup(**simulated.setup())
    assert rebuilt.truth is truth and rebuilt.sensor_outliers == 0.1
    with pytest.raises(SessionError, match="PriorLibrary"):
        Session([bundled["mug_1"]])


def test_the_old_signature_warns_and_makes_the_same_session(bundled, library):
    truth = make_truth(bundled["mug_1"], rng=2)
    new = Session.simulated(truth, library, "gpis-dhd", seed=2, sensor_noise=(0.02, 1.0),
                            sensor_outliers=0.05)
    with pytest.warns(DeprecationWarning, match="Session.simulated"):
        old = Session(truth, library, "gpis-dhd", seed=2, sensor_noise=(0.02, 1.0),
                      sensor_outliers=0.05)
    with pytest.warns(DeprecationWarning):
        robot = Session(None, library, seed=2)
    assert robot.truth is None and old.sensor_outliers == 0.05
    for _ in range(2):
        a, b = new.step(), old.step()
        np.testing.assert_array_equal(a.contacts, b.contacts)
        assert a.pose_error == b.pose_error
    with pytest.raises(TypeError, match="multiple values"), pytest.warns(DeprecationWarning):
        Session(truth, library, "gpis-dhd", library=library)
