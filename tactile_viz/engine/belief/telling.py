"""Where to touch to tell plausible hypotheses apart (beyond the paper): the point of one
hypothesis's surface where a touch is expected to take the most posterior mass from the
others (:func:`disagreement_target`), for the hypotheses of a
:class:`~.decision.Decision`."""

import numpy as np
from scipy.spatial import cKDTree

from ..transforms import transform_points


def _posed_distance(bank, class_index, rotation, translation, points):
    """Signed distance of one class at a pose to world points: (m,) float."""
    values, _ = bank.evaluate(np.array([class_index]), ((points - translation) @ rotation)[None])
    return values[0]


def disagreement_target(bank, hypotheses, scale, avoid=(), crowd=(), candidates=None):
    """Where a touch tells the hypotheses apart best.

    Every candidate point ``x`` of every hypothesis ``k`` (posed) is one unless a point to
    avoid (a target the sensor could not reach, the path of a missed probe) lies within
    its radius. Its score is the posterior mass a touch there is expected to take from the
    wrong hypotheses::

        p_k sum_{j != k} p_j (1 - exp(-f_j(x)^2 / (2 s^2)))

    with ``f_j`` the signed distance of hypothesis ``j``, ``p`` the fit posteriors and
    ``s`` their noise scale: if ``k`` is right the touch lands at ``x`` and scales ``p_j``
    by ``exp(-f_j(x)^2 / 2 s^2)``. Bounded, unlike ``f_j^2``: a point far off a rival
    refutes it no better than one a few ``s`` off, and a likely hypothesis's surface (a
    contact expected) beats an unlikely one's (a miss expected, and a miss through a thin
    blade refutes little). For ``j`` of another class than ``k``, ``|f_j|`` is the smaller
    at ``j``'s pose and at ``k``'s: what their shapes differ in, not what a refit would
    absorb.

    Parameters
    ----------
    bank : PriorBank
    hypotheses : sequence of ~.decision.Hypothesis
        At least two.
    scale : float, scene units
        The fit posterior's noise scale ``s`` (:attr:`~.decision.Decision.scale`).
    avoid : sequence of ((m, 3) float, float)
        Points (world frame) where touching again would teach nothing, each set with its
        radius (scene units).
    crowd : sequence of ((m, 3) float, float)
        Points (world frame) touched or aimed at before, each set with its radius: every
        one within its radius halves a candidate's score. Under noise a second touch of
        the one part two shapes differ in (a screwdriver's tip) teaches as much as the
        first; without noise the first refutes the rival, or a refit absorbed it and
        ``f_j`` there is small.
    candidates : callable, optional
        ``candidates(class_index) -> (points (m, 3), normals (m, 3))``, object frame: the
        surface points a class offers as targets (default its feature points). The part
        that tells two shapes apart can be small (a screwdriver's tip): a few of 200
        feature points lie on it, and the spacing of the touches soon uses them up.

    Returns
    -------
    (position (3,), outward normal (3,), index of the hypothesis it lies on) or None
        None when no candidate would separate them.
    """
    points, normals, owner = [], [], []
    if candidates is None:
        candidates = lambda c: (bank.points[c], bank.normals[c])  # noqa: E731
    for k, h in enumerate(hypotheses):
        own_points, own_normals = candidates(h.class_index)
        points.append(transform_points(own_points, h.rotation, h.translation))
        normals.append(own_normals @ h.rotation.T)
        owner.append(np.full(len(points[-1]), k))
    points, normals, owner = np.vstack(points), np.vstack(normals), np.concatenate(owner)
    weights = np.array([h.probability for h in hypotheses])
    excluded = np.zeros(len(points), dtype=bool)
    for places, radius in avoid:
        if len(places):
            excluded |= cKDTree(places).query(points)[0] < radius
    halvings = np.zeros(len(points))
    for places, radius in crowd:
        if len(places):
            halvings += cKDTree(places).query_ball_point(points, radius, return_length=True)
    spread = np.zeros(len(points))
    live = np.flatnonzero(~excluded)  # the candidates that may still score best
    # Weight of the hypotheses after each one: what a candidate's spread can still gain.
    after = np.r_[np.cumsum(weights[::-1])[::-1][1:], 0.0]
    factor = weights[owner] * 0.5 ** halvings  # a candidate's score per unit of spread
    for j in range(len(hypotheses)):
        spread[live] += weights[j] * _refuted(bank, hypotheses, j, points, owner, live, scale)
        live = _still_possible(live, spread, factor, weights, owner, after[j], j)
    score = weights[owner] * spread
    score[excluded] = 0.0
    score *= 0.5 ** halvings
    best = int(np.argmax(score))
    if score[best] <= 0:
        return None
    return points[best], normals[best], int(owner[best])


def _refuted(bank, hypotheses, j, points, owner, live, scale):
    """``1 - exp(-f_j^2 / 2 s^2)`` at the candidates ``live`` (0 on ``j``'s own)."""
    h = hypotheses[j]
    chosen, whose = points[live], owner[live]
    distance = np.abs(_posed_distance(bank, h.class_index, h.rotation, h.translation, chosen))
    # Twins in a shared frame differ in shape, not in where each fits best: a rival
    # tilted to absorb the contacts disagrees far along a shared handle, but a touch
    # there is absorbed again by the next fit.
    for k, other in enumerate(hypotheses):
        mine = whose == k
        if other.class_index != h.class_index and mine.any():
            at_theirs = _posed_distance(bank, h.class_index, other.rotation,
                                        other.translation, chosen[mine])
            distance[mine] = np.minimum(distance[mine], np.abs(at_theirs))
    refuted = -np.expm1(-np.square(distance) / (2 * max(scale, 1e-300) ** 2))
    return refuted * (whose != j)


def _still_possible(live, spread, factor, weights, owner, rest, j):
    """The candidates of ``live`` whose score, with every hypothesis after ``j`` still to
    refute, can reach the best one's so far: each adds at most its weight. The others
    are dropped, so the distances of the hypotheses left are looked up only where they
    can change the choice; the choice is the same."""
    whose = owner[live]
    sure = factor[live] * spread[live]  # the score so far: it only grows
    gain = rest - np.where(whose > j, weights[whose], 0.0)  # hypothesis k does not refute k
    bound = factor[live] * (spread[live] + np.maximum(gain, 0.0)) * (1.0 + 1e-9)
    return live[bound >= sure.max(initial=0.0)]
