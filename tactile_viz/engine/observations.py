"""Tactile observations: contacts (position and outward normal) and non-contacts."""

from dataclasses import dataclass

import numpy as np

from .errors import ObservationError


def _vector(value, what):
    try:
        array = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as error:
        raise ObservationError(f"{what} is not numeric ({error})") from error
    if array.shape != (3,):
        raise ObservationError(f"{what} must have 3 components, got {array.size}")
    if not np.isfinite(array).all():
        raise ObservationError(f"{what} is not finite: {array.tolist()}")
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class Contact:
    """The sensor touched the surface.

    Attributes
    ----------
    position : (3,) float, world frame
    normal : (3,) float, world frame, unit length (renormalised on entry)
    """

    position: np.ndarray
    normal: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "position", _vector(self.position, "contact position"))
        normal = _vector(self.normal, "contact normal")
        length = float(np.linalg.norm(normal))
        if not length > 1e-9:
            raise ObservationError("contact normal has zero length")
        normal = normal / length
        normal.flags.writeable = False
        object.__setattr__(self, "normal", normal)


@dataclass(frozen=True, eq=False)
class NonContact:
    """The sensor reached ``position`` without touching anything (the point is outside).

    Attributes
    ----------
    position : (3,) float, world frame
    """

    position: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "position", _vector(self.position, "non-contact position"))
