"""A session's lengths in scene units: the parameters' size units turned into the scene's.

Each length parameter is in size units, a sixth of an object's longest side
(:mod:`..params`). A session measures them in its MAP object's (docs/units.md); with
``own_size_share`` (0.5 by default, 0 in ``paper``) a novel object much smaller or larger
than its MAP prior is explored at its own size. The prior's eps and contact spacing can be
larger than a small object (a 2 cm block beside a 25 cm knife was stopped by the knife's
25 mm eps, and every touch after the first few was given up within its 12.5 mm spacing),
and a large object's touches must then cover it finer than its own eps (a 15 cm elephant
under a 10 cm mug's 10 mm eps ran to its 400-touch cap). Plain functions, so that the
rule is tested without a session."""

import functools
from dataclasses import replace

import numpy as np

from ..params import PAPER_SIZE, scaled_lengths
from ..shape.metrics import diameter

# What a novel object much smaller or larger than its MAP prior measures in its own size unit
# (own_size_share): the stop's eps and the probes'. The GPIS's box, kernel and carve, and
# the decision, keep the prior's.
OWN_LENGTHS = ("eps", "probe_depth", "approach_clearance", "follow_step", "contact_spacing",
               "max_follow", "rrt_step")
# Fewer contacts span less than the object: a 10 cm mug judged novel at its third touch
# beside a 20 cm prior spanned 4.5 cm.
OWN_CONTACTS = 10
# A span still growing is not yet the object's: a 20 cm fork's first contacts spanned 3 to
# 8 cm over five touches, and its lengths switched to theirs. The span counts once the
# last OWN_CONTACTS contacts widened it by at most this share.
OWN_GROWTH = 0.1
# A judgement that flickers is not the object's: a learned 20 cm fork met again was judged
# novel at single steps among known ones, its few contacts spanning 3 cm, and its lengths
# switched there. Own lengths wait until this many steps in a row judged it novel.
OWN_STEPS = 10
# An object is larger than its prior when its contacts span more than this many times the
# prior's diameter, and smaller when they span less than the prior's diameter over it.
# Objects of one longest side differ in diameter by up to a fifth (the bundled objects'
# diameters are 1.0 to 1.19 times their longest side): an object of its prior's size
# keeps its lengths.
OWN_LARGER = 1.25
# A span between the share and the prior's diameter over OWN_LARGER counts once it held
# over this many contacts: nearer the prior's size a settled span is more often a part of
# the object's (a 7.2-unit chair's first 28 contacts spanned 4.6 units for ten touches).
OWN_SETTLE = 40


def novel_for_long(judgements):
    """Whether the last :data:`OWN_STEPS` of the steps' novelty ``judgements`` (oldest
    first) all judged the object novel."""
    recent = list(judgements)[-OWN_STEPS:]
    return len(recent) == OWN_STEPS and all(recent)


def own_unit(contacts, unit, share, prior_diameter=None):
    """A novel object's own size unit: a sixth of its contacts' diameter (the largest
    distance between two of them), when that is under ``share`` of ``unit``'s object or
    over :data:`OWN_LARGER` times ``prior_diameter``, there are more than
    :data:`OWN_CONTACTS` contacts and the last :data:`OWN_CONTACTS` of them widened the
    diameter by at most :data:`OWN_GROWTH`; or when it is under ``prior_diameter`` over
    :data:`OWN_LARGER` and the last :data:`OWN_SETTLE` contacts widened it by at most
    that; else None.

    The diameter, not a box's longest side: it does not depend on axes (a cube's principal
    axes are any three, and its box along them was 5-50% longer from one touch to the
    next), it only grows as contacts come, and it is the size a touch can tell before the
    object's corners are found.

    Parameters
    ----------
    contacts : (m, 3) float, scene units
        In the order they were touched.
    unit : float, scene units
        The MAP prior's size unit.
    share : float
        ``own_size_share`` (0: never).
    prior_diameter : float, optional, scene units
        The MAP prior's diameter (:attr:`~..shape.objects.ObjectModel.diameter`);
        without it only an object under ``share`` of the prior has its own unit.

    Returns
    -------
    float or None, scene units
    """
    contacts = np.ascontiguousarray(contacts, dtype=float)
    if share <= 0 or len(contacts) <= OWN_CONTACTS:
        return None
    span = _diameter(contacts.tobytes())
    smaller = 0.0 < span < share * unit * PAPER_SIZE
    larger = prior_diameter is not None and span > OWN_LARGER * prior_diameter
    settle = OWN_CONTACTS
    if not (smaller or larger) and prior_diameter is not None:
        # A 10 cm mug under a 15 cm prior's eps (15% of the mug) stopped with its
        # estimate 11 mm inside the wall on its untouched handle side.
        smaller, settle = 0.0 < span < prior_diameter / OWN_LARGER, OWN_SETTLE
    if not (smaller or larger) or len(contacts) <= settle:
        return None
    before = _diameter(contacts[:-settle].tobytes())
    return span / PAPER_SIZE if before >= (1.0 - OWN_GROWTH) * span else None


@functools.lru_cache(maxsize=8)
def _diameter(data):
    # A step asks it several times of the same contacts.
    return diameter(np.frombuffer(data, dtype=float))


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
        but at most ``unit``'s when ``own`` is the smaller.
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
        eps = float(np.hypot(mine.eps, p.cover_noise_stds * noise))
        eps = eps if own > unit else min(p.eps, eps)
        p = replace(p, **{**{name: getattr(mine, name) for name in OWN_LENGTHS}, "eps": eps})
    if tip_radius:
        p = replace(p, gpis_carve_radius=p.gpis_carve_radius + tip_radius)
    return p
