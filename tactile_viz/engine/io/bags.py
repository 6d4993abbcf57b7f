"""Recorded touches from a ROS 2 bag (MCAP or sqlite3), read with ``rosbags`` (pure Python).

A bag gives the same :class:`~tactile_viz.engine.io.observation_file.RecordedStep` list as the
CSV recording, so that everything after reading is one code path. The topics (each
optional one used only when present, unless named):

- contacts (default ``/contacts``): ``gazebo_msgs/msg/ContactsState`` (every position of
  every state, with its normal, as Gazebo's contact sensor publishes them) or
  ``geometry_msgs/msg/PointStamped``, whose normals come from the normals topic;
- normals (default ``/contact_normals``): ``geometry_msgs/msg/Vector3Stamped``, matched to
  the contact points by header time stamp (in order, for contacts sharing a stamp);
- misses (default ``/misses``, optional): ``PointStamped``, the ends of paths in free space
  (non-contacts);
- free space (default ``/free_space``, optional): ``PointStamped``, points passed through
  without touching (the CSV's ``free`` rows);
- steps (default ``/step``, optional): any type; each message starts a step at its header
  stamp (its bag time when it has no header).

Observations are ordered by header stamp. Steps: by the step topic when present; else, with
``step_gap``, a new step starts where consecutive stamps are more than ``step_gap`` seconds
apart; else observations sharing a stamp are one step (a ``ContactsState``'s contacts).
Free-space points join the step of the next observation when theirs has none. Every
message must be in one frame; positions are in metres (REP 103) and converted to the
scene's unit.
"""

from __future__ import annotations

import bisect
import functools
import importlib.util
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BagWarning, ObservationError
from ..explore.observations import Contact, NonContact
from ..shape.meshes import UNITS
from .observation_file import (
    SPAN_CONTACTS,
    ObservationFileError,
    RecordedStep,
    read_observations,
    recording_span,
    recording_warning,
)

BAG_UNITS = "m"  # REP 103
BAG_SUFFIXES = (".mcap", ".db3")
CONTACTS_STATE = "gazebo_msgs/msg/ContactsState"
POINT = "geometry_msgs/msg/PointStamped"
VECTOR = "geometry_msgs/msg/Vector3Stamped"
DEFAULT_TOPICS = {"contacts": "/contacts", "normals": "/contact_normals", "misses": "/misses",
                  "free": "/free_space", "steps": "/step"}
# gazebo_msgs is not in rosbags' stores: its two contact messages, as gazebo_ros defines them.
GAZEBO_MSGS = {
    "gazebo_msgs/msg/ContactState": (
        "string info\nstring collision1_name\nstring collision2_name\n"
        "geometry_msgs/Wrench[] wrenches\ngeometry_msgs/Wrench total_wrench\n"
        "geometry_msgs/Vector3[] contact_positions\ngeometry_msgs/Vector3[] contact_normals\n"
        "float64[] depths\n"),
    "gazebo_msgs/msg/ContactsState": (
        "std_msgs/Header header\ngazebo_msgs/ContactState[] states\n"),
}


class BagError(ObservationFileError):
    """A bag cannot be read as a recording: names the file and the fault."""

    def __init__(self, path, fault):
        super().__init__(path, None, fault)


@dataclass(frozen=True)
class BagTopics:
    """Where a bag's touches are and how they form steps (None: the default).

    Attributes
    ----------
    contacts, normals, misses, free, steps : str or None
        Topic names (see the module's docstring); a named optional topic must exist.
    step_gap : float or None
        Seconds between stamps that start a new step (instead of the step topic).
    frame : str or None
        The frame every message must be in (None: any one frame).
    """

    contacts: str | None = None
    normals: str | None = None
    misses: str | None = None
    free: str | None = None
    steps: str | None = None
    step_gap: float | None = None
    frame: str | None = None


def is_bag(path) -> bool:
    """True for an ``.mcap`` or ``.db3`` file or a rosbag2 folder (with metadata.yaml)."""
    path = Path(path)
    return path.suffix.lower() in BAG_SUFFIXES or (path / "metadata.yaml").is_file()


def _rosbags(path):
    if importlib.util.find_spec("rosbags") is None:
        raise BagError(path, "reading or writing a ROS 2 bag needs rosbags: "
                             "pip install rosbags")


@functools.cache
def typestore():
    """rosbags' ROS 2 Humble types plus gazebo_msgs' ContactState and ContactsState."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for name, text in GAZEBO_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def stamp_text(nanoseconds):
    """A time stamp in seconds, exactly: ``12.000000345 s``."""
    return f"{nanoseconds // 10**9}.{nanoseconds % 10**9:09d} s"


def _stamp(message, logged):
    header = getattr(message, "header", None)
    if header is None:
        return logged
    return int(header.stamp.sec) * 10**9 + int(header.stamp.nanosec)


def _read(path, topics):
    """``(types, messages)``: every topic's type, and the decoded messages of the topics
    :func:`_roles` picks, as ``{topic: [(stamp, message), ...]}`` in bag order."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    try:
        with AnyReader([Path(path)], default_typestore=typestore()) as reader:
            types = {c.topic: c.msgtype for c in reader.connections}
            roles = _roles(path, types, topics)
            wanted = [c for c in reader.connections if c.topic in roles.values()]
            messages = {topic: [] for topic in roles.values() if topic}
            for connection, logged, raw in reader.messages(wanted) if wanted else ():
                message = reader.deserialize(raw, connection.msgtype)
                messages[connection.topic].append((_stamp(message, logged), message))
    except (AnyReaderError, ReaderError, SerdeError, TypesysError, OSError, EOFError,
            IndexError, KeyError, UnicodeDecodeError, AssertionError) as error:
        raise BagError(path, f"cannot read the bag, truncated or not a ROS 2 bag "
                             f"({type(error).__name__}: {error})") from None
    return roles, messages


def _listing(types):
    if not types:
        return "the bag is empty (no topic)"
    return "the bag has " + ", ".join(f"{t} ({m})" for t, m in sorted(types.items()))


def _roles(path, types, topics):
    """``{role: topic or None}`` of the bag's topics; a missing or mistyped one is an error
    listing the topics present."""
    if not types:
        raise BagError(path, "the bag is empty (no topic, no message)")

    def pick(role, allowed, required=False):
        given = getattr(topics, role)
        name = given or DEFAULT_TOPICS[role]
        alone = [topic for topic, kind in types.items() if kind == CONTACTS_STATE]
        if name not in types and given is None and role == "contacts" and len(alone) == 1:
            # Nothing else it could mean: the bag's one topic of a contact type.
            warnings.warn(f"{Path(path).name}: no {role} topic {name}; using {alone[0]} "
                          f"({types[alone[0]]}), the bag's one {role} topic "
                          f"(--{role}-topic names another)", BagWarning, stacklevel=2)
            name = alone[0]
        if name not in types:
            if given is None and not required:
                return None
            raise BagError(path, f"no {role} topic {name}; {_listing(types)}")
        if allowed and types[name] not in allowed:
            raise BagError(path, f"topic {name} has the unknown message type {types[name]}; "
                                 f"{role} need {' or '.join(allowed)}")
        return name

    roles = {"contacts": pick("contacts", (CONTACTS_STATE, POINT), required=True)}
    points = types[roles["contacts"]] == POINT
    roles["normals"] = pick("normals", (VECTOR,), required=points) if points else None
    roles["misses"] = pick("misses", (POINT,))
    roles["free"] = pick("free", (POINT,))
    roles["steps"] = None if topics.step_gap is not None else pick("steps", ())
    return roles


def _vector(vector):
    return [float(vector.x), float(vector.y), float(vector.z)]


def _items(path, roles, messages):
    """Every observation as ``(stamp, kind, position, normal, topic)`` (bag order) and the
    set of frames of the messages."""
    items, frames = [], set()
    contacts = roles["contacts"]
    for stamp, message in messages[contacts]:
        frames.add(message.header.frame_id)
        if hasattr(message, "states"):
            for state in message.states:
                if len(state.contact_positions) != len(state.contact_normals):
                    raise BagError(path, f"{contacts} at {stamp_text(stamp)}: "
                                         f"{len(state.contact_positions)} positions but "
                                         f"{len(state.contact_normals)} normals")
                items += [(stamp, "contact", _vector(p), _vector(n), contacts)
                          for p, n in zip(state.contact_positions, state.contact_normals)]
        else:
            items.append((stamp, "contact", _vector(message.point), None, contacts))
    if roles["normals"]:
        items = _with_normals(path, items, messages[roles["normals"]], roles, frames)
    for role, kind in (("misses", "noncontact"), ("free", "free")):
        for stamp, message in messages.get(roles[role], ()):
            frames.add(message.header.frame_id)
            items.append((stamp, kind, _vector(message.point), None, roles[role]))
    items.sort(key=lambda item: item[0])
    return items, frames


def _with_normals(path, items, normals, roles, frames):
    """The contact points of ``items`` given their normals, matched by stamp."""
    by_stamp = {}
    for stamp, message in normals:
        frames.add(message.header.frame_id)
        by_stamp.setdefault(stamp, []).append(_vector(message.vector))
    matched = []
    for stamp, kind, position, _, topic in items:
        waiting = by_stamp.get(stamp)
        if not waiting:
            raise BagError(path, f"the contact on {topic} at {stamp_text(stamp)} has no normal "
                                 f"with its stamp on {roles['normals']}")
        matched.append((stamp, kind, position, waiting.pop(0), topic))
    left = sorted(stamp for stamp, waiting in by_stamp.items() if waiting)
    if left:
        raise BagError(path, f"the normal on {roles['normals']} at {stamp_text(left[0])} has no "
                             f"contact with its stamp on {roles['contacts']}")
    return matched


def _check_frames(path, frames, wanted):
    names = ", ".join(repr(f) for f in sorted(frames))
    if wanted is not None and frames != {wanted}:
        raise BagError(path, f"the messages are in the frame(s) {names}, not {wanted!r}")
    if len(frames) > 1:
        raise BagError(path, f"the messages are in several frames ({names}): a recording "
                             "must be in one frame (transform them to one first)")


def _groups(items, roles, messages, step_gap):
    """The step key of each item: the step marker before it, a gap count, or its stamp."""
    if roles["steps"]:
        starts = sorted(stamp for stamp, _ in messages[roles["steps"]])
        return [bisect.bisect_right(starts, item[0]) for item in items]
    if step_gap is not None:
        keys, key = [], 0
        for number, item in enumerate(items):
            if number and item[0] - items[number - 1][0] > step_gap * 1e9:
                key += 1
            keys.append(key)
        return keys
    return [item[0] for item in items]


def _observation(path, kind, position, normal, topic, stamp):
    try:
        if kind == "contact":
            return Contact.recorded(position, normal)
        if kind == "noncontact":
            return NonContact(position)
        if not all(math.isfinite(v) for v in position):
            raise ObservationError(f"free-space point is not finite: {position}")
        return position
    except ObservationError as error:
        raise BagError(path, f"{topic} at {stamp_text(stamp)}: {error}") from None


def _steps(path, items, keys, scale):
    """The recorded steps of the ordered ``items`` with their step ``keys``."""
    steps, pending, last = [], [], None
    for (stamp, kind, position, normal, topic), key in zip(items, keys):
        position = [scale * value for value in position] if scale != 1.0 else position
        made = _observation(path, kind, position, normal, topic, stamp)
        if kind == "free":
            (steps[-1].free_space.append(made) if steps and key == last
             else pending.append(made))
            continue
        if not steps or key != last:
            steps.append(RecordedStep([], []))
            last = key
        steps[-1].observations.append(made)
        steps[-1].free_space.extend(pending)
        pending = []
    if pending:
        raise BagError(path, "free-space points after the last observation belong to no step")
    for step in steps:
        step.free_space = np.reshape(np.array(step.free_space, dtype=float), (-1, 3))
    return steps


def read_bag(path, units: str | None = None, topics: BagTopics | None = None):
    """Read the touches of a ROS 2 bag.

    Parameters
    ----------
    path : str or Path
        An ``.mcap`` or ``.db3`` file or a rosbag2 folder.
    units : str, optional
        The scene's unit (a name of ``UNITS``): the bag's metres are converted to it.
        None: positions as written (metres).
    topics : BagTopics, optional
        Topics, step grouping and frame (default: :class:`BagTopics` ()).

    Returns
    -------
    list of RecordedStep
        In time order, positions and normals in the bag's one frame.

    Raises
    ------
    BagError
        One line naming the file and the fault: unreadable or truncated, empty, a missing
        topic (with those present), an unknown message type, several frames, NaN, ...
    """
    _rosbags(path)
    topics = topics or BagTopics()
    roles, messages = _read(path, topics)
    items, frames = _items(path, roles, messages)
    if not any(kind != "free" for _, kind, *_ in items):
        raise BagError(path, f"the bag holds no contact or miss on {roles['contacts']}"
                             + (f" or {roles['misses']}" if roles["misses"] else ""))
    _check_frames(path, frames, topics.frame)
    scale = UNITS[BAG_UNITS] / UNITS[units] if units is not None else 1.0
    return _steps(path, items, _groups(items, roles, messages, topics.step_gap), scale)


def read_recording(path, units: str | None = None, topics: BagTopics | None = None):
    """The steps of a recording, a bag (:func:`is_bag`) or a CSV file
    (:func:`~tactile_viz.engine.io.observation_file.read_observations`)."""
    if is_bag(path):
        return read_bag(path, units, topics)
    return read_observations(path, units)


def recording_file_warning(path, steps, library, units=None):
    """Why the recording ``path`` is likely not in the library's unit, or None: a CSV as
    :func:`~tactile_viz.engine.io.observation_file.recording_warning`; a bag is in metres, so
    it is checked only against a library without a unit."""
    from ..shape.library import size_warning

    if not is_bag(path):
        return recording_warning(path, steps, library, units)
    if len(library) == 0 or library.units is not None:
        return None
    contacts = sum(isinstance(o, Contact) for step in steps for o in step.observations)
    return size_warning(Path(path).name, recording_span(steps), library.reference_size, units,
                        remedy="a bag is in metres: give the priors' unit (--mesh-units "
                               "or MESH:UNIT) so that they are converted",
                        smaller=contacts >= SPAN_CONTACTS)


__all__ = ["BAG_SUFFIXES", "BAG_UNITS", "BagError", "BagTopics", "DEFAULT_TOPICS",
           "GAZEBO_MSGS", "is_bag", "read_bag", "read_recording", "recording_file_warning",
           "stamp_text", "typestore"]
