"""The command line: ``python -m tactile_viz COMMAND ...``, installed as ``tactile-viz``."""

import argparse
import contextlib
import importlib
import json
import logging
import os
import sys
import warnings

from .threads import one_blas_thread

one_blas_thread()  # before numpy loads (the imports below)

from .cli import (  # noqa: E402
    ArgumentParser,
    add_logging_arguments,
    one_line,
    one_line_warning,
    setup_logging,
)
from .engine.errors import TactileVizError  # noqa: E402
from .experiments import BENCHMARKS  # noqa: E402

# Not __name__: run as ``python -m`` it is "__main__", outside the package's loggers.
log = logging.getLogger("tactile_viz.__main__")


def _objects(args):
    from .engine.shape.objects import bundled_manifest

    entries = bundled_manifest()
    if args.json:
        print(json.dumps([{"name": e["name"], "set": e["set"],
                           "variant_of": e.get("variant_of") or None} for e in entries]))
        return 0
    width = max(len(e["name"]) for e in entries)
    print(f"{'name':<{width}}  set    variant of")
    for entry in entries:
        print(f"{entry['name']:<{width}}  {entry['set']:<5}  {entry.get('variant_of') or '-'}")
    return 0


def _library(args):
    from .commands.library import run_library_command

    return run_library_command(args)


def _trial(args):
    from .commands.trial import run_trial_command

    return run_trial_command(args)


def _replay(args):
    from .commands.replay import run_replay_command

    return run_replay_command(args)


def _app_prog():
    """How the app command is named in its errors: as the user typed the program."""
    program = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    return "tactile-viz app" if program == "tactile-viz" else "python -m tactile_viz app"


def _app(args, options):
    """Open the desktop app with ``options`` (app.py's); ``--verbose`` and ``--log-file``
    given before ``app`` are passed on too."""
    from .launcher import main as app_main

    before = (["--verbose"] if args.verbose else []) + (
        ["--log-file", args.log_file] if args.log_file is not None else [])
    return app_main(before + list(options), prog=_app_prog())


def _bench(args):
    """Run the benchmark ``args.what`` (:data:`~tactile_viz.experiments.BENCHMARKS`) with
    the options after its name; its module is imported only now."""
    module, _ = BENCHMARKS[args.what]
    return importlib.import_module(module).main(args.rest)


def build_parser():
    parser = ArgumentParser(
        prog="python -m tactile_viz",
        description="Active tactile object recognition, pose estimation and shape transfer.")
    add_logging_arguments(parser)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    objects = commands.add_parser("objects", help="list the bundled objects and their set")
    objects.add_argument("--json", action="store_true",
                         help='print a JSON list of {"name": ..., "set": "known"|"novel", '
                              '"variant_of": NAME or null}')
    objects.set_defaults(run=_objects, prog=objects.prog)

    from .commands.trial import add_trial_arguments

    trial = commands.add_parser(
        "trial", help="run one active-exploration trial headless and write its JSON",
        description="Run one trial of Algorithm 2 on a bundled object or a mesh file at a "
                    "random pose (from --seed) and write one JSON record per step.")
    add_trial_arguments(trial)
    from .commands.inputs import options_problem

    trial.set_defaults(run=_trial, prog=trial.prog, check=options_problem)

    from .commands.replay import add_replay_arguments

    replay = commands.add_parser(
        "replay", help="replay recorded touches (CSV or ROS 2 bag) through the filter and "
                       "the GPIS",
        description="Replay an observation file (header kind,x,y,z,nx,ny,nz, optional step "
                    "column; kind contact, noncontact or free) or a ROS 2 bag (docs/robots.md) "
                    "through the filter and the GPIS and write the trial command's per-step "
                    "JSON (truth metrics null).")
    add_replay_arguments(replay)
    replay.set_defaults(run=_replay, prog=replay.prog, check=options_problem)

    from .commands.library import add_library_arguments

    library = commands.add_parser(
        "library", help="build and keep a library folder: build, add, remove, list, show",
        description="Make a library folder from mesh files and keep it (docs/cli.md).")
    add_library_arguments(library)
    library.set_defaults(run=_library, prog=library.prog)

    # Its options are the launcher's (app.py's), parsed there: --help lists them.
    commands.add_parser("app", add_help=False,
                        help="open the desktop app (options as app.py's; app --help "
                             "lists them; needs the gui extra)")

    bench = commands.add_parser("bench", help=f"run a benchmark ({', '.join(BENCHMARKS)})",
                                description="Benchmarks; each has its own --help.")
    bench.add_argument("what", choices=list(BENCHMARKS),
                       help="; ".join(f"{name}: {what}" for name, (_, what) in
                                      BENCHMARKS.items()))
    bench.add_argument("rest", nargs=argparse.REMAINDER, help="options of the benchmark")
    bench.set_defaults(run=_bench, prog=bench.prog)
    return parser


def _fail(prog, message, status, verbose, hint=""):
    """Log the exception being handled with its traceback (to the log file; on stderr too
    with ``--verbose``) and show ``message`` as one line, ``PROG: error: MESSAGE`` as the
    parser's errors; returns ``status``."""
    log.error("the command failed: %s", message, exc_info=True,
              extra={"file_only": not verbose})
    print(f"{prog}: error: {one_line(message)}{hint}", file=sys.stderr)
    return status


@contextlib.contextmanager
def one_line_warnings(prog):
    """Show every Python warning raised while the command runs as one line on stderr,
    ``PROG: warning: MESSAGE`` (the log file keeps it too), not as Python's two lines with
    a source path."""
    before = warnings.showwarning
    warnings.showwarning = one_line_warning(prog, log)
    try:
        yield
    finally:
        warnings.showwarning = before


def main(argv=None):
    """Run ``python -m tactile_viz`` (or ``tactile-viz``) with ``argv``; returns the exit
    status. ``app`` hands its options to :func:`tactile_viz.launcher.main`.

    Bad arguments exit (status 2) with one line on stderr. A failing command is shown as one
    line on stderr, its traceback goes to the ``--log-file``: status 2 for the errors a
    user can cause (bad input files, ...), 1 for anything unexpected.
    """
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if args.command == "app":
        return _app(args, unknown)
    if unknown:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    log_file = setup_logging(args.verbose, args.log_file)
    log.debug("command: %s", sys.argv if argv is None else argv)
    prog = getattr(args, "prog", "python -m tactile_viz")
    if args.command == "bench":
        prog = f"{prog} {args.what}"
    check = getattr(args, "check", None)
    if check is not None and (problem := check(args)):
        print(f"{prog}: error: {one_line(problem)}", file=sys.stderr)
        return 2
    try:
        with one_line_warnings(prog):
            status = args.run(args)
            sys.stdout.flush()  # a closed pipe shows here, not at the interpreter's exit
        return status
    except BrokenPipeError:  # `... | head`: the reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except TactileVizError as error:
        return _fail(prog, str(error), 2, args.verbose)
    except SystemExit as stop:
        if not isinstance(stop.code, str):  # argparse's exits and plain exit statuses
            raise
        return _fail(prog, stop.code, 2, args.verbose)
    except KeyboardInterrupt:
        log.info("interrupted", exc_info=True, extra={"file_only": True})
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as error:
        where = (f"traceback in {log_file}" if log_file
                 else "--log-file FILE or --verbose shows the traceback")
        return _fail(prog, f"{type(error).__name__}: {error}", 1, args.verbose, f" ({where})")


if __name__ == "__main__":
    sys.exit(main())
