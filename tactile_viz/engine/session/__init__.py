"""The inference session (Algorithm 2): :class:`Session` in :mod:`.loop`, its planner,
estimate, learning and state in modules of their own."""

from ..errors import SessionError
from ..params import SessionParams
from ..presets import SESSION_PRESETS, session_preset
from .fields import (
    BelowTangentPlane,
    PosedSDF,
    ValueOf,
    deepest_inside,
    free_approach,
    free_space_points,
    thin_points,
)
from .learning import learned_model_from_surface
from .loop import Session, make_truth
from .recorded import RecordedSession
from .snapshot import Move, Reconstruction, Snapshot
from .state import Aim, Check, ExplorationState

__all__ = ["Aim", "BelowTangentPlane", "Check", "ExplorationState", "Move", "PosedSDF",
           "Reconstruction", "RecordedSession", "SESSION_PRESETS", "Session", "SessionError",
           "SessionParams", "Snapshot", "ValueOf", "deepest_inside", "free_approach",
           "free_space_points", "learned_model_from_surface", "make_truth", "session_preset",
           "thin_points"]
