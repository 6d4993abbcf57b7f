"""The groups of the Controls dock, one widget each.

Each panel builds its own widgets, emits a signal per user action and has a ``sync`` method
that fills its widgets from the :class:`~tactile_viz.app.scene.Scene` without emitting any
signal; the main window connects the signals to the scene and calls ``sync`` when the scene
changes.
"""

from .exploration_panel import PARAMETERS, ExplorationPanel
from .layers_panel import LayersPanel
from .loop_panel import LoopPanel, status_text
from .priors_panel import PriorsPanel
from .scene_panel import OPEN_FILE, ScenePanel

__all__ = ["ExplorationPanel", "LayersPanel", "LoopPanel", "OPEN_FILE", "PARAMETERS",
           "PriorsPanel", "ScenePanel", "status_text"]
