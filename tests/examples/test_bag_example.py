"""The bag example (examples/robot_bag.py): a robot's trial logged to a ROS 2 bag replays
to the live estimate, and the replay's export opens with the bag library."""

from pathlib import Path

import pytest

pytest.importorskip("rosbags")


@pytest.fixture(scope="module")
def bag_example(load_example):
    return load_example("robot_bag.py", "robot_bag_example")


@pytest.mark.slow
@pytest.mark.parametrize("style", ["gazebo", "points"])
def test_a_logged_trial_replays_from_its_bag_to_the_live_estimate(bag_example, tmp_path,
                                                                  style, capsys):
    from rosbags.highlevel import AnyReader

    result = bag_example.main(["--steps", "6", "--style", style, "--out", str(tmp_path / "o")])
    assert result["steps"] == 6 and result["same"]
    assert "the same estimate as live" in capsys.readouterr().out
    with AnyReader([Path(result["recording"])]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
    assert types["/contacts"] == ("gazebo_msgs/msg/ContactsState" if style == "gazebo"
                                  else "geometry_msgs/msg/PointStamped")
    with AnyReader([Path(result["export"])]) as reader:
        poses = [c for c in reader.connections if c.topic == "/tactile/map_pose"]
        assert sum(1 for _ in reader.messages(poses)) == 6
