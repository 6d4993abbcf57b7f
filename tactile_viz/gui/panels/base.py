"""What the Controls panels share: blocking signals while a panel is filled, group layout."""

from contextlib import ExitStack, contextmanager

from PySide6.QtCore import QSignalBlocker, Qt
from PySide6.QtWidgets import QScrollArea, QVBoxLayout, QWidget

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


def scrolled(groups):
    """A scroll area that stacks ``(group, stretch)`` pairs and never scrolls sideways (it
    scrolls down only in a window too small for the groups)."""
    panel = QWidget()
    layout = QVBoxLayout(panel)
    layout.setContentsMargins(4, 0, 4, 4)
    layout.setSpacing(4)
    for group, stretch in groups:
        layout.addWidget(group, stretch)
    scroll = QScrollArea()
    scroll.setWidget(panel)
    scroll.setWidgetResizable(True)
    scroll.setFrameShape(QScrollArea.NoFrame)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
    # As wide as the panel wants plus a vertical scroll bar: nothing clipped sideways.
    scroll.setMinimumWidth(panel.sizeHint().width()
                           + scroll.verticalScrollBar().sizeHint().width() + 4)
    return scroll
