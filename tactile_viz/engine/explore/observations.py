"""Tactile observations: contacts (position and outward normal) and non-contacts."""

from dataclasses import dataclass

import numpy as np

from ..errors import ObservationError

# Observations beyond this distance from the origin (object units; objects are 6 long) are
# refused: squaring their distances in the likelihood would overflow to infinity.
MAX_COORDINATE = 1e6


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


def _position(value, what):
    array = _vector(value, what)
    if np.abs(array).max() > MAX_COORDINATE:
        raise ObservationError(f"{what} is out of range (a coordinate beyond "
                               f"{MAX_COORDINATE:g} units): {array.tolist()}")
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
        object.__setattr__(self, "position", _position(self.position, "contact position"))
        normal = _vector(self.normal, "contact normal")
        if np.abs(normal).max() > 1e150:
            # The length of a huge vector overflows: divide by its largest component first.
            normal = normal / np.abs(normal).max()
        length = float(np.linalg.norm(normal))
        if not length > 1e-9:
            raise ObservationError("contact normal has zero length")
        normal = normal / length
        normal.flags.writeable = False
        object.__setattr__(self, "normal", normal)

    @classmethod
    def recorded(cls, position, normal):
        """A contact whose normal is kept bit for bit when it already has unit length
        (within 1e-9): dividing by a length of 1 +- 1 ulp changes the last bits, and a
        replayed recording must give the filter the very numbers of the original run."""
        contact = cls(position, normal)
        given = np.array(normal, dtype=float).reshape(-1)
        if abs(float(np.linalg.norm(given)) - 1.0) < 1e-9:
            given.flags.writeable = False
            object.__setattr__(contact, "normal", given)
        return contact


@dataclass(frozen=True, eq=False)
class NonContact:
    """The sensor reached ``position`` without touching anything (the point is outside).

    Attributes
    ----------
    position : (3,) float, world frame
    """

    position: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "position", _position(self.position, "non-contact position"))


def observation_arrays(observations):
    """Validated arrays from observations: contacts, their normals and non-contacts,
    ``(k, 3)`` float each, world frame.

    Raises
    ------
    ObservationError
        For anything that is not a Contact or NonContact (or a sequence of them).
    """
    if isinstance(observations, (Contact, NonContact)):
        observations = [observations]
    try:
        observations = list(observations)
    except TypeError:
        raise ObservationError(
            f"expected observations, got {type(observations).__name__}") from None
    contacts, normals, noncontacts = [], [], []
    for item in observations:
        if isinstance(item, Contact):
            contacts.append(item.position)
            normals.append(item.normal)
        elif isinstance(item, NonContact):
            noncontacts.append(item.position)
        else:
            raise ObservationError(f"expected Contact or NonContact, got {type(item).__name__}")
    return tuple(np.array(rows, dtype=float).reshape(-1, 3)
                 for rows in (contacts, normals, noncontacts))
