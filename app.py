#!/usr/bin/env python3
"""Desktop launcher for tactile_viz: a thin wrapper around tactile_viz.gui.

    python app.py                                   # the window, default scene (mug_1)
    python app.py --object vase_2 --seed 3          # another object and pose
    python app.py --object mug_1 --steps 40 --screenshot out.png   # headless picture
"""

import argparse
import logging
import os
import sys

from tactile_viz.cli import add_logging_arguments, default_log_file, setup_logging

log = logging.getLogger("tactile_viz.app.launcher")
GUI_HINT = "the desktop app needs the GUI extra: pip install -e '.[gui]'"


def parse_args(argv=None):
    from tactile_viz.app.engine_process import ENGINES
    from tactile_viz.engine import SESSION_PRESETS, STRATEGIES

    parser = argparse.ArgumentParser(description="tactile_viz desktop app: watch and steer "
                                                 "active tactile recognition and shape learning")
    parser.add_argument("--object", default="mug_1", metavar="NAME",
                        help="bundled ground-truth object (default mug_1)")
    parser.add_argument("--seed", type=int, default=0, help="pose and session seed (default 0)")
    parser.add_argument("--strategy", choices=STRATEGIES, default="gpis-dhd")
    parser.add_argument("--preset", choices=list(SESSION_PRESETS), default="paper")
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
    add_logging_arguments(parser, log_file_default=str(default_log_file()))
    return parser.parse_args(argv)


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


def build_scene(args):
    from tactile_viz.app.scene import Scene

    scene = Scene(truth_name=args.object, seed=args.seed, strategy=args.strategy,
                  preset=args.preset)
    if args.learn_first:
        scene.ensure_session().run()
        scene.add_learned_shape()
        scene.randomize_pose(args.seed + 1)
    return scene


def main(argv=None):
    args = parse_args(argv)
    log_file = setup_logging(args.verbose, args.log_file)
    log.info("app started: %s (log file %s)", sys.argv if argv is None else argv, log_file)
    try:
        from PySide6.QtWidgets import QApplication

        from tactile_viz.gui.main_window import MainWindow
    except ImportError as error:
        log.debug("no GUI", exc_info=True)
        print(f"error: {error}\n{GUI_HINT}", file=sys.stderr)
        return 2
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        print("error: no display (DISPLAY is not set); on a headless machine run it under "
              "Xvfb, e.g. `xvfb-run -a make run`", file=sys.stderr)
        return 2

    from tactile_viz.engine.errors import TactileVizError

    try:
        scene = build_scene(args)
    except TactileVizError as error:
        log.debug("the scene could not be built", exc_info=True)
        print(f"error: {error}", file=sys.stderr)
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
        window.grab().save(args.screenshot)
        window.close()
        app.processEvents()
        print(f"saved {args.screenshot}")
        sys.excepthook = default_hook
        return 0
    try:
        return app.exec()
    finally:
        sys.excepthook = default_hook


if __name__ == "__main__":
    sys.exit(main())
