"""Pieces every command line of the package shares: list options whose repeats add up, and
logging (``--verbose``, ``--log-file``).

Qt-free and light: the engine's commands, the benchmarks and ``app.py`` all use it.
"""

import argparse
import logging
import os
import sys
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


class _CurrentStderr(logging.StreamHandler):
    """A handler that writes to whatever ``sys.stderr`` is when a message comes (pytest and
    some GUIs replace it after logging is set up)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass


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
