"""What the Controls panels share: blocking signals while a panel is filled, group layout."""

from contextlib import ExitStack, contextmanager

from PySide6.QtCore import QSignalBlocker

MARGINS = (6, 4, 6, 4)  # a panel's contents margins, pixels


@contextmanager
def blocked(*objects):
    """Block the signals of some QObjects within a ``with`` block (a QSignalBlocker each).

    Parameters
    ----------
    *objects : QObject
        The widgets (or actions) whose signals are silent inside the block.
    """
    with ExitStack() as stack:
        for item in objects:
            stack.enter_context(QSignalBlocker(item))
        yield
