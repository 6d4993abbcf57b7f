"""Which hypothesis a decision is about: its *lead* (beyond the paper).

The filter's MAP particle proposes it; the refined fits may overrule it, within limits
that keep normals alone from moving the decision (docs/decision.md): a pose of the same
class that the contacts' positions prefer at the confidence (:func:`particle_lead`), and
with ``decision_any_class`` a hypothesis of another class that the fit posterior holds
(:func:`class_lead`): only the last touch's most probable hypothesis's class, whose
flips are weighed (:func:`fit_leader`).
"""

import numpy as np


def margin(scale2, confidence):
    """How much lower a hypothesis's squared residuals must be to be preferred at
    ``confidence`` on positions alone: ``2 s^2 log(1 / (1 - confidence))``."""
    return 2 * scale2 * np.log(1 / (1 - confidence))


def particle_lead(hypotheses, scale2, confidence):
    """The hypothesis a decision is about: the MAP particle's, or a pose of its class that
    the contacts' positions alone prefer to it at ``confidence`` (their squared residuals
    lower by ``2 s^2 log(1 / (1 - confidence))``), the most probable such.

    The filter's broad likelihood can leave the class's heaviest particle in a turn that
    another of its poses fits far better (a bumpy ball's, 60-180 degrees off for 120
    steps). Normals alone, or an equal fit, must not move the decision: a fork was decided
    as a knife and a flat screwdriver as the cross so (docs/decision.md)."""
    first, lower = hypotheses[0], margin(scale2, confidence)
    better = [h for h in hypotheses[1:]
              if h.class_index == first.class_index and h.misfit <= first.misfit - lower]
    return max(better, key=lambda h: h.probability) if better else first


def class_lead(hypotheses, lead, scale2, confidence, posterior, names, limit):
    """The hypothesis of another class than ``lead``'s that the decision is about instead,
    or ``lead``: one whose fit posterior, positions and normals, holds ``confidence``,
    that fits within the noise (its squared residuals within ``limit(class)``), whose
    positions fit no worse than the lead's beyond the :func:`margin`, and whose class the
    filter holds at least ``1 - confidence`` of (``posterior`` by ``names``).

    The filter's likelihood is broad (``sigma_d``, 8% of the size): on a table a fork's
    tines, out of a 5 mm tip's reach between them, fit a knife's blade, and its MAP turned
    between the two from touch to touch, while the refined fits held the fork at 1.000 by
    the normals of its tines. A lead that only its normals prefer while its positions fit
    worse is refused (a knife 6 degrees off leading by its normals with seven times the
    residuals was decided once)."""
    worse = margin(scale2, confidence)
    better = [h for h in hypotheses if h.class_index != lead.class_index
              and h.probability >= confidence and h.misfit <= lead.misfit + worse
              and h.misfit <= limit(h.class_index)
              and posterior.get(names[h.class_index], 0.0) >= 1 - confidence]
    return better[0] if better else lead


def fit_leader(carried, map_class):
    """The last touch's most probable hypothesis, as ``(class, rotation, translation)``,
    when it is of another class than ``map_class`` (else None): its flips are weighed
    too, and only its class may lead the decision (:func:`class_lead`), its upside-down
    modes then open rivals."""
    best = max(carried, key=lambda h: h.probability, default=None)
    if best is None or best.class_index == map_class:
        return None
    return best.class_index, best.rotation, best.translation
