"""ROS 2 bags as recordings and as exports (engine/io/bags.py, engine/io/bag_export.py).

The recordings are written here with rosbags' own writer, as a robot's software would:
Gazebo-style ContactsState messages, and point and normal topics. Each replays to the
estimate of its CSV twin bit for bit.
"""

from pathlib import Path

import numpy as np
import pytest
import trimesh

pytest.importorskip("rosbags")

from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402

from tactile_viz.commands.replay import replay  # noqa: E402
from tactile_viz.engine import Contact, ObjectModel, PriorLibrary  # noqa: E402
from tactile_viz.engine.io.bag_export import MAP_FRAME, TOPICS, export_bag  # noqa: E402
from tactile_viz.engine.io.bags import (  # noqa: E402
    BagError,
    BagTopics,
    is_bag,
    read_bag,
    read_recording,
    typestore,
)
from tactile_viz.engine.io.observation_file import read_observations, write_observations  # noqa: E402
from tactile_viz.engine.session import Session, make_truth  # noqa: E402

MS = 10**6  # nanoseconds


def tiny_library():
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    library = PriorLibrary()
    library.add_arrays(box.vertices, box.faces, "box")
    library.add_arrays(cylinder.vertices, cylinder.faces, "cylinder")
    return library


@pytest.fixture(scope="module")
def trial():
    """Six steps of a sphere (novel) against a box and a cylinder: contacts, misses and
    free-space points; the GPIS surface from step 3."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=3.0)
    truth = ObjectModel.from_arrays(sphere.vertices, sphere.faces, "sphere", longest_side=6.0)
    library = tiny_library()
    session = Session.simulated(make_truth(truth, rng=[0, 0]), library, seed=0)
    session.run(max_steps=6)
    steps = session.recorded_steps()
    assert any(not isinstance(o, Contact) for s in steps for o in s.observations)
    assert sum(len(s.free_space) for s in steps) > 0
    return library, session


class Robot:
    """Messages as a robot's software makes them (rosbags' types)."""

    def __init__(self):
        self.store = typestore()
        self.t = self.store.types

    def header(self, stamp, frame="world"):
        time = self.t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
        return self.t["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def vector(self, values):
        return self.t["geometry_msgs/msg/Vector3"](*map(float, values))

    def point(self, stamp, position, frame="world"):
        return self.t["geometry_msgs/msg/PointStamped"](
            header=self.header(stamp, frame),
            point=self.t["geometry_msgs/msg/Point"](*map(float, position)))

    def normal(self, stamp, normal, frame="world"):
        return self.t["geometry_msgs/msg/Vector3Stamped"](header=self.header(stamp, frame),
                                                          vector=self.vector(normal))

    def contacts_state(self, stamp, contacts, frame="world"):
        zero = self.vector((0, 0, 0))
        wrench = self.t["geometry_msgs/msg/Wrench"](force=zero, torque=zero)
        state = self.t["gazebo_msgs/msg/ContactState"](
            info="", collision1_name="probe::link::collision",
            collision2_name="object::link::collision", wrenches=[wrench] * len(contacts),
            total_wrench=wrench, contact_positions=[self.vector(c.position) for c in contacts],
            contact_normals=[self.vector(c.normal) for c in contacts],
            depths=np.zeros(len(contacts)))
        return self.t["gazebo_msgs/msg/ContactsState"](header=self.header(stamp, frame),
                                                       states=[state])

    def write(self, path, messages, storage=StoragePlugin.MCAP):
        """A rosbag2 folder of ``messages`` ((topic, type, stamp, message), in time order);
        returns its storage file."""
        with Writer(path, version=8, storage_plugin=storage) as writer:
            connections = {}
            for topic, kind, stamp, message in messages:
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, kind, typestore=self.store)
                writer.write(connections[topic], stamp,
                             self.store.serialize_cdr(message, kind))
        return next(p for p in Path(path).iterdir() if p.suffix in (".mcap", ".db3"))


def gazebo_messages(robot, steps):
    """Step k at k s, its touches 1 ms apart: contacts as ContactsState, misses as points."""
    messages = []
    for k, step in enumerate(steps, start=1):
        for j, observation in enumerate(step.observations):
            stamp = k * 10**9 + j * MS
            if isinstance(observation, Contact):
                messages.append(("/contacts", "gazebo_msgs/msg/ContactsState", stamp,
                                 robot.contacts_state(stamp, [observation])))
            else:
                messages.append(("/misses", "geometry_msgs/msg/PointStamped", stamp,
                                 robot.point(stamp, observation.position)))
        for j, point in enumerate(step.free_space):
            stamp = k * 10**9 + (100 + j) * MS
            messages.append(("/free_space", "geometry_msgs/msg/PointStamped", stamp,
                             robot.point(stamp, point)))
    return messages


def point_messages(robot, steps):
    """A /step marker per step, then each contact as a point and a normal of one stamp."""
    messages = []
    for k, step in enumerate(steps, start=1):
        start = k * 10**9
        messages.append(("/step", "std_msgs/msg/UInt32", start,
                         robot.t["std_msgs/msg/UInt32"](data=k)))
        for j, observation in enumerate(step.observations, start=1):
            stamp = start + j * MS
            if isinstance(observation, Contact):
                messages += [("/contacts", "geometry_msgs/msg/PointStamped", stamp,
                              robot.point(stamp, observation.position)),
                             ("/contact_normals", "geometry_msgs/msg/Vector3Stamped", stamp,
                              robot.normal(stamp, observation.normal))]
            else:
                messages.append(("/misses", "geometry_msgs/msg/PointStamped", stamp,
                                 robot.point(stamp, observation.position)))
        for j, point in enumerate(step.free_space, start=500):
            messages.append(("/free_space", "geometry_msgs/msg/PointStamped",
                             start + j * MS, robot.point(start + j * MS, point)))
    return sorted(messages, key=lambda m: m[2])


def assert_same_steps(read, expected):
    assert len(read) == len(expected)
    for got, want in zip(read, expected):
        assert [type(o) for o in got.observations] == [type(o) for o in want.observations]
        for a, b in zip(got.observations, want.observations):
            np.testing.assert_array_equal(a.position, b.position)
            if isinstance(a, Contact):
                np.testing.assert_array_equal(a.normal, b.normal)
        np.testing.assert_array_equal(got.free_space, np.reshape(want.free_space, (-1, 3)))


def assert_same_estimates(first, second):
    assert len(first.snapshots) == len(second.snapshots)
    for a, b in zip(first.snapshots, second.snapshots):
        assert a.map_class == b.map_class and a.novel == b.novel
        np.testing.assert_array_equal(a.map_rotation, b.map_rotation)
        np.testing.assert_array_equal(a.map_translation, b.map_translation)
        np.testing.assert_array_equal([a.class_posterior[k] for k in sorted(a.class_posterior)],
                                      [b.class_posterior[k] for k in sorted(b.class_posterior)])


@pytest.mark.parametrize("style", ["gazebo", "points"])
def test_a_robots_bag_replays_to_the_estimate_of_its_csv_twin(trial, tmp_path, style):
    library, session = trial
    steps = session.recorded_steps()
    twin = write_observations(tmp_path / "twin.csv", steps, units="m")
    robot = Robot()
    if style == "gazebo":
        bag = robot.write(tmp_path / "bag", gazebo_messages(robot, steps))
        topics = BagTopics(step_gap=0.5)
    else:
        bag = robot.write(tmp_path / "bag", point_messages(robot, steps))
        topics = BagTopics()
    from_csv = read_observations(twin, "m")
    for path in (bag, tmp_path / "bag"):  # the storage file and the rosbag2 folder
        assert is_bag(path)
        assert_same_steps(read_recording(path, "m", topics), from_csv)
    replayed_bag, _ = replay(read_bag(bag, "m", topics), library)
    replayed_csv, _ = replay(from_csv, library)
    assert_same_estimates(replayed_bag, replayed_csv)
    assert_same_estimates(replayed_bag, session)


def test_a_bag_is_converted_from_metres_like_a_csv_in_metres(trial, tmp_path):
    steps = trial[1].recorded_steps()
    robot = Robot()
    bag = robot.write(tmp_path / "bag", point_messages(robot, steps), StoragePlugin.SQLITE3)
    assert bag.suffix == ".db3"
    twin = write_observations(tmp_path / "twin.csv", steps, units="m")
    assert_same_steps(read_bag(bag, "mm"), read_observations(twin, "mm"))


def test_touches_of_one_stamp_are_one_step_and_free_points_join_the_next(tmp_path):
    robot = Robot()
    touches = [Contact([1.0, 0, 0], [1, 0, 0]), Contact([0, 1.0, 0], [0, 1, 0])]
    messages = [("/free_space", "geometry_msgs/msg/PointStamped", 10**9 - MS,
                 robot.point(10**9 - MS, [2.0, 0, 0])),
                ("/contacts", "gazebo_msgs/msg/ContactsState", 10**9,
                 robot.contacts_state(10**9, touches)),
                ("/misses", "geometry_msgs/msg/PointStamped", 2 * 10**9,
                 robot.point(2 * 10**9, [3.0, 0, 0]))]
    steps = read_bag(robot.write(tmp_path / "bag", messages))
    assert [len(s.observations) for s in steps] == [2, 1]
    np.testing.assert_array_equal(steps[0].free_space, [[2.0, 0, 0]])
    np.testing.assert_array_equal(steps[1].observations[0].position, [3.0, 0, 0])


def test_an_exported_bag_holds_touches_poses_and_both_meshes(trial, tmp_path):
    library, session = trial
    path = export_bag(session, tmp_path / "run.mcap")
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]  # no temporary left
    found = {}
    with AnyReader([path]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TOPICS
        for connection, stamp, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            found.setdefault(connection.topic, []).append((stamp, message))
    snapshots = session.snapshots
    contacts = sum(isinstance(o, Contact) for s in snapshots for o in s.new_observations)
    assert len(found["/contacts"]) == len(found["/contact_normals"]) == contacts
    poses = found["/tactile/map_pose"]
    assert [stamp // 10**9 for stamp, _ in poses] == [s.step for s in snapshots]
    for (_, pose), snapshot in zip(poses, snapshots):
        position = pose.pose.position
        np.testing.assert_array_equal([position.x, position.y, position.z],
                                      snapshot.map_translation)
    shapes = found["/tactile/map_shape"]
    assert shapes[0][1].header.frame_id == MAP_FRAME and shapes[0][1].frame_locked
    shown = library[snapshots[0].map_class].mesh
    assert shapes[0][1].type == 11 and len(shapes[0][1].points) == 3 * len(shown.faces)
    surfaces = found["/tactile/reconstruction"]
    assert len(surfaces) == len(snapshots)
    last = snapshots[-1]
    assert last.gpis_faces is not None and surfaces[-1][1].action == 0
    assert len(surfaces[-1][1].points) == 3 * len(last.gpis_faces)
    cloud = found["/tactile/contact_cloud"][-1][1]
    assert cloud.width == len(last.contacts)
    estimate = found["/tactile/estimate"][-1][1].data
    assert '"novel": true' in estimate and last.map_class in estimate
    # The exported bag replays with the default topics to the session's estimate.
    replayed, _ = replay(read_bag(path), library)
    assert_same_estimates(replayed, session)


def test_an_export_in_millimetres_is_written_in_metres(trial, tmp_path):
    path = export_bag(trial[1], tmp_path / "run.mcap", units="mm")
    steps = read_bag(path, "m")
    first = trial[1].recorded_steps()[0].observations[0].position
    np.testing.assert_allclose(steps[0].observations[0].position, np.asarray(first) / 1000)


# ------------------------------------------------------------------------- bad bags
def one_contact(robot, stamp=10**9, position=(1.0, 0, 0), frame="world"):
    return ("/contacts", "geometry_msgs/msg/PointStamped", stamp,
            robot.point(stamp, position, frame))


def one_normal(robot, stamp=10**9, frame="world"):
    return ("/contact_normals", "geometry_msgs/msg/Vector3Stamped", stamp,
            robot.normal(stamp, (1.0, 0, 0), frame))


def bad_bags(robot, folder):
    """``{fault: (bag, message pattern)}``, one bag per fault."""
    text = robot.t["std_msgs/msg/String"](data="hello")
    cases = {
        "missing topic": ([("/chatter", "std_msgs/msg/String", 1, text)],
                          r"no contacts topic /contacts; the bag has /chatter "
                          r"\(std_msgs/msg/String\)"),
        "unknown type": ([("/contacts", "std_msgs/msg/String", 1, text)],
                         r"/contacts has the unknown message type std_msgs/msg/String"),
        "frames": ([one_contact(robot), one_normal(robot, frame="base_link")],
                   r"several frames \('base_link', 'world'\)"),
        "nan": ([one_contact(robot, position=(np.nan, 0, 0)), one_normal(robot)],
                r"/contacts at 1\.000000000 s: contact position is not finite"),
        "no normal": ([one_contact(robot), one_normal(robot, stamp=2 * 10**9)],
                      r"has no normal with its stamp on /contact_normals"),
        "empty": ([], r"the bag is empty"),
    }
    bags = {}
    for name, (messages, pattern) in cases.items():
        bags[name] = (robot.write(folder / name.replace(" ", "_"), messages), pattern)
    good = robot.write(folder / "good", [one_contact(robot), one_normal(robot)])
    truncated = folder / "truncated.mcap"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    bags["truncated"] = (truncated, r"cannot read the bag, truncated or not a ROS 2 bag")
    return bags


def test_each_bad_bag_is_one_error_naming_the_file_and_the_fault(tmp_path):
    for name, (path, pattern) in bad_bags(Robot(), tmp_path).items():
        with pytest.raises(BagError, match=pattern) as caught:
            read_bag(path)
        assert str(path) in str(caught.value) and "\n" not in str(caught.value), name


def test_the_frame_and_named_topics_are_checked(tmp_path):
    robot = Robot()
    bag = robot.write(tmp_path / "bag", [one_contact(robot), one_normal(robot)])
    assert len(read_bag(bag, topics=BagTopics(frame="world"))) == 1
    with pytest.raises(BagError, match=r"in the frame\(s\) 'world', not 'map'"):
        read_bag(bag, topics=BagTopics(frame="map"))
    with pytest.raises(BagError, match=r"no misses topic /probe/misses; the bag has "
                                       r"/contact_normals .*, /contacts"):
        read_bag(bag, topics=BagTopics(misses="/probe/misses"))


def test_a_failed_export_leaves_the_old_bag_and_no_temporary(trial, tmp_path, monkeypatch):
    import tactile_viz.engine.io.bag_export as bag_export

    path = tmp_path / "run.mcap"
    path.write_bytes(b"old")

    def broken(*args):
        raise OSError("disk full")

    monkeypatch.setattr(bag_export, "_estimate", broken)
    with pytest.raises(BagError, match=r"run.mcap: cannot write the bag \(disk full\)"):
        export_bag(trial[1], path)
    assert path.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["run.mcap"]
    with pytest.raises(BagError, match="cannot write the bag"):
        export_bag(trial[1], tmp_path / "missing" / "run.mcap")


def test_export_session_writes_the_bag_beside_the_files(trial, tmp_path):
    from tactile_viz.engine.io.export import export_session

    written = export_session(trial[1], tmp_path, bag=True)
    assert tmp_path / "session.mcap" in written
    assert len(read_bag(tmp_path / "session.mcap")) == len(trial[1].snapshots)


def test_the_one_contacts_topic_of_a_bag_is_used_and_named(trial, tmp_path):
    """A bag whose only ContactsState topic is not /contacts: nothing else it could mean."""
    from tactile_viz.engine.errors import BagWarning

    steps = trial[1].recorded_steps()
    robot = Robot()
    messages = [(("/tactile/contacts",) + m[1:]) if m[0] == "/contacts" else m
                for m in gazebo_messages(robot, steps)]
    bag = robot.write(tmp_path / "bag", messages)
    with pytest.warns(BagWarning, match="using /tactile/contacts"):
        read = read_recording(bag, "m", BagTopics(step_gap=0.5))
    assert_same_steps(read, read_recording(robot.write(tmp_path / "plain", gazebo_messages(
        robot, steps)), "m", BagTopics(step_gap=0.5)))
