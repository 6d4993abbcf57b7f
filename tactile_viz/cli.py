"""Pieces every command line of the package shares: a parser whose errors are one line,
argument types that check values before any work starts, list options whose repeats add
up, and logging (``--verbose``, ``--log-file``).

Qt-free and light: the engine's commands, the benchmarks and ``app.py`` all use it.
"""

import argparse
import json
import logging
import math
import os
import sys
from pathlib import Path

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
MAX_SEED = 2**32 - 1
MAX_COUNT = 10_000
MAX_WORKERS = 256


def one_line(text):
    """``text`` with its lines joined by spaces (an error message shown as one line)."""
    return " ".join(line.strip() for line in str(text).splitlines() if line.strip())


def one_line_warning(prog, log=None):
    """A ``warnings.showwarning`` that shows a warning as one line on stderr,
    ``PROG: warning: MESSAGE`` (and to ``log``'s file when given), not as Python's two
    lines with a source path. Its ``prog`` attribute names the command (a process pool
    gives its workers the same)."""

    def show(message, category, filename, lineno, file=None, line=None):
        if log is not None:
            log.warning("%s: %s", category.__name__, message, extra={"file_only": True})
        print(f"{prog}: warning: {one_line(str(message))}", file=sys.stderr)

    show.prog = prog
    return show


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser, but an error is one line on stderr, ``PROG: error: MESSAGE``, and
    exit status 2 (argparse's usage line is left out; ``--help`` shows it).

    Subcommand parsers made with ``add_subparsers`` are of this class too.
    """

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def int_range(low, high=None):
    """An argument type: an integer from ``low`` to ``high`` (no upper bound when None)."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low or (high is not None and value > high):
            bounds = f"at least {low}" if high is None else f"from {low} to {high}"
            raise argparse.ArgumentTypeError(f"must be {bounds}, got {text!r}")
        return value

    return parse


positive_int = int_range(1)
nonnegative_int = int_range(0)
seed_int = int_range(0, MAX_SEED)
count_int = int_range(1, MAX_COUNT)
workers_int = int_range(1, MAX_WORKERS)


def finite_float(text):
    """An argument type: a finite number (no nan or inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive_float(text):
    """An argument type: a positive finite number."""
    value = finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def nonnegative_float(text):
    """An argument type: a finite number >= 0."""
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {text!r}")
    return value


def fraction(text):
    """An argument type: a number in [0, 0.5) (the simulated sensor's share of wrong
    contacts)."""
    value = finite_float(text)
    if not 0 <= value < 0.5:
        raise argparse.ArgumentTypeError(f"must lie in [0, 0.5), got {text!r}")
    return value


def existing_file(text):
    """An argument type: a readable file (returned as given)."""
    path = Path(text)
    if not text or not path.exists():
        raise argparse.ArgumentTypeError(f"no such file: {text!r}")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"not a file: {text!r}")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"cannot read {text!r}")
    return text


def existing_dir(text):
    """An argument type: a folder that exists (returned as given)."""
    if not text or not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"no such folder: {text!r}")
    return text


def _writable_folder(folder, text):
    if not os.access(folder, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write in {str(folder)!r} (for {text!r})")


def writable_output(text):
    """An argument type: a file that can be written (its folder exists; returned as given).

    Checked when the command line is read, so that a long run does not end in a file that
    cannot be written.
    """
    path = Path(text)
    if not text:
        raise argparse.ArgumentTypeError("a file name is needed")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"a file name is needed, got the folder {text!r}")
    folder = path.parent
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"no such folder: {str(folder)!r} (for {text!r})")
    _writable_folder(folder, text)
    if path.exists() and not os.access(path, os.W_OK):
        raise argparse.ArgumentTypeError(f"cannot write {text!r}")
    return text


def output_dir(text):
    """An argument type: a folder to write into, existing or creatable (returned as given).

    Missing folders are not made here: only the nearest existing one is checked.
    """
    path = Path(text)
    if not text:
        raise argparse.ArgumentTypeError("a folder name is needed")
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"not a folder: {text!r}")
    existing = next(p for p in [path, *path.absolute().parents] if p.exists())
    if not existing.is_dir():
        raise argparse.ArgumentTypeError(f"cannot make a folder under the file "
                                         f"{str(existing)!r} (for {text!r})")
    _writable_folder(existing, text)
    return text


def bag_output(text):
    """An argument type: an ``.mcap`` file that can be written (returned as given)."""
    if Path(text).suffix.lower() != ".mcap":
        raise argparse.ArgumentTypeError(f"the bag must be an .mcap file, got {text!r}")
    return writable_output(text)


def name_list(choices, what):
    """An argument type: one name or a comma list of them, each one of ``choices`` (a list,
    or a function returning it, called on first use); returns the text as given.

    ``what`` names a choice in the error message: ``"a strategy"``.
    """
    def parse(text):
        known = choices() if callable(choices) else choices
        names = [name for name in text.split(",") if name]
        unknown = [name for name in names if name not in known]
        if unknown or not names:
            raise argparse.ArgumentTypeError(
                f"not {what}: {', '.join(map(repr, unknown or [text]))}; choose from "
                f"{', '.join(known)}")
        return text

    return parse


def _bundled(which):
    from .engine.shape.objects import bundled_names

    return bundled_names(which)


def bundled_object(which="all"):
    """An argument type: the name of a bundled object of the set ``which``."""
    what = "an object" if which == "all" else f"a {which} object"
    check = name_list(lambda: _bundled(which), what)

    def parse(text):
        if "," in text:
            raise argparse.ArgumentTypeError(f"one object name, got {text!r}")
        return check(text)

    return parse


def bundled_objects(text):
    """An argument type: bundled object names, one or a comma list."""
    return name_list(lambda: _bundled("all"), "an object")(text)


class ExtendList(argparse.Action):
    """``nargs="+"`` whose repeated flags add up: ``--x A --x B C`` gives ``[A, B, C]``.

    argparse's own ``action="extend"`` appends to a non-empty default (``--objects X`` would
    give the default objects plus X); here the first use on the command line replaces the
    default and later uses extend it.
    """

    def __init__(self, option_strings, dest, nargs="+", **kwargs):
        if nargs != "+":
            raise ValueError("ExtendList takes nargs='+' only")
        super().__init__(option_strings, dest, nargs=nargs, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        current = getattr(namespace, self.dest, None)
        if current is None or current is self.default:
            current = []
        setattr(namespace, self.dest, [*current, *values])


def _for_console(record):
    """Records logged with ``extra={"file_only": True}`` go to the log file only."""
    return not getattr(record, "file_only", False)


class _CurrentStderr(logging.StreamHandler):
    """A handler that writes to whatever ``sys.stderr`` is when a message comes (pytest and
    some GUIs replace it after logging is set up)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass


def preset_name(text):
    """An argument type: a session preset's name (an old name is taken with a note)."""
    from .engine.presets import RENAMED_PRESETS, SESSION_PRESETS

    if text in RENAMED_PRESETS:
        print(f"note: the preset {text!r} is now called {RENAMED_PRESETS[text]!r}",
              file=sys.stderr)
        return RENAMED_PRESETS[text]
    if text not in SESSION_PRESETS:
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from "
                                         f"{', '.join(SESSION_PRESETS)})")
    return text


def add_preset_argument(parser, default=None, purpose=""):
    """``--preset NAME``, one of the engine's session presets (default ``recommended``; an old
    name is taken with a note on stderr), declared here once for every command; ``purpose``
    ends its help."""
    from .engine.presets import DEFAULT_PRESET, SESSION_PRESETS

    default = default or DEFAULT_PRESET
    parser.add_argument("--preset", type=preset_name, default=default, metavar="NAME",
                        help=f"speed/accuracy preset: {', '.join(SESSION_PRESETS)} (default "
                             f"{default}; paper: the paper exactly; recommended: the "
                             f"project's configuration){purpose}")


# Options that set a declared parameter besides --set: option -> the parameter's name.
PARAMETER_OPTIONS = {"--outlier-probability": "outlier_probability"}
_WORDS = {"True": True, "False": False, "None": None}


def parameter_setting(text):
    """An argument type: ``NAME=VALUE`` of a declared parameter (see
    :func:`tactile_viz.engine.params.declarations`), VALUE as JSON (``0.4``, ``true``,
    ``null``), ``True``/``False``/``None``, or else as text (``contact``); checked against
    the parameter's kind and range. Returns ``(name, value)``."""
    from .engine.errors import ParameterError
    from .engine.params import declaration

    name, equals, value = text.partition("=")
    if not equals:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    if value in _WORDS:
        value = _WORDS[value]
    else:
        try:
            value = json.loads(value)
        except ValueError:
            pass  # a word such as a choice's name
    try:
        return name.strip(), declaration(name.strip()).check(value)
    except ParameterError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def parameter_value(name):
    """An argument type: a value of the declared parameter ``name`` (as for ``--set``)."""

    def value(text):
        return parameter_setting(f"{name}={text}")[1]

    value.__name__ = name  # argparse names the type in its messages
    return value


def add_set_argument(parser):
    """``--set NAME=VALUE ...``: change declared parameters of the preset (repeatable)."""
    parser.add_argument("--set", type=parameter_setting, action=ExtendList, default=[],
                        metavar="NAME=VALUE",
                        help="change parameters of the preset, e.g. --set eps=0.4 "
                             "sigma_d=0.3 (repeatable; the names and ranges: "
                             "tactile_viz/engine/params.py)")


def with_settings(params, settings):
    """``params`` (SessionParams) with the ``--set`` pairs applied."""
    from .engine.params import with_changes

    return with_changes(params, **dict(settings))


def default_log_file():
    """``$XDG_STATE_HOME/tactile_viz/app.log``, else ``~/.local/state/tactile_viz/app.log``."""
    base = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(base) / "tactile_viz" / "app.log"


def add_logging_arguments(parser, log_file_default=None):
    """``--verbose`` (debug messages on stderr) and ``--log-file FILE`` (every message there)."""
    parser.add_argument("--verbose", "-v", action="store_true",
                        help="log debug messages on stderr (default: warnings and errors)")
    where = f" (default {log_file_default}; '' for none)" if log_file_default else ""
    parser.add_argument("--log-file", metavar="FILE", default=log_file_default,
                        help=f"also append every log message to this file{where}")


def stop_logging():
    """Remove (and close) the handlers :func:`setup_logging` added."""
    logger = logging.getLogger("tactile_viz")
    for handler in [h for h in logger.handlers if getattr(h, "tactile_viz_cli", False)]:
        logger.removeHandler(handler)
        handler.close()


def setup_logging(verbose=False, log_file=None):
    """Send the ``tactile_viz`` loggers' messages to stderr (warnings and errors; everything
    with ``verbose``) and, when ``log_file`` is given, append everything to that file.

    Calling it again replaces what an earlier call set up. A log file that cannot be opened
    is reported on stderr and skipped: logging never stops the program.

    Returns
    -------
    Path or None
        The log file in use.
    """
    stop_logging()
    logger = logging.getLogger("tactile_viz")
    logger.setLevel(logging.DEBUG)
    console = _CurrentStderr()
    console.setLevel(logging.DEBUG if verbose else logging.WARNING)
    console.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    console.addFilter(_for_console)
    handlers = [console]
    opened = None
    if log_file:
        try:
            Path(log_file).parent.mkdir(parents=True, exist_ok=True)
            file_handler = logging.FileHandler(log_file, encoding="utf-8")
        except OSError as error:
            problem = f"cannot write the log file {log_file}: {error}"
        else:
            problem = None
            file_handler.setLevel(logging.DEBUG)
            file_handler.setFormatter(logging.Formatter(LOG_FORMAT))
            handlers.append(file_handler)
            opened = Path(log_file)
    for handler in handlers:
        handler.tactile_viz_cli = True
        logger.addHandler(handler)
    if log_file and opened is None:
        logger.warning(problem)
    return opened


def add_sensor_arguments(parser, simulated=True):
    """The sensor's noise (``--position-noise``, ``--normal-noise``: the simulator adds it
    and the model assumes it), the model's outlier probability and, for a simulated
    sensor, its rate of wrong contacts (``--outliers``)."""
    parser.add_argument("--position-noise", type=nonnegative_float, default=0.0, metavar="STD",
                        help="std of the sensor's contact positions, scene units (default 0)")
    parser.add_argument("--normal-noise", type=nonnegative_float, default=0.0, metavar="DEG",
                        help="std of the tilt of the sensor's normals, degrees (default 0)")
    parser.add_argument("--outlier-probability", type=parameter_value("outlier_probability"),
                        default=None, metavar="P",
                        help="the model's chance of a wrong contact: a robust likelihood "
                             "(default the preset's; 0 is the paper's Gaussian)")
    if simulated:
        parser.add_argument("--outliers", type=fraction, default=0.0, metavar="FRACTION",
                            help="the simulated sensor's chance of a wrong contact, a third "
                                 "of the object's size off (default 0)")


def add_output_arguments(parser, export_help):
    """``--json``, ``--export DIR`` (``export_help`` says what it writes), ``--export-bag``
    and ``--no-progress`` of the commands that run a session."""
    parser.add_argument("--json", metavar="OUT", type=writable_output,
                        help="write the JSON here (default stdout)")
    parser.add_argument("--export", metavar="DIR", type=output_dir, help=export_help)
    parser.add_argument("--export-bag", metavar="FILE.mcap", type=bag_output,
                        help="write every step as a ROS 2 bag (MCAP, metres) for RViz and "
                             "Foxglove: touches, MAP pose, posterior, MAP shape and GPIS "
                             "markers (docs/robots.md)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    parser.add_argument("--quiet", action="store_true",
                        help="no summary on stderr at the end (the JSON is unchanged)")


def reach_angle(text):
    """An argument type: a reach cone's half-angle in degrees, in (0, 180]."""
    value = finite_float(text)
    if not 0 < value <= 180:
        raise argparse.ArgumentTypeError(f"must lie in (0, 180] degrees, got {text!r}")
    return value


def add_scene_arguments(parser, several_radii=False, simulated=True, unit="scene units"):
    """The robot's scene (docs/cli.md, "The robot's scene"): ``--table``,
    ``--table-height H``, ``--reach-angle DEG`` and ``--tip-radius R``; all off by default
    (the paper's free space). With ``several_radii`` (a benchmark) ``--tip-radius`` (alias
    ``--tip-radii``) takes a list of radii, one run of every trial per radius. ``simulated``:
    the command places a simulated object (on the table); ``unit`` names the lengths' unit
    in the help."""
    group = parser.add_argument_group("the robot's scene (docs/cli.md; default: the paper's "
                                      "free space)")
    rests = (": the simulated object rests on it at a random stable pose, contacts with it "
             "are misses of the object" if simulated
             else ": contacts with it are misses of the object")
    group.add_argument("--table", action="store_true",
                       help=f"a horizontal support plane under the object, z up{rests}")
    group.add_argument("--table-height", type=finite_float, default=None, metavar="H",
                       help=f"the table's height z, {unit} (default 0; giving it implies "
                            "--table)")
    group.add_argument("--reach-angle", type=reach_angle, default=180.0, metavar="DEG",
                       help="half-angle of the cone about straight down in which the tip "
                            "may travel, degrees in (0, 180] (default 180: any direction)")
    if several_radii:
        group.add_argument("--tip-radius", "--tip-radii", dest="tip_radius",
                           type=nonnegative_float, action=ExtendList, default=[0.0],
                           metavar="R",
                           help=f"radii of the spherical fingertip, {unit}, >= 0; every "
                                "trial runs once per radius (default 0: the paper's point)")
    else:
        group.add_argument("--tip-radius", type=nonnegative_float, default=0.0, metavar="R",
                           help=f"radius of the spherical fingertip, {unit}, >= 0 "
                                "(default 0: the paper's point sensor)")


def scene_from_args(args, tip_radius=None):
    """The :class:`~tactile_viz.engine.scene.Scene` of the options of
    :func:`add_scene_arguments` (``tip_radius`` replaces ``--tip-radius``: one of a
    benchmark's radii); None when they are all at their defaults (the paper's free space)."""
    from .engine.scene import Scene

    height = getattr(args, "table_height", None)
    table = bool(getattr(args, "table", False)) or height is not None
    reach = float(getattr(args, "reach_angle", 180.0))
    if tip_radius is None:
        tip_radius = getattr(args, "tip_radius", 0.0)
        if isinstance(tip_radius, (list, tuple)):
            tip_radius = tip_radius[0] if len(tip_radius) == 1 else None
            if tip_radius is None:
                raise ValueError("several tip radii: pass one of them as tip_radius")
    tip_radius = float(tip_radius)
    if not table and reach == 180.0 and tip_radius == 0.0:
        return None
    if table:
        return Scene.on_table(height or 0.0, reach, tip_radius)
    return Scene(None, (0.0, 0.0, 1.0), reach, tip_radius)


def scenes_from_args(args):
    """One scene (or None, free space) per ``--tip-radius`` of a benchmark's options."""
    radii = getattr(args, "tip_radius", 0.0)
    radii = list(radii) if isinstance(radii, (list, tuple)) else [radii]
    return [scene_from_args(args, radius) for radius in dict.fromkeys(radii)]
