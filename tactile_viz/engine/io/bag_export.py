"""A session as a ROS 2 bag (one MCAP file) that RViz and Foxglove play step by step.

Step ``k`` (1, 2, ...) is stamped ``k`` seconds (bag time and header stamps alike), in the
frame ``world``, lengths in metres (REP 103; a scene without a named unit is written as it
is). Topics:

- ``/step`` (``std_msgs/msg/UInt32``, the step number, at ``k`` s), then the step's touches
  in their order, ``k`` s plus one microsecond each: ``/contacts``
  (``geometry_msgs/msg/PointStamped``) with ``/contact_normals``
  (``geometry_msgs/msg/Vector3Stamped``, the same stamp), ``/misses`` and ``/free_space``
  (``PointStamped``): what :func:`~tactile_viz.engine.io.bags.read_bag` reads with its default
  topics, so the bag replays to the same estimate;
- at ``k + 0.5`` s, for the viewers: ``/tactile/contact_cloud`` and ``/tactile/miss_cloud``
  (``sensor_msgs/msg/PointCloud2``, every contact, with its normal, and every miss so far),
  ``/tactile/map_pose`` (``geometry_msgs/msg/PoseStamped``, the MAP pose: the prior's
  object frame in the world) and the same as ``/tf`` (``world`` to ``tactile_map``),
  ``/tactile/estimate`` (``std_msgs/msg/String``, JSON: step, map_class, class_posterior,
  novel, decided, log_evidence, log_threshold, units), ``/tactile/map_shape``
  (``visualization_msgs/msg/Marker``, a triangle list in ``tactile_map``, frame-locked:
  written when the MAP class changes, moved by ``/tf``) and ``/tactile/reconstruction``
  (a triangle list in ``world``, the GPIS surface, each step the object is judged novel;
  deleted when it is not).
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..explore.observations import Contact
from ..shape.meshes import UNITS
from .bags import POINT, VECTOR, BagError, _rosbags, typestore
from .files import write_atomic

WORLD, MAP_FRAME = "world", "tactile_map"
SECOND, OUTPUTS = 10**9, 5 * 10**8  # a step's span; its outputs' offset, ns
TOPICS = {"/step": "std_msgs/msg/UInt32", "/contacts": POINT, "/contact_normals": VECTOR,
          "/misses": POINT, "/free_space": POINT,
          "/tactile/contact_cloud": "sensor_msgs/msg/PointCloud2",
          "/tactile/miss_cloud": "sensor_msgs/msg/PointCloud2",
          "/tactile/map_pose": "geometry_msgs/msg/PoseStamped", "/tf": "tf2_msgs/msg/TFMessage",
          "/tactile/estimate": "std_msgs/msg/String",
          "/tactile/map_shape": "visualization_msgs/msg/Marker",
          "/tactile/reconstruction": "visualization_msgs/msg/Marker"}
COLOURS = {"/tactile/map_shape": (0.55, 0.6, 0.7, 0.8), "/tactile/reconstruction":
           (0.9, 0.55, 0.2, 0.8)}


class _Messages:
    """Builds the messages of :data:`TOPICS` (rosbags' types) and writes them serialized."""

    def __init__(self, writer, factor):
        self.store, self.writer, self.factor = typestore(), writer, factor
        self.types = self.store.types
        self.connections = {topic: writer.add_connection(topic, kind, typestore=self.store)
                            for topic, kind in TOPICS.items()}

    def write(self, topic, stamp, message):
        data = self.store.serialize_cdr(message, TOPICS[topic])
        self.writer.write(self.connections[topic], stamp, data)

    def header(self, stamp, frame=WORLD):
        time = self.types["builtin_interfaces/msg/Time"](sec=stamp // SECOND,
                                                         nanosec=stamp % SECOND)
        return self.types["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def length(self, values):
        """Scene lengths in metres (as Python floats: bit for bit when the scene is)."""
        return [self.factor * float(v) for v in values] if self.factor != 1.0 else [
            float(v) for v in values]

    def point(self, stamp, position):
        x, y, z = self.length(position)
        return self.types[POINT](header=self.header(stamp),
                                 point=self.types["geometry_msgs/msg/Point"](x=x, y=y, z=z))

    def vector(self, stamp, normal):
        x, y, z = (float(v) for v in normal)
        return self.types[VECTOR](header=self.header(stamp),
                                  vector=self.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z))

    def cloud(self, stamp, columns):
        """A PointCloud2 of float32 fields, ``columns`` {name: (n,) values}."""
        names = list(columns)
        table = np.column_stack([columns[n] for n in names]).astype("<f4")
        field = self.types["sensor_msgs/msg/PointField"]
        fields = [field(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(names)]
        return self.types["sensor_msgs/msg/PointCloud2"](
            header=self.header(stamp), height=1, width=len(table), fields=fields,
            is_bigendian=False, point_step=4 * len(names), row_step=4 * len(names) * len(table),
            data=np.frombuffer(table.tobytes(), dtype=np.uint8), is_dense=True)

    def pose(self, rotation, translation):
        x, y, z, w = Rotation.from_matrix(rotation).as_quat()
        t = self.types
        return (t["geometry_msgs/msg/Point"](*self.length(translation)),
                t["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z),
                                                  w=float(w)))

    def marker(self, stamp, topic, frame, vertices=None, faces=None):
        """A triangle-list marker (``vertices`` None: its deletion)."""
        t = self.types
        action = 0 if vertices is not None else 2  # ADD, DELETE
        points = []
        if vertices is not None:
            corners = np.asarray(vertices, dtype=float)[np.asarray(faces).reshape(-1)]
            corners = corners * self.factor if self.factor != 1.0 else corners
            make = t["geometry_msgs/msg/Point"]
            points = [make(x=float(a), y=float(b), z=float(c)) for a, b, c in corners]
        vector = t["geometry_msgs/msg/Vector3"]
        empty = np.zeros(0, dtype=np.uint8)
        return t["visualization_msgs/msg/Marker"](
            header=self.header(stamp, frame), ns=topic.rsplit("/", 1)[-1], id=0, type=11,
            action=action, pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
            scale=vector(x=1.0, y=1.0, z=1.0),
            color=t["std_msgs/msg/ColorRGBA"](*COLOURS[topic]),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
            frame_locked=frame != WORLD, points=points, colors=[], texture_resource="",
            texture=t["sensor_msgs/msg/CompressedImage"](header=self.header(stamp, frame),
                                                          format="", data=empty),
            uv_coordinates=[], text="", mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=empty),
            mesh_use_embedded_materials=False)


def _touches(out, step, start):
    """The step's touches from ``start``, one microsecond apart, on the topics read back."""
    stamp = start
    for observation in step.observations:
        stamp += 1000
        if isinstance(observation, Contact):
            out.write("/contacts", stamp, out.point(stamp, observation.position))
            out.write("/contact_normals", stamp, out.vector(stamp, observation.normal))
        else:
            out.write("/misses", stamp, out.point(stamp, observation.position))
    for point in np.reshape(step.free_space, (-1, 3)):
        stamp += 1000
        out.write("/free_space", stamp, out.point(stamp, point))


def _estimate(out, session, snapshot, stamp, shown, units):
    """The viewers' topics of one snapshot; returns the MAP class now shown."""
    t = out.types
    factor = out.factor
    contacts = np.reshape(snapshot.contacts, (-1, 3)) * factor
    normals = np.reshape(snapshot.normals, (-1, 3))
    out.write("/tactile/contact_cloud", stamp, out.cloud(stamp, {
        "x": contacts[:, 0], "y": contacts[:, 1], "z": contacts[:, 2], "normal_x": normals[:, 0],
        "normal_y": normals[:, 1], "normal_z": normals[:, 2]}))
    misses = np.reshape(snapshot.noncontacts, (-1, 3)) * factor
    out.write("/tactile/miss_cloud", stamp, out.cloud(stamp, {
        "x": misses[:, 0], "y": misses[:, 1], "z": misses[:, 2]}))
    position, orientation = out.pose(snapshot.map_rotation, snapshot.map_translation)
    out.write("/tactile/map_pose", stamp, t["geometry_msgs/msg/PoseStamped"](
        header=out.header(stamp), pose=t["geometry_msgs/msg/Pose"](position=position,
                                                                    orientation=orientation)))
    vector = t["geometry_msgs/msg/Vector3"](x=position.x, y=position.y, z=position.z)
    out.write("/tf", stamp, t["tf2_msgs/msg/TFMessage"](transforms=[
        t["geometry_msgs/msg/TransformStamped"](
            header=out.header(stamp), child_frame_id=MAP_FRAME,
            transform=t["geometry_msgs/msg/Transform"](translation=vector,
                                                       rotation=orientation))]))
    record = {"step": snapshot.step, "map_class": snapshot.map_class,
              "class_posterior": {k: float(p) for k, p in snapshot.class_posterior.items()},
              "novel": bool(snapshot.novel), "decided": bool(snapshot.decided),
              "log_evidence": float(snapshot.log_evidence),
              "log_threshold": float(snapshot.log_threshold),
              "units": "m" if units is not None else None}
    out.write("/tactile/estimate", stamp, t["std_msgs/msg/String"](data=json.dumps(record)))
    if snapshot.map_class != shown:
        mesh = session.library[snapshot.map_class].mesh
        out.write("/tactile/map_shape", stamp, out.marker(stamp, "/tactile/map_shape", MAP_FRAME,
                                                          mesh.vertices, mesh.faces))
    faces = snapshot.gpis_faces
    if faces is not None and len(faces):
        out.write("/tactile/reconstruction", stamp, out.marker(
            stamp, "/tactile/reconstruction", WORLD, snapshot.gpis_vertices, faces))
    else:
        out.write("/tactile/reconstruction", stamp, out.marker(stamp, "/tactile/reconstruction",
                                                               WORLD))
    return snapshot.map_class


def export_bag(session, path, units: str | None = None) -> Path:
    """Write every step of ``session`` to the MCAP bag ``path`` (see the module docstring).

    Parameters
    ----------
    session : Session
        With at least one step.
    path : path-like
        The ``.mcap`` file, replaced whole (or left as it was on failure).
    units : str, optional
        The scene's length unit: converted to metres (None: written as they are).

    Returns
    -------
    Path
    """
    from ..session import SessionError

    if session.latest is None:
        raise SessionError("nothing to export: the session has no step yet")
    _rosbags(path)
    from rosbags.rosbag2 import StoragePlugin, Writer

    path = Path(path)
    factor = UNITS[units] if units is not None else 1.0
    folder = None
    try:
        folder = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
        with Writer(folder / "bag", version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            out, shown = _Messages(writer, factor), None
            for step, snapshot in zip(session.recorded_steps(), session.snapshots):
                start = snapshot.step * SECOND
                out.write("/step", start, out.types["std_msgs/msg/UInt32"](data=snapshot.step))
                _touches(out, step, start)
                shown = _estimate(out, session, snapshot, start + OUTPUTS, shown, units)
        data = next((folder / "bag").glob("*.mcap")).read_bytes()
        return write_atomic(path, data)
    except OSError as error:
        raise BagError(path, f"cannot write the bag ({error})") from error
    finally:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)


__all__ = ["MAP_FRAME", "TOPICS", "WORLD", "export_bag"]
