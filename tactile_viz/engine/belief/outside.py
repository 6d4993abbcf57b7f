"""The non-contacts' share of a pose fit, summed over the few that count.

A non-contact ``p`` (a missed probe's centre, or a point of the path it passed through)
costs a pose ``r = min(s(x) - c, 0)`` at ``x = R^T (p - t)``: only inside the shape grown
by the probe tip's radius ``c``. Its Jacobian row is that of a contact,
``-(a x n, n)`` with ``a = p - centre`` and ``n = R grad s(x)``
(:func:`~.pose_refinement.refine_poses`). Of the thousands of free points a long session
gathers, a pose has few inside (under 1% of the pairs in a learned cup met again): a
``below`` look-up finds them (:meth:`~.prior_bank.PriorBank.below` skips the points
outside a box about the shape unlooked), and only they are summed into the pose's
``J^T J``, ``J^T r`` and ``r^T r``, which is all the fit needs of them.
"""

import numpy as np

from ..transforms import inverse_transform_points_batch


def outside_terms(below, classes, rotations, translations, points, centre, clearance=0.0):
    """The non-contacts' sums ``r^T r``, ``J^T J`` and ``J^T r`` for each pose.

    Parameters
    ----------
    below : callable
        ``below(classes (k,), rotations (k, 3, 3), translations (k, 3), points (q, 3),
        level)`` -> ``pose (n,), point (n,), values (n,), gradients (n, 3)``: the pairs
        whose signed distance is below ``level``, with their values and outward unit
        gradients in the object frame (:meth:`~.prior_bank.PriorBank.below`,
        :func:`dense_below`).
    classes : (k,) int
    rotations : (k, 3, 3) float
        Object-to-world rotations.
    translations : (k, 3) float, world frame
    points : (q, 3) float, world frame
        The non-contacts.
    centre : (3,) float, world frame
        The point the fit's turns are about (the contacts' mean).
    clearance : float, length units
        The probe tip's radius.

    Returns
    -------
    cost : (k,) float, squared length units
        ``sum r^2`` over each pose's non-contacts.
    normal : (k, 6, 6) float
        ``J^T J``.
    gradient : (k, 6) float
        ``J^T r``.
    """
    k = len(classes)
    points = np.asarray(points, float).reshape(-1, 3)
    if not len(points):
        return np.zeros(k), np.zeros((k, 6, 6)), np.zeros((k, 6))
    rotations = np.asarray(rotations, float)
    pose, point, values, slopes = below(classes, rotations, translations, points, clearance)
    values = values - clearance  # r = min(s - c, 0), each below 0
    normals = np.einsum("kij,kj->ki", rotations[pose], slopes)  # n = R grad s
    rows = -np.concatenate([np.cross(points[point] - centre, normals), normals], axis=1)
    return (np.bincount(pose, values * values, minlength=k),
            _summed(pose, rows[:, :, None] * rows[:, None, :], k),
            _summed(pose, rows * values[:, None], k))


def dense_below(evaluate):
    """A ``below`` look-up for :func:`outside_terms` that evaluates every pair.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(classes (k,), points (k, q, 3))`` -> ``values (k, q), gradients
        (k, q, 3)``, object frame.
    """
    def below(classes, rotations, translations, points, level):
        local = inverse_transform_points_batch(points, rotations, translations)
        values, gradients = evaluate(np.asarray(classes), local)
        pose, point = np.nonzero(values - level < 0)
        return pose, point, values[pose, point], gradients[pose, point]

    return below


def _summed(pose, terms, k):
    """``terms (n, ...)`` summed by ``pose (n,)`` into ``(k, ...)``."""
    tail = terms.shape[1:]
    size = int(np.prod(tail))
    index = (pose[:, None] * size + np.arange(size)).ravel()
    return np.bincount(index, terms.ravel(), minlength=k * size).reshape((k,) + tail)
