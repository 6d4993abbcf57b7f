"""The example robot (examples/robot.py): guarded moves by ray casting on a mesh in metres,
driving a session in the callback and the ask/tell styles."""

import pytest


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
    import numpy as np

    from tactile_viz.engine import Contact, NonContact

    _, mesh, _ = robot_example.place("bottle_1", 1)
    robot = robot_example.RayCastingRobot(mesh)
    centre = mesh.bounds.mean(axis=0)
    far = centre + [1.0, 0.0, 0.0]
    hit = robot.probe([far, centre])
    assert isinstance(hit, Contact) and hit.normal @ (far - centre) > 0
    miss = robot.probe([far, far + [0.0, 1.0, 0.0]])
    assert isinstance(miss, NonContact)
    np.testing.assert_allclose(miss.position, far + [0.0, 1.0, 0.0])
