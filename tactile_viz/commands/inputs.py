"""What the commands read, and the checks that it agrees: mesh files with their units, the
prior library, learning into a library folder. ``trial``, ``replay`` and ``app.py`` share it,
so that one recording gives one estimate whichever of them reads it.

Units (docs/units.md): ``--units`` names the scene's unit; a mesh file's own unit is the
suffix after its last colon (``cup.stl:mm``, ``cup.stl:0.001``), else ``--mesh-units``. When
``--units`` is not given the scene is in metres if any mesh names a unit, else in the saved
library's unit, else in the files' own unnamed units.
"""

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np

from ..cli import ExtendList, existing_file, one_line, output_dir, positive_float
from ..engine.errors import LibraryError, TactileVizError
from ..engine.shape.library import MANIFEST, PriorLibrary, size_warning
from ..engine.shape.meshes import UNITS, split_units, unit_factor
from ..engine.shape.objects import ObjectModel, bundled_names

log = logging.getLogger(__name__)


def mesh_units(text):
    """An argument type: a mesh file's unit (m, cm, mm, in) or a factor (scene units per
    file unit)."""
    try:
        unit_factor(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def mesh_file(text):
    """An argument type: a readable mesh file, optionally followed by its unit after a colon
    (``cup.stl:mm``, ``cup.stl:0.001``); returned as given."""
    path, units = split_units(text)
    if units is not None:
        try:
            unit_factor(units)
        except ValueError as error:
            raise argparse.ArgumentTypeError(f"{text}: {error}") from None
    try:
        existing_file(path)
    except argparse.ArgumentTypeError as error:
        if ":" in text and units is None:
            raise argparse.ArgumentTypeError(
                f"{error} (a unit after ':' is one of {', '.join(UNITS)} or a number)") from None
        raise
    return text


def recording_file(text):
    """An argument type: a readable recording, a file or a rosbag2 folder (returned as
    given)."""
    from ..engine.io.bags import is_bag

    if Path(text).is_dir() and is_bag(text):
        return text
    return existing_file(text)


BAG_OPTIONS = {"contacts_topic": "contacts", "normals_topic": "normals",
               "misses_topic": "misses", "free_topic": "free", "step_topic": "steps",
               "step_gap": "step_gap", "bag_frame": "frame"}


def add_bag_arguments(parser):
    """The topics, steps and frame of a ``--observations`` bag (docs/robots.md)."""
    from ..engine.io.bags import DEFAULT_TOPICS as TOPICS

    group = parser.add_argument_group("bags (--observations FILE.mcap, FILE.db3 or a bag "
                                      "folder; metres, one frame)")
    group.add_argument("--contacts-topic", metavar="TOPIC",
                       help="gazebo_msgs/msg/ContactsState or geometry_msgs/msg/PointStamped "
                            f"contacts (default {TOPICS['contacts']})")
    group.add_argument("--normals-topic", metavar="TOPIC",
                       help="geometry_msgs/msg/Vector3Stamped normals of PointStamped "
                            f"contacts, matched by stamp (default {TOPICS['normals']})")
    group.add_argument("--misses-topic", metavar="TOPIC",
                       help="PointStamped ends of paths in free space (default "
                            f"{TOPICS['misses']}, when present)")
    group.add_argument("--free-topic", metavar="TOPIC",
                       help="PointStamped points passed through without touching (default "
                            f"{TOPICS['free']}, when present)")
    group.add_argument("--step-topic", metavar="TOPIC",
                       help="each message starts a step (default "
                            f"{TOPICS['steps']}, when present)")
    group.add_argument("--step-gap", metavar="SECONDS", type=positive_float,
                       help="a new step where stamps are more than SECONDS apart (instead of "
                            "the step topic; default: touches sharing a stamp are a step)")
    group.add_argument("--bag-frame", metavar="FRAME",
                       help="the frame every message must be in (default: any one frame)")


def bag_topics(args):
    """The :class:`~tactile_viz.engine.io.bags.BagTopics` of the bag options."""
    from ..engine.io.bags import BagTopics

    return BagTopics(**{field: getattr(args, option, None)
                        for option, field in BAG_OPTIONS.items()})


def bag_problem(args):
    """Why the bag options do not fit (None if they do): given for a CSV recording, or a
    step topic and a step gap both."""
    from ..engine.io.bags import is_bag

    given = [option for option in BAG_OPTIONS if getattr(args, option, None) is not None]
    if not given:
        return None
    flag = "--" + given[0].replace("_", "-")
    recording = getattr(args, "observations", None)
    if recording is None or not is_bag(recording):
        return f"{flag} is for a bag (--observations FILE.mcap, FILE.db3 or a bag folder)"
    if args.step_topic is not None and args.step_gap is not None:
        return "--step-topic and --step-gap both group the steps: give one of them"
    return None


def add_prior_arguments(parser):
    """``--library`` or ``--library-dir``, plus any ``--prior-file`` (see :func:`load_priors`)."""
    priors = parser.add_mutually_exclusive_group()
    priors.add_argument("--library", choices=["known", "novel", "all"], default=None,
                        help="the filter's priors: a bundled set (default known)")
    priors.add_argument("--library-dir", metavar="DIR",
                        help="a saved prior library folder (with --learn, made if missing)")
    parser.add_argument("--prior-file", metavar="MESH[:UNIT]", action=ExtendList,
                        type=mesh_file,
                        help="mesh files added to --library or --library-dir as priors; "
                             "alone, the only priors (repeats add up); a suffix :mm, :m, ... "
                             "or :FACTOR gives a file's unit")


def add_unit_arguments(parser, learning=True):
    """``--units`` (the scene's), ``--mesh-units``, ``--normalise`` and, with ``learning``,
    ``--learn`` and ``--learn-to``."""
    parser.add_argument("--units", choices=list(UNITS), default=None,
                        help="the scene's length unit, written in the outputs; meshes, "
                             "libraries and recordings in another named unit are converted "
                             "(default: m when a mesh's unit is named, else the library's)")
    parser.add_argument("--mesh-units", type=mesh_units, default=None, metavar="UNIT",
                        help="the unit of mesh files without a :UNIT suffix: m, cm, mm, in "
                             "(converted to the scene's, metres by default) or a factor")
    parser.add_argument("--normalise", type=positive_float, default=None, metavar="SIZE",
                        help="scale --object-file and --prior-file meshes to this longest "
                             "side (the paper's normalisation is 6); not with mesh units")
    if not learning:
        return
    parser.add_argument("--learn", metavar="NAME",
                        help="when the object ends judged novel, add its reconstruction as "
                             "the learned prior NAME to the library folder --learn-to")
    parser.add_argument("--learn-to", metavar="DIR", type=output_dir,
                        help="library folder --learn writes, made if missing (default "
                             "--library-dir): the session's priors plus the learned shape")


def mesh_texts(args):
    """The mesh options as given: ``--object-file`` (if any) and every ``--prior-file``."""
    first = getattr(args, "object_file", None)
    return ([first] if first else []) + list(getattr(args, "prior_file", None) or ())


def file_units(args, text):
    """``(path, unit)`` of a mesh option: its own ``:UNIT`` suffix, else ``--mesh-units``
    (None: none given)."""
    path, units = split_units(text)
    return path, units if units is not None else getattr(args, "mesh_units", None)


def _named(units):
    return isinstance(units, str) and units.strip().lower() in UNITS


def given_units(args):
    """The scene unit the options name: ``--units``, else ``m`` when a mesh's unit is a
    name; None when they name none (the library may, see :func:`scene_units`)."""
    if getattr(args, "units", None):
        return args.units
    return "m" if any(_named(file_units(args, text)[1]) for text in mesh_texts(args)) else None


def scene_units(args, library=None):
    """The scene's unit name: :func:`given_units`, else the one ``library`` records for all
    its priors; None when the files' own (unnamed) units are kept."""
    return given_units(args) or (library.units if library is not None else None)


def options_problem(args):
    """The first contradiction or missing piece of the unit and learning options (None if
    there is none), found before anything is read."""
    if problem := bag_problem(args):
        return problem
    normalise = getattr(args, "normalise", None)
    if normalise is not None:
        units = [units for units in [getattr(args, "mesh_units", None)]
                 + [split_units(text)[1] for text in mesh_texts(args)] if units is not None]
        if units:
            return (f"--normalise {normalise:g} and the mesh unit {units[0]} both set the "
                    "meshes' size: give one of them")
    learn, learn_to = getattr(args, "learn", None), getattr(args, "learn_to", None)
    if learn_to and not learn:
        return f"--learn-to {learn_to} needs --learn NAME (the learned prior's name)"
    if learn and not (learn_to or getattr(args, "library_dir", None)):
        return "--learn needs a library folder to write: --learn-to DIR (or --library-dir DIR)"
    folder = getattr(args, "library_dir", None)
    if folder is not None:
        path = Path(folder)
        if path.exists() and not path.is_dir():
            return f"--library-dir {folder}: not a folder"
        if not path.exists() and not learn:
            return f"--library-dir {folder}: no such folder (with --learn NAME it is made)"
        if not path.exists():
            return output_problem(folder)
    return None


def output_problem(folder):
    """Why ``--library-dir`` cannot be made where it is named (None if it can)."""
    try:
        output_dir(folder)
    except argparse.ArgumentTypeError as error:
        return f"--library-dir {folder}: {error}"
    return None


def load_mesh(args, text, units, name=None):
    """The :class:`ObjectModel` of a mesh option in the scene unit ``units``."""
    path, own = file_units(args, text)
    if own is None:
        scale = 1.0
    elif _named(own) and units is not None:
        scale = UNITS[own.strip().lower()] / UNITS[units]
    else:
        scale = unit_factor(own)
    return ObjectModel.from_file(path, name=name, longest_side=getattr(args, "normalise", None),
                                 scale=scale)


def _has_size(args, text):
    """True when a mesh option fixes its size: a unit, or ``--normalise``."""
    return file_units(args, text)[1] is not None or getattr(args, "normalise", None) is not None


def load_priors(args, units=None):
    """The priors of ``args`` in the scene unit ``units`` (None: :func:`scene_units`): the
    bundled set (``--library``, default known) or the saved library (``--library-dir``,
    empty when missing and ``--learn`` makes it), plus the ``--prior-file`` meshes;
    ``--prior-file`` alone gives only those.

    Raises
    ------
    LibraryError
        If an extra file would have the name (its stem) of a prior already there, or there
        is no prior at all.
    """
    extra = list(args.prior_file or [])
    folder = args.library_dir
    bundled = args.library or (None if extra or folder else "known")
    units = units or given_units(args)
    new = getattr(args, "learn", None) and not (Path(folder or ".") / MANIFEST).exists()
    library = PriorLibrary.load(folder, units=units) if folder and not new else PriorLibrary()
    # Names are checked before the bundled and extra meshes are read: a clash shows at once.
    names = library.names + (bundled_names(bundled) if bundled else [])
    for text in extra:
        name = Path(split_units(text)[0]).stem
        if name in names:
            raise LibraryError(f"--prior-file {text}: there is already a prior named "
                               f"{name!r}; rename the file")
        names.append(name)
    if bundled:
        library = PriorLibrary.bundled(bundled)
    units = units or library.units
    for text in extra:
        library.add(load_mesh(args, text, units), units=units)
    if not len(library):
        raise LibraryError(f"--library-dir {folder}: the folder holds no library yet, and no "
                           "--prior-file gives priors: add --prior-file MESH ...")
    return library


def size_warnings(args, library, truth=None):
    """Why the meshes of ``args`` are likely not in the library's unit: one line per
    suspicious file (:func:`tactile_viz.engine.shape.library.size_warning`). Every file is
    checked against the other priors, its unit declared or not (a millimetre file given as
    ``:m`` is a 120 m can); only ``--normalise`` sets sizes on purpose."""
    units = scene_units(args, library)
    found = []
    priors = [(text, library[Path(split_units(text)[0]).stem])
              for text in getattr(args, "prior_file", None) or ()]
    if truth is not None and getattr(args, "object_file", None):
        priors.append((args.object_file, truth))
    for text, model in priors:
        others = [m for m in library if m is not model]
        if getattr(args, "normalise", None) is not None or not others:
            continue
        message = size_warning(Path(split_units(text)[0]).name, model.length,
                               PriorLibrary(others).reference_size, units,
                               remedy=f"use {split_units(text)[0]}:{{unit}} (or --mesh-units "
                                      f"{{unit}})")
        if message:
            found.append(message)
    return found


def say(args, kind, message):
    """One line on stderr, ``PROG: KIND: MESSAGE`` (``kind`` ``warning`` or ``note``); the
    log file keeps it too."""
    prog = getattr(args, "prog", None) or "python -m tactile_viz"
    level = logging.WARNING if kind == "warning" else logging.INFO
    log.log(level, "%s: %s", kind, message, extra={"file_only": True})
    print(f"{prog}: {kind}: {one_line(message)}", file=sys.stderr)


def check_learning(args, library):
    """Where ``--learn`` writes (None without it); refused before any work when the name is
    taken."""
    if not getattr(args, "learn", None):
        return None
    if args.learn in library:
        raise LibraryError(f"--learn {args.learn}: the library already has a prior of that "
                           "name; choose another")
    return args.learn_to or args.library_dir


def learn(session, library, name, folder, units=None, args=None):
    """Add the session's reconstruction to ``library`` as the learned prior ``name`` (in
    the scene unit ``units``) and save the library to ``folder``; when the object was not
    judged novel, save the library unchanged if ``folder`` holds none yet (so that
    ``--library-dir`` finds it next time). Says what happened on stderr; returns a
    JSON-ready note."""
    saved = library.subset(library.names)
    try:
        model = session.learned_model(name)
    except TactileVizError as error:
        latest = session.latest
        reason = (f"the object was judged known as {latest.map_class}"
                  if latest is not None and not latest.novel else str(error))
        made = not (Path(folder) / MANIFEST).exists()
        if made:
            saved.save(folder)
        say(args, "note", f"not learned: {reason}" + (f"; {folder} saved with the session's "
                                                        "priors" if made else ""))
        return {"name": name, "saved_to": str(folder) if made else None, "reason": reason}
    saved.add(model, units=units)
    saved.save(folder)
    unit, turn = units or "scene units", chord_degrees(model.normal_error)
    say(args, "note", f"learned {name} ({model.length:.3g} {unit} long; a touch may miss it "
                      f"by {model.shape_error:.2g} {unit} RMS, its normal by {turn:.0f} deg), "
                      f"saved to {folder}")
    return {"name": name, "saved_to": str(folder), "longest_side": model.length,
            "shape_error": model.shape_error, "normal_error_deg": turn}


def chord_degrees(chord):
    """The angle between two unit vectors ``chord`` apart (0 to 2), degrees."""
    return float(np.degrees(2 * np.arcsin(np.clip(chord / 2, 0.0, 1.0))))


# ------------------------------------------------------------- a recording's scene
SCENE_KEY = "scene"


def _leading_comments(text):
    """``(line number, key, value)`` of the ``# KEY: VALUE`` comments before a CSV's header."""
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if not stripped.startswith("#"):
            return
        key, colon, value = stripped.lstrip("#").partition(":")
        if colon:
            yield number, key.strip().lower(), value.strip()


def recorded_scene(path, units=None):
    """The robot's scene a CSV recording names in a ``# scene: {...}`` comment before its
    header (the JSON of :meth:`~tactile_viz.engine.scene.Scene.as_dict`, lengths in the
    file's ``# units:``), converted to the scene unit ``units``; None when it names none
    (and for a bag, which has no such line).

    Raises
    ------
    ObservationFileError
        The line is not a scene (one line naming the file and the line).
    """
    from ..engine.errors import TactileVizError
    from ..engine.io.bags import is_bag
    from ..engine.io.observation_file import ObservationFileError, file_units
    from ..engine.scene import Scene
    from ..engine.shape.meshes import UNITS as LENGTHS

    if is_bag(path):
        return None
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None  # reading the touches reports it
    for number, key, value in _leading_comments(text):
        if key != SCENE_KEY:
            continue
        try:
            record = json.loads(value)
            if not isinstance(record, dict):
                raise ValueError("not a JSON object")
            scene = Scene.from_dict(record)
        except (ValueError, TypeError, TactileVizError) as error:
            raise ObservationFileError(path, number, f"the scene line is not a scene: {error} "
                                       '(expected e.g. # scene: {"table_point": [0, 0, 0], '
                                       '"reach_angle_deg": 60, "tip_radius": 0.005})') from None
        written = file_units(text, path)
        if units is None or written is None or written == units:
            return scene
        scale = LENGTHS[written] / LENGTHS[units]
        return Scene(None if scene.table_point is None else scene.table_point * scale,
                     scene.up, scene.reach_angle_deg, scene.tip_radius * scale)
    return None


def scene_line(scene):
    """The ``# scene: {...}`` comment of a recording made in ``scene`` (no newline)."""
    return f"# {SCENE_KEY}: {json.dumps(scene.as_dict())}"


def write_scene_line(path, scene):
    """Add the ``# scene:`` comment of ``scene`` before the header of the CSV recording
    ``path`` (after its ``# units:`` line); nothing for free space (None) or when the file
    already names a scene."""
    from ..engine.io.files import write_atomic

    if scene is None or scene.is_free:
        return
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    if any(key == SCENE_KEY for _, key, _ in _leading_comments(text)):
        return
    at = next((k for k, line in enumerate(lines)
               if line.strip() and not line.lstrip().startswith("#")), len(lines))
    lines.insert(at, scene_line(scene) + "\n")
    write_atomic(path, "".join(lines).encode("utf-8"))
