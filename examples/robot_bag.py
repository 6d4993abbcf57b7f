"""A robot's trial logged to a ROS 2 bag, replayed from the bag, and exported for the viewers.

The robot of examples/robot.py (ray casting on a mug in metres) drives a session move by
move; its software logs every completed step to a rosbag2 folder with rosbags, as a ROS
node's recorder would: Gazebo-style ``gazebo_msgs/msg/ContactsState`` contacts (or
``PointStamped`` points with ``Vector3Stamped`` normals), ``PointStamped`` misses and
free-space points, a ``/step`` marker per step, frame ``world``, metres. The bag is then
read back and replayed: the estimate is the live one, bit for bit. The replay is exported
as one MCAP file to open in Foxglove or RViz (docs/robots.md).

    python examples/robot_bag.py                       # mug_1, 20 steps, Gazebo-style
    python examples/robot_bag.py --style points --steps 30 --out run
"""

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from robot import RayCastingRobot, metric_library, place  # noqa: E402

from tactile_viz.commands.replay import replay  # noqa: E402
from tactile_viz.engine import Contact  # noqa: E402
from tactile_viz.engine.io.bag_export import export_bag  # noqa: E402
from tactile_viz.engine.io.bags import read_bag, typestore  # noqa: E402
from tactile_viz.engine.session import Session  # noqa: E402

MS = 10**6  # nanoseconds


class BagLog:
    """A robot's log of its touches: one rosbag2 folder (MCAP), written as steps end."""

    def __init__(self, folder, style):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.store, self.style = typestore(), style
        self.t = self.store.types
        self.writer = Writer(folder, version=8, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections = {}

    def write(self, topic, kind, stamp, message):
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, kind,
                                                                 typestore=self.store)
        self.writer.write(self.connections[topic], stamp, self.store.serialize_cdr(message, kind))

    def header(self, stamp):
        return self.t["std_msgs/msg/Header"](stamp=self.t["builtin_interfaces/msg/Time"](
            sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="world")

    def vector(self, values, kind="geometry_msgs/msg/Vector3"):
        return self.t[kind](*map(float, values))

    def point(self, topic, stamp, position):
        self.write(topic, "geometry_msgs/msg/PointStamped", stamp,
                   self.t["geometry_msgs/msg/PointStamped"](
                       header=self.header(stamp),
                       point=self.vector(position, "geometry_msgs/msg/Point")))

    def contact(self, stamp, contact):
        if self.style == "points":
            self.point("/contacts", stamp, contact.position)
            self.write("/contact_normals", "geometry_msgs/msg/Vector3Stamped", stamp,
                       self.t["geometry_msgs/msg/Vector3Stamped"](
                           header=self.header(stamp), vector=self.vector(contact.normal)))
            return
        zero = self.vector((0, 0, 0))
        wrench = self.t["geometry_msgs/msg/Wrench"](force=zero, torque=zero)
        state = self.t["gazebo_msgs/msg/ContactState"](
            info="", collision1_name="probe", collision2_name="object", wrenches=[wrench],
            total_wrench=wrench, contact_positions=[self.vector(contact.position)],
            contact_normals=[self.vector(contact.normal)], depths=np.zeros(1))
        self.write("/contacts", "gazebo_msgs/msg/ContactsState", stamp,
                   self.t["gazebo_msgs/msg/ContactsState"](header=self.header(stamp),
                                                           states=[state]))

    def step(self, number, observations, free_space):
        """Step ``number`` at ``number`` seconds, its touches a millisecond apart."""
        start = number * 10**9
        self.write("/step", "std_msgs/msg/UInt32", start, self.t["std_msgs/msg/UInt32"](
            data=number))
        for j, observation in enumerate(observations, start=1):
            if isinstance(observation, Contact):
                self.contact(start + j * MS, observation)
            else:
                self.point("/misses", start + j * MS, observation.position)
        for j, point in enumerate(free_space, start=500):
            self.point("/free_space", start + j * MS, point)

    def close(self):
        self.writer.close()


def record(library, robot, seed, steps, log):
    """Ask/tell with the robot; every completed step goes to the log."""
    session = Session(library, seed=seed)
    while session.step_count < steps and not session.terminated:
        snapshot = session.observe(robot.probe(session.propose().path))
        if snapshot is not None:
            recorded = session.recorded_steps()[-1]
            log.step(snapshot.step, recorded.observations, recorded.free_space)
    log.close()
    return session


def same_estimates(first, second):
    """True when every step has the same MAP class and pose, bit for bit."""
    return len(first.snapshots) == len(second.snapshots) and all(
        a.map_class == b.map_class and np.array_equal(a.map_rotation, b.map_rotation)
        and np.array_equal(a.map_translation, b.map_translation)
        for a, b in zip(first.snapshots, second.snapshots))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="mug_1")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--style", choices=["gazebo", "points"], default="gazebo")
    parser.add_argument("--out", default="robot_bag", help="folder for the bags (replaced)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    library = metric_library()
    _, mesh, _ = place(args.object, args.seed)
    live = record(library, RayCastingRobot(mesh), args.seed, args.steps,
                  BagLog(out / "recording", args.style))
    steps = read_bag(out / "recording")  # metres, as the library
    replayed, _ = replay(steps, library, seed=args.seed)
    exported = export_bag(replayed, out / "replay.mcap", units="m")
    result = {"steps": live.step_count, "map_class": replayed.latest.map_class,
              "novel": bool(replayed.latest.novel), "same": same_estimates(live, replayed),
              "recording": str(out / "recording"), "export": str(exported)}
    print(f"recorded {result['steps']} steps to {result['recording']}; replayed from the bag: "
          f"{result['map_class']} ({'novel' if result['novel'] else 'known'}), "
          f"{'the same' if result['same'] else 'NOT the same'} estimate as live; "
          f"for Foxglove/RViz: {result['export']}")
    return result


if __name__ == "__main__":
    main()
