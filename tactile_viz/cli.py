"""Pieces every command line of the package shares: list options whose repeats add up, and
logging (``--verbose``, ``--log-file``).

Qt-free and light: the engine's commands, the benchmarks and ``app.py`` all use it.
"""

import argparse
import logging
import os
from pathlib import Path

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


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


def default_log_file():
    """``$XDG_STATE_HOME/tactile_viz/app.log``, else ``~/.local/state/tactile_viz/app.log``."""
    base = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(base) / "tactile_viz" / "app.log"


def add_logging_arguments(parser, log_file_default=None):
    """``--verbose`` (debug messages on stderr) and ``--log-file FILE`` (every message there)."""
    parser.add_argument("--verbose", "-v", action="store_true",
                        help="log debug messages on stderr (default: warnings and errors)")
    where = f" (default {log_file_default})" if log_file_default else ""
    parser.add_argument("--log-file", metavar="FILE", default=log_file_default,
                        help=f"also append every log message to this file{where}")


def setup_logging(verbose=False, log_file=None):
    """Configure the ``tactile_viz`` loggers: stderr at WARNING (DEBUG with ``verbose``), and
    ``log_file`` (appended, at DEBUG) when given. A log file that cannot be opened is reported
    on stderr and skipped: logging never stops the program. Returns the log file's path or
    None."""
    root = logging.getLogger("tactile_viz")
    for handler in list(root.handlers):
        if getattr(handler, "_tactile_viz", False):
            root.removeHandler(handler)
            handler.close()
    root.setLevel(logging.DEBUG)
    root.propagate = False
    console = logging.StreamHandler()
    console.setLevel(logging.DEBUG if verbose else logging.WARNING)
    console.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    handlers = [console]
    opened = None
    if log_file:
        try:
            Path(log_file).parent.mkdir(parents=True, exist_ok=True)
            handler = logging.FileHandler(log_file, encoding="utf-8")
        except OSError as error:
            root.addHandler(console)
            console._tactile_viz = True
            root.warning("cannot write the log file %s: %s", log_file, error)
            return None
        handler.setLevel(logging.DEBUG)
        handler.setFormatter(logging.Formatter(LOG_FORMAT))
        handlers.append(handler)
        opened = Path(log_file)
    for handler in handlers:
        handler._tactile_viz = True
        root.addHandler(handler)
    return opened
