"""The desktop app's command line: ``tactile-viz app [options]`` (``python app.py`` in a
clone runs the same), a thin launcher of :mod:`tactile_viz.gui`.

    tactile-viz app                                   # the window, default scene (mug_1)
    tactile-viz app --object vase_2 --seed 3          # another object and pose
    tactile-viz app --object mug_1 --steps 40 --screenshot out.png   # headless picture
    tactile-viz app --object-file cup.stl --library known --prior-file cup.stl   # own meshes
    tactile-viz app --object-file can.stl:mm --prior-file cup.stl:mm bowl.stl:m  # with units
    tactile-viz app --object-file scans/mug/textured.obj:m --object-name mug --library-dir lib
    tactile-viz app --observations touches.csv --library-dir my_library  # recorded touches
    tactile-viz app --table --reach-angle 60 --tip-radius 0.2   # on a table, a robot's reach

Nothing here imports Qt before :func:`main` has parsed the options: without the gui extra
the command ends with one line saying how to install it.
"""

import argparse
import logging
import os
import sys

from tactile_viz.threads import one_blas_thread

one_blas_thread()  # before numpy loads: the window's process and the engine's it spawns

from tactile_viz.cli import (  # noqa: E402
    ExtendList,
    add_logging_arguments,
    add_preset_argument,
    add_scene_arguments,
    add_sensor_arguments,
    default_log_file,
    one_line,
    scene_from_args,
    setup_logging,
)

log = logging.getLogger("tactile_viz.app.launcher")
PROG = "app.py"  # errors are one line, "PROG: error: MESSAGE", as the command line's
GUI_HINT = "install the gui extra: pip install -e '.[gui]' (in the clone)"


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit status 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def parse_args(argv=None, prog=PROG):
    """The app's options from ``argv`` (default ``sys.argv[1:]``); a bad one exits with
    status 2 and one line, ``PROG: error: ...``, on stderr."""
    from tactile_viz.app.engine_process import ENGINES
    from tactile_viz.engine import STRATEGIES

    parser = Parser(prog=prog, description="tactile_viz desktop app: watch and steer active "
                                           "tactile recognition and shape learning")
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--object", metavar="NAME",
                      help="bundled ground-truth object (default mug_1)")
    what.add_argument("--object-file", metavar="MESH[:UNIT]",
                      help="a mesh file as the ground truth; a suffix :mm, :m, ... or "
                           ":FACTOR gives its unit")
    parser.add_argument("--object-name", metavar="NAME",
                        help="the --object-file object's name in the window (default: the "
                             "file's; a scan set's textured.obj is better named by its folder)")
    what.add_argument("--observations", metavar="FILE",
                      help="step through recorded touches (CSV: kind,x,y,z,nx,ny,nz, or a "
                           "ROS 2 bag: .mcap, .db3 or a bag folder) instead of touching an "
                           "object")
    library = parser.add_mutually_exclusive_group()
    library.add_argument("--library", choices=["known", "novel", "all"],
                         help="the priors: a bundled set (default known)")
    library.add_argument("--library-dir", metavar="DIR", help="a saved prior library folder")
    parser.add_argument("--prior-file", metavar="MESH[:UNIT]", action=ExtendList,
                        help="mesh files as priors (repeats add up): added to --library or "
                             "--library-dir when given, else the only priors; a suffix :mm, "
                             ":m, ... or :FACTOR gives a file's unit")
    parser.add_argument("--seed", type=int, default=0, help="pose and session seed (default 0)")
    parser.add_argument("--strategy", choices=STRATEGIES, default="gpis-dhd")
    add_preset_argument(parser)
    parser.add_argument("--engine", choices=ENGINES, default="process",
                        help="where Step and Run step the session: a process of its own, so "
                             "the window draws meanwhile on another core (default), or a "
                             "thread of the app's process")
    parser.add_argument("--steps", type=int, default=0,
                        help="run this many steps before showing (or before the screenshot)")
    parser.add_argument("--learn-first", action="store_true",
                        help="first explore the object to termination, add its reconstruction "
                             "as a prior, then place it at the next seed's pose")
    parser.add_argument("--screenshot", metavar="FILE",
                        help="render, save a PNG of the window and exit (no event loop)")
    from tactile_viz.commands.inputs import add_bag_arguments, add_unit_arguments

    add_unit_arguments(parser, learning=False)  # the same --units, --mesh-units, --normalise
    add_sensor_arguments(parser)
    add_scene_arguments(parser)
    add_bag_arguments(parser)
    add_logging_arguments(parser, log_file_default=str(default_log_file()))
    args = parser.parse_args(argv)
    args.prog = prog
    problem = argument_problem(args)
    if problem:
        parser.error(problem)
    return args


def _path_problem(option, path, folder=False):
    kind = "folder" if folder else "file"
    if not os.path.exists(path):
        return f"{option} {path}: no such {kind}"
    if folder and not os.path.isdir(path):
        return f"{option} {path}: not a folder"
    if not folder and not os.path.isfile(path):
        return f"{option} {path}: not a file (a folder?)"
    return None


def screenshot_problem(path):
    """Why a screenshot cannot be written to ``path`` (None if it can)."""
    folder = os.path.dirname(os.path.abspath(path))
    if not path.lower().endswith(".png"):
        return f"--screenshot {path}: the file name must end in .png"
    if os.path.isdir(path):
        return f"--screenshot {path}: is a folder"
    if not os.path.isdir(folder):
        return f"--screenshot {path}: the folder {folder} does not exist"
    if not os.access(folder, os.W_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        return f"--screenshot {path}: not writable"
    return None


def argument_problem(args):
    """The first fault of the options that can be told without loading anything (None if
    there is none): the screenshot's path first, then numbers and paths."""
    if args.screenshot and (problem := screenshot_problem(args.screenshot)):
        return problem
    if args.seed < 0:
        return f"--seed must be 0 or more, not {args.seed}"
    if args.steps < 0:
        return f"--steps must be 0 or more, not {args.steps}"
    if args.object_name and not args.object_file:
        return "--object-name names an --object-file object, not a bundled one or a recording"
    if args.observations and args.learn_first:
        return "--learn-first needs an object to explore, not --observations"
    from tactile_viz.commands.inputs import mesh_units, options_problem
    from tactile_viz.engine.io.bags import is_bag
    from tactile_viz.engine.shape.meshes import split_units

    if args.observations and not (os.path.isdir(args.observations) and is_bag(
            args.observations)) and (problem := _path_problem("--observations",
                                                              args.observations)):
        return problem
    meshes = [("--object-file", args.object_file)] if args.object_file else []
    for option, text in meshes + [("--prior-file", text) for text in args.prior_file or ()]:
        path, units = split_units(text)
        if problem := _path_problem(option, path):
            return problem
        try:
            units is None or mesh_units(units)
        except argparse.ArgumentTypeError as error:
            return f"{option} {text}: {error}"
    if args.library_dir and (problem := _path_problem("--library-dir", args.library_dir,
                                                      folder=True)):
        return problem
    return options_problem(args)


def log_errors_shown(window):
    """Log every error the window shows in a message box (the worker's and the scene's), and
    uncaught exceptions, so that the log file of a bug report has their tracebacks."""
    show_error = window.show_error

    def logged(error):
        log.error("shown to the user: %s", error, exc_info=error)
        show_error(error)

    window.show_error = logged  # the window calls self.show_error, so this replaces it
    default_hook = sys.excepthook

    def excepthook(kind, value, traceback):
        log.critical("uncaught exception", exc_info=(kind, value, traceback))
        default_hook(kind, value, traceback)

    sys.excepthook = excepthook
    return default_hook


def load_priors(args):
    """The priors of the options, read as ``trial`` and ``replay`` read them: the bundled
    set or the saved library (known when neither is given and no --prior-file is), plus
    every --prior-file, in the scene's unit."""
    from tactile_viz.commands.inputs import load_priors as load

    return load(args)


def build_scene(args):
    """The scene of the options, read as ``trial`` and ``replay`` read them (units, a
    recording's ``# units:`` line, warnings about files likely in another unit); a bad mesh,
    library or recording raises the project's error (before any window opens)."""
    from tactile_viz.app.scene import Scene
    from tactile_viz.commands.inputs import load_mesh, scene_units, size_warnings

    library = load_priors(args)
    units = scene_units(args, library)
    truth = (load_mesh(args, args.object_file, units, name=args.object_name)
             if args.object_file else None)
    for message in size_warnings(args, library, truth):
        log.warning("%s", message)
    scene = Scene(truth_name=args.object or "mug_1", truth_model=truth, seed=args.seed,
                  library=library, strategy=args.strategy, preset=args.preset,
                  units=units,
                  sensor_noise=(args.position_noise, args.normal_noise),
                  sensor_outliers=args.outliers, robot_scene=scene_from_args(args))
    if args.outlier_probability is not None:
        scene.set_parameter("outlier_probability", args.outlier_probability)
    if args.learn_first:
        scene.ensure_session().run()
        scene.add_learned_shape()
        scene.randomize_pose(args.seed + 1)
    if args.observations:
        from tactile_viz.commands.inputs import bag_topics

        scene.open_observations(args.observations, bag_topics(args))
    return scene


def main(argv=None, prog=PROG):
    """Open the desktop app with the options ``argv`` (default ``sys.argv[1:]``); ``prog``
    names the command in its one-line errors. Returns the exit status."""
    args = parse_args(argv, prog)
    log_file = setup_logging(args.verbose, args.log_file)
    log.info("app started: %s (log file %s)", sys.argv if argv is None else argv, log_file)
    try:
        from PySide6.QtWidgets import QApplication

        from tactile_viz.gui.main_window import MainWindow
    except ImportError as error:
        log.debug("no GUI", exc_info=True)
        print(f"{prog}: error: the desktop app needs PySide6 and pyvista ({error}); {GUI_HINT}",
              file=sys.stderr)
        return 2
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        print(f"{prog}: error: no display (DISPLAY is not set); on a headless machine run it under "
              "Xvfb, e.g. `xvfb-run -a make run`", file=sys.stderr)
        return 2

    from tactile_viz.engine.errors import TactileVizError

    try:
        scene = build_scene(args)
    except (TactileVizError, ValueError, OSError) as error:
        log.debug("the scene could not be built", exc_info=True)
        print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
        return 2
    app = QApplication.instance() or QApplication(sys.argv[:1])
    window = MainWindow(scene, engine=args.engine)
    if window.engine is not None and not args.screenshot:
        window.engine.start()  # it imports the engine while the window opens
    default_hook = log_errors_shown(window)
    window.show()
    for _ in range(args.steps):
        if scene.ensure_session().terminated:
            break
        scene.step()
    if args.screenshot:
        app.processEvents()
        window.frame_truth()  # the final window size is known only now
        window.plots.draw()
        app.processEvents()
        saved = window.grab().save(args.screenshot)
        window.close()
        app.processEvents()
        sys.excepthook = default_hook
        if not saved:
            print(f"{prog}: error: cannot write the screenshot {args.screenshot}",
                  file=sys.stderr)
            return 1
        print(f"saved {args.screenshot}")
        return 0
    try:
        return app.exec()
    finally:
        sys.excepthook = default_hook

