"""A session's lengths in scene units: the parameters' size units turned into the scene's.

Each length parameter is in size units, a sixth of an object's longest side
(:mod:`..params`). A session measures them in its MAP object's (docs/units.md); with
``own_size_share`` (off by default) a novel object much smaller than its MAP prior is
explored at its own size, since the prior's eps and contact spacing can be larger than the
object (a 2 cm block beside a 25 cm knife was stopped by the knife's 25 mm eps, and every
touch after the first few was given up within its 12.5 mm spacing). Plain functions, so
that the rule is tested without a session.
"""

import functools
from dataclasses import replace

import numpy as np
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.distance import pdist

from ..params import PAPER_SIZE, scaled_lengths

# What a novel object much smaller than its MAP prior measures in its own size unit
# (own_size_share): the stop's eps and the probes'. The GPIS's box, kernel and carve, and
# the decision, keep the prior's.
OWN_LENGTHS = ("eps", "probe_depth", "approach_clearance", "follow_step", "contact_spacing",
               "max_follow", "rrt_step")
# Fewer contacts span less than the object: a 10 cm mug judged novel at its third touch
# beside a 20 cm prior spanned 4.5 cm.
OWN_CONTACTS = 10


def own_unit(contacts, unit, share):
    """A novel object's own size unit: a sixth of its contacts' diameter (the largest
    distance between two of them), when that is under ``share`` of ``unit`` and there are
    at least :data:`OWN_CONTACTS` contacts; else None.

    The diameter, not a box's longest side: it does not depend on axes (a cube's principal
    axes are any three, and its box along them was 5-50% longer from one touch to the
    next), it only grows as contacts come, and it is the size a touch can tell before the
    object's corners are found.

    Parameters
    ----------
    contacts : (m, 3) float, scene units
    unit : float, scene units
        The MAP prior's size unit.
    share : float
        ``own_size_share`` (0: never).

    Returns
    -------
    float or None, scene units
    """
    contacts = np.ascontiguousarray(contacts, dtype=float)
    if share <= 0 or len(contacts) < OWN_CONTACTS:
        return None
    own = _diameter(contacts.tobytes()) / PAPER_SIZE
    return own if 0.0 < own < share * unit else None


@functools.lru_cache(maxsize=8)
def _diameter(data):
    # A step asks it several times of the same contacts. The farthest pair are corners of
    # their hull: its few vertices, not the m^2 / 2 pairs of a long session.
    points = np.frombuffer(data, dtype=float).reshape(-1, 3)
    try:
        points = points[ConvexHull(points).vertices]
    except QhullError:  # flat or on a line: every pair
        pass
    return float(pdist(points).max())


def session_lengths(params, unit, own=None, noise=0.0, tip_radius=0.0):
    """``params`` with their lengths in scene units.

    Parameters
    ----------
    params : SessionParams
        In size units.
    unit : float, scene units
        The size unit (the MAP object's).
    own : float, optional, scene units
        A novel object's own size unit (:func:`own_unit`): :data:`OWN_LENGTHS` are in it,
        and ``eps`` is its own within the noise, ``hypot(eps, cover_noise_stds noise)``,
        but at most ``unit``'s.
    noise : float, scene units
        The sensor's position noise (std).
    tip_radius : float, scene units
        A probe tip of radius r widens the carve of the space its centre passed through by
        r (the object was at least r away).

    Returns
    -------
    SessionParams
    """
    p = scaled_lengths(params, unit)
    if own is not None:
        mine = scaled_lengths(params, own)
        eps = min(p.eps, float(np.hypot(mine.eps, p.cover_noise_stds * noise)))
        p = replace(p, **{**{name: getattr(mine, name) for name in OWN_LENGTHS}, "eps": eps})
    if tip_radius:
        p = replace(p, gpis_carve_radius=p.gpis_carve_radius + tip_radius)
    return p
