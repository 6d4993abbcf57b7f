"""The example robot (examples/robot.py): guarded moves of a spherical tip by ray casting on
a mesh in metres, at a table, driving a session in the callback and the ask/tell styles."""

import numpy as np
import pytest

from tactile_viz.engine import Contact, NonContact


@pytest.fixture(scope="module")
def robot_example(load_example):
    return load_example("robot.py", "robot_example")


def test_both_styles_recognise_a_mug_as_the_simulator_does(robot_example, capsys):
    results = robot_example.main(["--object", "mug_1", "--seed", "0", "--steps", "40"])
    assert set(results) == {"simulator", "callback", "ask/tell"}
    assert results["callback"] == results["ask/tell"]  # one loop, the same trajectory
    for result in results.values():
        # Within 40 steps the mug is known on every trajectory; its pose is right once it
        # is decided (before, the handle may still be anywhere nothing touched).
        assert result["map_class"] == "mug_1" and not result["novel"]
        assert result["success"] or not result["decided"]
    assert "ask/tell" in capsys.readouterr().out


def test_the_robot_answers_guarded_moves(robot_example):
    _, mesh, _ = robot_example.place("bottle_1", 1)
    robot = robot_example.RayCastingRobot(mesh)
    centre = mesh.bounds.mean(axis=0)
    far = centre + [1.0, 0.0, 0.0]
    hit = robot.probe([far, centre])
    assert isinstance(hit, Contact) and hit.normal @ (far - centre) > 0
    miss = robot.probe([far, far + [0.0, 1.0, 0.0]])
    assert isinstance(miss, NonContact)
    np.testing.assert_allclose(miss.position, far + [0.0, 1.0, 0.0])


def test_a_round_tip_at_a_table(robot_example):
    """The tip touches the object with its sphere (the surface point reported), the table
    with its sphere too (a point on the plane, the normal up), and the controller refuses
    paths below the table and outside the reach cone."""
    from tactile_viz.engine.scene import Scene

    radius = 0.005
    scene = Scene.on_table(0.0, 60.0, radius)
    _, mesh, _ = robot_example.place("bottle_1", 1, scene)
    assert abs(mesh.bounds[0, 2]) < 1e-6  # resting on the table
    robot = robot_example.RayCastingRobot(mesh, scene)
    top = mesh.bounds.mean(axis=0) * [1, 1, 0] + [0, 0, mesh.bounds[1, 2] + 0.05]
    hit = robot.probe([top, top - [0, 0, 0.1]])
    assert isinstance(hit, Contact) and hit.normal[2] > 0
    # The reported point is on the surface; the centre was a radius off it.
    _, distance, _ = robot_example.trimesh.proximity.closest_point(mesh, hit.position[None])
    assert distance[0] < 0.1 * radius
    assert not scene.is_table_contact(hit.position, hit.normal, 1e-6)
    beside = top + [mesh.extents.max() + 0.05, 0, 0]
    table = robot.probe([beside, beside * [1, 1, 0] + [0, 0, radius]])  # down to the table
    assert isinstance(table, Contact) and scene.is_table_contact(table.position,
                                                                 table.normal, 1e-9)
    np.testing.assert_allclose(table.normal, [0, 0, 1])
    assert robot.touches == 1 and robot.table_touches == 1
    with pytest.raises(robot_example.MoveRefused, match="below the table"):
        robot.probe([beside, beside * [1, 1, 0] - [0, 0, 0.01]])
    with pytest.raises(robot_example.MoveRefused, match="reach cone"):
        robot.probe([top, top + [0.1, 0, 0]])
    assert robot.moves == 2  # refused moves are not carried out


def test_the_example_at_a_table_keeps_every_path_to_the_scene(robot_example, capsys):
    sessions = {}
    results = robot_example.main(["--object", "mug_1", "--seed", "0", "--steps", "6",
                                  "--no-simulator"], sessions=sessions)
    assert set(results) == {"callback", "ask/tell"}
    assert results["callback"] == results["ask/tell"]
    for result in results.values():
        assert result["steps"] == 6 and result["touches"] <= result["object_touches"]
    scene = sessions["callback"].scene
    assert scene.has_table and scene.tip_radius == 0.005 and scene.reach_angle_deg == 60
    for session in sessions.values():
        assert session.scene is scene and session.step_count == 6
        paths = [path for snapshot in session.snapshots for path in snapshot.paths]
        assert paths
        for path in paths:
            scene.check_path(path, 1e-6)  # raises for a path below the table or too steep
        last = session.latest  # the table's touches are misses, never contacts
        assert not any(scene.is_table_contact(point, normal, 1e-3)
                       for point, normal in zip(last.contacts, last.normals))
        assert len(last.noncontacts) >= results["callback"]["table_touches"]
    out = capsys.readouterr().out
    assert "on a table, tip radius 5 mm, reach 60 deg" in out
    assert "ask/tell: " in out
