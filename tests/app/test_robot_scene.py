"""The app's model in a robot's scene (tactile_viz.engine.scene): the truth rests on the
table, every session is made in the scene, and app.py's scene options reach the model."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from tactile_viz.app.scene import Scene
from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.scene import FREE, Scene as RobotScene
from tactile_viz.engine.session import RecordedSession, Session, make_truth

REPO_ROOT = Path(__file__).resolve().parents[2]
HEIGHT = -1.5


@pytest.fixture(scope="module")
def library(bundled):
    return PriorLibrary(bundled[name] for name in ["mug_1", "vase_1", "bottle_1"])


@pytest.fixture
def robot():
    return RobotScene.on_table(HEIGHT, reach_angle_deg=60.0, tip_radius=0.2)


@pytest.fixture
def scene(bundled, library, robot):
    # The bundled models keep their stable poses once found (seconds for the first pose).
    return Scene(truth_model=bundled["vase_1"], seed=1, library=PriorLibrary(list(library)),
                 robot_scene=robot)


def _lowest(truth, robot):
    """The truth's lowest point above the table, scene units."""
    return float(robot.height(truth.to_world(truth.model.mesh.vertices)).min())


def test_the_truth_rests_on_the_table(scene, robot):
    assert scene.robot_scene is robot
    tolerance = 1e-3 * scene.truth.model.length
    assert abs(_lowest(scene.truth, robot)) < tolerance
    scene.randomize_pose(2)
    assert abs(_lowest(scene.truth, robot)) < tolerance
    scene.set_truth_bundled("bottle_1")
    assert abs(_lowest(scene.truth, robot)) < tolerance
    # ... at the resting pose the engine gives the seed in this scene.
    expected = make_truth(scene.truth_model, rng=[scene.seed, 0], scene=robot)
    np.testing.assert_allclose(scene.truth.rotation, expected.rotation)
    np.testing.assert_allclose(scene.truth.translation, expected.translation)


def test_without_a_robot_scene_the_truth_floats_as_before(library):
    scene = Scene("vase_1", seed=1, library=library)
    assert scene.robot_scene is FREE
    expected = make_truth(scene.truth_model, rng=[1, 0])
    np.testing.assert_allclose(scene.truth.rotation, expected.rotation)
    np.testing.assert_allclose(scene.truth.translation, expected.translation)
    assert scene.ensure_session().scene is FREE
    with pytest.raises(ValueError, match="robot_scene"):
        Scene("vase_1", library=library, robot_scene={"tip_radius": 1.0})


def test_sessions_are_made_in_the_robot_scene(scene, robot, tmp_path):
    session = scene.ensure_session()
    assert isinstance(session, Session) and session.scene is robot
    assert session.setup()["scene"] is robot
    snapshot = scene.step()
    assert snapshot.step == 1
    # Every planned path keeps the tip's centre above the table.
    for path in snapshot.paths:
        assert robot.height(path).min() >= robot.tip_radius - 1e-6
    touches = tmp_path / "touches.csv"
    touches.write_text("kind,x,y,z,nx,ny,nz\ncontact,0.5,0,1,0,0,1\n")
    scene.open_observations(touches)
    recorded = scene.ensure_session()
    assert isinstance(recorded, RecordedSession) and recorded.scene is robot


def test_another_robot_scene_places_the_truth_anew(scene, robot):
    scene.step()
    truths, resets = [], []
    scene.truth_changed.connect(truths.append)
    scene.session_reset.connect(lambda: resets.append(True))
    higher = RobotScene.on_table(2.0, tip_radius=0.5)
    scene.set_robot_scene(higher)
    assert scene.robot_scene is higher and scene.session is None and resets
    assert truths == [scene.truth] and abs(_lowest(scene.truth, higher)) < 1e-2
    assert scene.ensure_session().scene is higher
    with pytest.raises(ValueError):
        scene.set_robot_scene(None)
    assert scene.robot_scene is higher


def test_a_loaded_session_brings_its_robot_scene(scene, robot, library, tmp_path):
    scene.step()
    saved = scene.save_session(tmp_path / "table.npz")
    other = Scene("mug_1", library=PriorLibrary(list(library)))
    other.load_session(saved)
    assert other.robot_scene.as_dict() == robot.as_dict()
    assert other.session.scene.as_dict() == robot.as_dict()
    assert abs(_lowest(other.truth, robot)) < 1e-3 * other.truth.model.length


# ---------------------------------------------------------------- app.py's options
@pytest.fixture
def launcher():
    spec = importlib.util.spec_from_file_location("app_launcher", REPO_ROOT / "app.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _robot(launcher, *argv):
    return launcher.scene_from_args(launcher.parse_args(["--log-file", "", *argv]))


def test_scene_options_make_the_robot_scene(launcher):
    assert _robot(launcher) is None  # the paper's free space: the model's FREE
    table = _robot(launcher, "--table")
    assert table.has_table and table.table_point.tolist() == [0, 0, 0]
    assert table.reach_angle_deg == 180 and table.tip_radius == 0
    high = _robot(launcher, "--table-height", "-2.5", "--reach-angle", "45", "--tip-radius",
                  "0.25")  # --table-height implies --table
    assert high.table_point.tolist() == [0, 0, -2.5] and high.up.tolist() == [0, 0, 1]
    assert high.reach_angle_deg == 45 and high.tip_radius == 0.25
    free = _robot(launcher, "--tip-radius", "0.1")  # a round tip in free space
    assert not free.has_table and free.tip_radius == 0.1


@pytest.mark.parametrize("argv, said", [
    (["--reach-angle", "0"], "--reach-angle: must lie in (0, 180]"),
    (["--reach-angle", "181"], "--reach-angle: must lie in (0, 180]"),
    (["--reach-angle", "nan"], "--reach-angle"),
    (["--tip-radius", "-0.1"], "--tip-radius: must be at least 0"),
    (["--table-height", "x"], "--table-height"),
])
def test_bad_scene_options_exit_2_with_one_line(launcher, capsys, argv, said):
    with pytest.raises(SystemExit) as stop:
        launcher.main(["--log-file", "", *argv])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and said in err


def test_the_launchers_scene_holds_the_robot_scene(launcher):
    args = launcher.parse_args(["--log-file", "", "--object", "vase_1", "--seed", "2",
                                "--table-height", "1", "--tip-radius", "0.2"])
    scene = launcher.build_scene(args)
    robot = scene.robot_scene
    assert robot.has_table and robot.tip_radius == 0.2 and robot.table_point[2] == 1
    assert abs(_lowest(scene.truth, robot)) < 1e-3 * scene.truth.model.length
    assert scene.ensure_session().scene is robot
    # Without the options the model is in the paper's free space.
    plain = launcher.build_scene(launcher.parse_args(["--log-file", "", "--object", "vase_1"]))
    assert plain.robot_scene is FREE
