"""The desktop app's model, without Qt: what the window shows and lets the user steer.

:mod:`tactile_viz.app.scene` holds the user's choices (truth object and pose, which priors
are ticked, names for learned priors, the knobs the window offers) and the running
:class:`~tactile_viz.engine.Session`; :mod:`tactile_viz.gui` draws it with Qt and pyvista.
Nothing here imports Qt, pyvista or vtk; a test enforces it.
"""

from .scene import FILTER_KNOBS, SESSION_KNOBS, Scene, Signal

__all__ = ["FILTER_KNOBS", "SESSION_KNOBS", "Scene", "Signal"]
