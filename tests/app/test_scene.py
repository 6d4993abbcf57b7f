"""The app's Qt-free model (tactile_viz.app): settings, signals, and bad input that changes
nothing."""

import numpy as np
import pytest

from tactile_viz.app.scene import Scene
from tactile_viz.engine import LibraryError, MeshError, ObservationFileError, PriorLibrary
from tactile_viz.engine.session import SessionError


@pytest.fixture
def scene(bundled):
    library = PriorLibrary(bundled[name] for name in ["mug_1", "vase_1", "bottle_1"])
    return Scene("vase_1", seed=1, library=library)


def test_steps_announce_snapshots(scene):
    seen = []
    scene.stepped.connect(seen.append)
    scene.step()
    scene.step()
    assert [s.step for s in seen] == [1, 2] and scene.latest is seen[-1]


def test_settings_reset_the_session(scene):
    resets = []
    scene.session_reset.connect(lambda: resets.append(True))
    scene.step()
    scene.set_parameter("eps", 0.8)
    assert scene.session is None and resets and scene.params.eps == 0.8
    scene.set_preset("fast")
    assert scene.params.filter.n_features == 120 and scene.parameter("eps") == 0.6
    scene.set_strategy("rrt")
    assert scene.ensure_session().strategy == "rrt"


def test_invalid_settings_change_nothing(scene):
    with pytest.raises(ValueError):
        scene.set_parameter("n_s", 0)
    with pytest.raises(ValueError):
        scene.set_parameter("sigma_q", 1.0)
    with pytest.raises(ValueError):
        scene.set_preset("fastest")
    assert scene.overrides == {} and scene.preset == "recommended"


def test_bad_mesh_changes_nothing(scene, tmp_path):
    scene.step()
    session, truth = scene.session, scene.truth
    bad = tmp_path / "bad.obj"
    bad.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="bad.obj"):
        scene.set_truth_file(bad)
    with pytest.raises(MeshError, match="bad.obj"):
        scene.add_prior_file(bad)
    assert scene.session is session and scene.truth is truth
    assert scene.library.names == ["mug_1", "vase_1", "bottle_1"]


def test_prior_selection(scene):
    scene.set_prior_enabled("mug_1", False)
    assert scene.active_library().names == ["vase_1", "bottle_1"]
    with pytest.raises(LibraryError):
        scene.set_prior_enabled("sofa_9", True)
    for name in ["vase_1", "bottle_1"]:
        scene.set_prior_enabled(name, False)
    with pytest.raises(SessionError, match="no prior"):
        scene.step()


def test_learned_shape_needs_a_reconstruction(scene):
    assert not scene.can_learn()
    with pytest.raises(SessionError):
        scene.add_learned_shape()


def test_save_and_load_session(scene, tmp_path):
    with pytest.raises(SessionError):
        scene.save_session(tmp_path / "none.npz")
    scene.step()
    scene.step()
    scene.save_session(tmp_path / "s.npz")
    other = Scene("mug_1", library=PriorLibrary(list(scene.library)))
    seen = []
    other.stepped.connect(seen.append)
    other.load_session(tmp_path / "s.npz")
    # The view is told the latest state once, not every replayed step.
    assert other.truth_model.name == "vase_1" and [s.step for s in seen] == [2]


def test_library_folders_round_trip_and_corrupt_ones_change_nothing(scene, tmp_path):
    scene.set_prior_enabled("mug_1", False)
    folder = scene.save_library(tmp_path / "priors")
    scene.load_library(folder)
    assert scene.library.names == ["mug_1", "vase_1", "bottle_1"]
    assert all(scene.enabled.values())
    (folder / "library.json").write_text("{not json")
    library = scene.library
    with pytest.raises(LibraryError, match="corrupt"):
        scene.load_library(folder)
    assert scene.library is library


def test_prior_from_file_is_added_and_enabled(scene, bundled, tmp_path):
    path = tmp_path / "sofa.ply"
    bundled["sofa_1"].mesh.export(path)
    model = scene.add_prior_file(path)
    assert model.name == "sofa" and scene.enabled["sofa"]
    with pytest.raises(LibraryError, match="already"):
        scene.add_prior_file(path)
    assert scene.active_library().names[-1] == "sofa"


def test_snapshots_carry_the_heaviest_other_hypotheses(scene):
    for _ in range(3):
        snapshot = scene.step()
    hypotheses = snapshot.hypotheses
    assert 1 <= len(hypotheses) <= 4
    weights = [weight for *_, weight in hypotheses]
    assert weights == sorted(weights, reverse=True) and 0 < sum(weights) <= 1
    for name, rotation, translation, _ in hypotheses:
        assert name in scene.library.names and rotation.shape == (3, 3)
        assert not (name == snapshot.map_class
                    and np.allclose(translation, snapshot.map_translation, atol=1e-3)
                    and np.allclose(rotation, snapshot.map_rotation, atol=1e-3))


def test_a_recording_replaces_the_simulator_until_the_truth_changes(scene, tmp_path):
    for _ in range(3):
        scene.step()
    contacts = scene.latest.contacts
    path = scene.export(tmp_path / "export")[0]
    truths = []
    scene.truth_changed.connect(truths.append)
    (tmp_path / "broken.csv").write_text("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,,,\n")
    with pytest.raises(ObservationFileError, match="broken.csv, line 2"):
        scene.open_observations(tmp_path / "broken.csv")
    assert scene.recording is None and scene.truth is not None and scene.latest.step == 3
    assert scene.open_observations(path) == 3 and truths == [None]
    for _ in range(3):
        scene.step()
    np.testing.assert_array_equal(scene.latest.contacts, contacts)
    assert scene.session.terminated and scene.latest.pose_error is None
    saved = scene.save_session(tmp_path / "replayed.npz")
    scene.randomize_pose(4)
    assert scene.recording is None and truths[-1] is scene.truth
    scene.load_session(saved)  # a session without truth comes back as a recording
    assert scene.truth is None and len(scene.recording[1]) == 3 and scene.latest.step == 3


def test_knob_units_come_from_the_parameters_metadata():
    from tactile_viz.app.scene import FILTER_KNOBS, SESSION_KNOBS, knob_length_power
    from tactile_viz.engine.params import FilterParams, SessionParams, length_fields

    powers = {name: knob_length_power(name) for name in FILTER_KNOBS + SESSION_KNOBS}
    assert powers == {name: {**length_fields(FilterParams), **length_fields(SessionParams)}
                      .get(name, 0) for name in powers}
    assert powers["eps"] == powers["sigma_d"] == 1 and powers["n_s"] == 0
    with pytest.raises(ValueError):
        knob_length_power("gpis_scale")


def test_lengths_in_scene_units_follow_the_object_size(bundled):
    from tactile_viz.engine import ObjectModel

    mug = bundled["mug_1"]
    small = ObjectModel.from_arrays(mug.mesh.vertices * 0.02, mug.mesh.faces, "small_mug")
    scene = Scene(truth_model=small, seed=1, library=PriorLibrary([small]), units="m")
    assert scene.unit_name == "m" and scene.truth_size() == pytest.approx(0.12)
    assert scene.error_threshold() == pytest.approx(0.012)
    assert scene.eps_length() == pytest.approx(0.012)  # the priors' size before a step
    scene.set_parameter("eps", 0.8)
    snapshot = scene.step()
    assert scene.map_model(snapshot).name == "small_mug"
    assert scene.eps_length(snapshot) == pytest.approx(0.8 * 0.12 / 6)
    paper = Scene("mug_1", seed=1, library=PriorLibrary([mug]))
    assert paper.unit_name == "scene units"
    assert (paper.truth_size(), paper.error_threshold(), paper.eps_length()) == pytest.approx(
        (6.0, 0.6, 0.6))
    with pytest.raises(ValueError):
        Scene("mug_1", library=PriorLibrary([mug]), units="furlong")


# ---------------------------------------------------------------- units of recordings
@pytest.fixture(scope="module")
def metric_recording(tmp_path_factory):
    """A library in metres (mug_1 at 10 and 20 cm, a 25 cm bottle) and 12 touches of the
    20 cm mug written in millimetres: with a ``# units: mm`` line and without one."""
    from tactile_viz.engine.explore.simulator import ContactSimulator, random_touch
    from tactile_viz.engine.io.observation_file import format_observations, read_observations
    from tactile_viz.engine.session import make_truth
    from tactile_viz.engine.shape.objects import load_bundled

    library = PriorLibrary()
    for name, size in [("mug_1", 0.10), ("mug_1", 0.20), ("bottle_1", 0.25)]:
        library.add(load_bundled(name, size=size).renamed(f"{name}_{size:g}"), units="m")
    truth = make_truth(library["mug_1_0.2"], rng=[3, 0])
    simulator, rng = ContactSimulator(truth), np.random.default_rng(3)
    steps = [([simulator.probe(random_touch(truth, rng))], np.zeros((0, 3))) for _ in range(12)]
    folder = tmp_path_factory.mktemp("recording")
    (folder / "m.csv").write_text(format_observations(steps, units="m"))
    text = format_observations(read_observations(folder / "m.csv", units="mm"), units="mm")
    (folder / "touches_mm.csv").write_text(text)
    (folder / "no_units.csv").write_text(text.split("\n", 1)[1])
    return library, folder


def test_the_app_and_replay_give_one_estimate_of_a_millimetre_recording(metric_recording):
    from tactile_viz.commands.replay import replay
    from tactile_viz.engine.io.observation_file import read_observations

    library, folder = metric_recording
    path = folder / "touches_mm.csv"
    replayed, _ = replay(read_observations(path, "m"), library, seed=3)
    scene = Scene(seed=3, library=library)  # in metres: the library's unit
    assert scene.units == "m" and scene.open_observations(path) == 12 and scene.warnings == []
    session = scene.ensure_session()
    while not session.terminated:
        scene.step()
    ours, theirs = scene.latest, replayed.latest
    assert ours.step == theirs.step and ours.map_class == theirs.map_class
    assert ours.novel == theirs.novel
    np.testing.assert_allclose(ours.contacts, theirs.contacts, rtol=1e-12)
    np.testing.assert_allclose(ours.map_translation, theirs.map_translation, atol=1e-9)
    np.testing.assert_allclose(ours.map_rotation, theirs.map_rotation, atol=1e-9)
    assert np.abs(ours.contacts).max() < 1.0  # metres, not millimetres


def test_a_recording_likely_in_another_unit_warns(metric_recording):
    library, folder = metric_recording
    scene = Scene(seed=3, library=library, units="m")
    assert scene.open_observations(folder / "no_units.csv") == 12
    (message,) = scene.warnings
    assert "no_units.csv spans" in message and "0.2 m long" in message
    assert "is the file in mm?" in message
    scene.open_observations(folder / "m.csv")
    assert scene.warnings == []


def test_a_library_saved_in_metres_loads_into_a_millimetre_scene(metric_recording, tmp_path):
    library, _ = metric_recording
    library.save(tmp_path / "lib")
    scene = Scene(seed=3, library=library, units="mm")
    scene.load_library(tmp_path / "lib")
    np.testing.assert_allclose([m.length for m in scene.library], [100.0, 200.0, 250.0],
                               rtol=1e-6)
    assert scene.library.units == "mm"
