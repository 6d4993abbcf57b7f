"""``replay --observations BAG`` and ``--export-bag`` on the command line: a bad bag is one
line on stderr and exit status 2, with nothing written."""

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

pytest.importorskip("rosbags")

from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402

from tactile_viz.__main__ import main  # noqa: E402
from tactile_viz.engine.io.bags import typestore  # noqa: E402


@pytest.fixture(scope="module")
def priors(tmp_path_factory):
    """Two small prior meshes (metres) as --prior-file options."""
    folder = tmp_path_factory.mktemp("priors")
    trimesh.creation.box(extents=(0.06, 0.03, 0.02)).export(folder / "box.stl")
    trimesh.creation.cylinder(radius=0.015, height=0.06).export(folder / "can.stl")
    return ["--prior-file", str(folder / "box.stl:m"), str(folder / "can.stl:m")]


def write_bag(folder, messages):
    """A rosbag2 folder of (topic, type, stamp, message); returns its .mcap file."""
    store = typestore()
    with Writer(folder, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {}
        for topic, kind, stamp, message in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, kind, typestore=store)
            writer.write(connections[topic], stamp, store.serialize_cdr(message, kind))
    return next(Path(folder).glob("*.mcap"))


def stamped(kind, stamp, values, frame="world"):
    t = typestore().types
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9),
        frame_id=frame)
    if kind == "point":
        return ("/contacts", "geometry_msgs/msg/PointStamped", stamp,
                t["geometry_msgs/msg/PointStamped"](
                    header=header, point=t["geometry_msgs/msg/Point"](*values)))
    return ("/contact_normals", "geometry_msgs/msg/Vector3Stamped", stamp,
            t["geometry_msgs/msg/Vector3Stamped"](
                header=header, vector=t["geometry_msgs/msg/Vector3"](*values)))


def touches(count, frame="world", bad=None):
    """``count`` contacts on a 3 cm sphere, one stamp each, with their normals."""
    messages = []
    rng = np.random.default_rng(0)
    for k in range(1, count + 1):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        position = 0.03 * normal if k != bad else np.array([np.nan, 0, 0])
        messages += [stamped("point", k * 10**9, position.tolist()),
                     stamped("normal", k * 10**9, normal.tolist(), frame if k == 2 else "world")]
    return messages


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    t = typestore().types
    text = t["std_msgs/msg/String"](data="hi")
    good = write_bag(folder / "good", touches(4))
    made = {name: write_bag(folder / name, messages) for name, messages in {
        "missing_topic": [("/chatter", "std_msgs/msg/String", 1, text)],
        "unknown_type": [("/contacts", "std_msgs/msg/String", 1, text)],
        "frames": touches(3, frame="base_link"),
        "nan": touches(3, bad=2),
        "empty": []}.items()}
    truncated = folder / "truncated.mcap"
    truncated.write_bytes(good.read_bytes()[:-200])
    made["truncated"] = truncated
    return good, made


FAULTS = {"missing_topic": "no contacts topic /contacts; the bag has /chatter",
          "unknown_type": "unknown message type std_msgs/msg/String",
          "frames": "several frames ('base_link', 'world')",
          "nan": "contact position is not finite", "empty": "the bag is empty",
          "truncated": "cannot read the bag, truncated"}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_a_bad_bag_is_one_line_exit_2_and_nothing_written(bags, priors, tmp_path, capsys,
                                                          fault):
    path = bags[1][fault]
    out = tmp_path / "out"
    out.mkdir()
    status = main(["--log-file", "", "replay", "--observations", str(path), *priors,
                   "--json", str(out / "r.json"), "--export", str(out / "export"),
                   "--export-bag", str(out / "r.mcap"), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert len(err.splitlines()) == 1 and FAULTS[fault] in err and str(path) in err
    assert list(out.iterdir()) == []


def test_bag_options_need_a_bag_and_one_grouping(bags, priors, tmp_path, capsys):
    csv = tmp_path / "touches.csv"
    csv.write_text("kind,x,y,z,nx,ny,nz\ncontact,0.03,0,0,1,0,0\n")
    assert main(["replay", "--observations", str(csv), *priors, "--step-gap", "1"]) == 2
    assert "--step-gap is for a bag" in capsys.readouterr().err
    assert main(["replay", "--observations", str(bags[0]), *priors, "--step-gap", "1",
                 "--step-topic", "/s"]) == 2
    assert "give one of them" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        main(["replay", "--observations", str(bags[0]), *priors,
              "--export-bag", str(tmp_path / "x.bag")])
    assert stop.value.code == 2 and "must be an .mcap file" in capsys.readouterr().err


def test_replay_of_a_bag_folder_exports_a_bag_that_replays_alike(bags, priors, tmp_path):
    folder = bags[0].parent
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    assert main(["--log-file", "", "replay", "--observations", str(folder), *priors,
                 "--json", str(first), "--export-bag", str(tmp_path / "out.mcap"),
                 "--no-progress"]) == 0
    assert main(["--log-file", "", "replay", "--observations", str(tmp_path / "out.mcap"),
                 *priors, "--json", str(second), "--no-progress"]) == 0
    one, two = json.loads(first.read_text()), json.loads(second.read_text())
    assert one["units"] == two["units"] == "m" and len(one["steps"]) == 4
    for a, b in zip(one["steps"], two["steps"]):
        assert a["map_class"] == b["map_class"]
        np.testing.assert_array_equal(a["map_translation"], b["map_translation"])
        np.testing.assert_array_equal(a["map_rotation"], b["map_rotation"])


def test_the_app_steps_through_a_bag_as_replay_does(bags, priors, tmp_path, capsys):
    import importlib.util

    from tactile_viz.app.scene import Scene
    from tactile_viz.commands.inputs import bag_topics
    from tactile_viz.engine import PriorLibrary
    from tactile_viz.engine.shape.objects import ObjectModel

    spec = importlib.util.spec_from_file_location(
        "app_launcher", Path(__file__).resolve().parents[2] / "app.py")
    launcher = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(launcher)
    folder = bags[0].parent
    args = launcher.parse_args(["--observations", str(folder), "--bag-frame", "world",
                                "--log-file", ""])
    files = [Path(text.split(":")[0]) for text in priors[1:]]
    library = PriorLibrary([ObjectModel.from_file(path, name=path.stem) for path in files])
    scene = Scene(seed=0, library=library)
    assert scene.open_observations(args.observations, bag_topics(args)) == 4
    csv = tmp_path / "touches.csv"
    csv.write_text("kind,x,y,z,nx,ny,nz\ncontact,0.03,0,0,1,0,0\n")
    with pytest.raises(SystemExit) as stop:
        launcher.parse_args(["--observations", str(csv), "--step-gap", "1", "--log-file", ""])
    assert stop.value.code == 2 and "--step-gap is for a bag" in capsys.readouterr().err
