"""Compiled inner loops of the likelihood over many hypotheses (numba).

The particle filter scores tens of thousands of hypotheses on tens of observations each
step. In numpy every operation of the trilinear look-up makes a temporary array of
``hypotheses x observations`` elements; these loops move each observation into each
hypothesis's object frame, interpolate its class's grid and add up its log-likelihood in
one pass, with nothing but the result allocated. They compute exactly what
:func:`~tactile_viz.engine.shape.sdf.interpolate` and
:mod:`~tactile_viz.engine.belief.likelihood` do (a test holds them to it).
"""

import math

import numpy as np
from numba import njit

from ..shape.sdf import grid_lookup as _lookup

_TINY = 1e-12  # as sdf._TINY: below it a gradient vanishes


@njit(cache=True)
def contact_log_likelihoods(codes, gradient_codes, offsets, shapes, origins, spacings, steps,
                            classes, rotations, translations, points, normals, sigma_d,
                            sigma_n, log_z, outlier_probability, outlier_log_density):
    """Summed contact log-likelihood of each hypothesis.

    Parameters
    ----------
    codes, gradient_codes, offsets, shapes, origins, spacings, steps
        The prior bank's arrays.
    classes : (k,) int
    rotations : (k, 3, 3) float
    translations : (k, 3) float
        ``object_to_world`` of each hypothesis.
    points, normals : (m, 3) float, world frame
    sigma_d, sigma_n, log_z : float
    outlier_probability, outlier_log_density : float
        The mixture's ``eps`` (0: the Gaussian alone) and ``log(exp(-OUTLIER_NATS) / Z)``.

    Returns
    -------
    (k,) float
    """
    k, m = len(classes), len(points)
    total = np.zeros(k)
    keep = math.log1p(-outlier_probability) if outlier_probability > 0 else 0.0
    flat = math.log(outlier_probability) + outlier_log_density if outlier_probability > 0 else 0.0
    for i in range(k):
        c = classes[i]
        r = rotations[i]
        t = translations[i]
        acc = 0.0
        for j in range(m):
            dx, dy, dz = points[j, 0] - t[0], points[j, 1] - t[1], points[j, 2] - t[2]
            # object frame: R^T (x - t); the observed normal: R^T n
            x = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
            y = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            z = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            nx = r[0, 0] * normals[j, 0] + r[1, 0] * normals[j, 1] + r[2, 0] * normals[j, 2]
            ny = r[0, 1] * normals[j, 0] + r[1, 1] * normals[j, 1] + r[2, 1] * normals[j, 2]
            nz = r[0, 2] * normals[j, 0] + r[1, 2] * normals[j, 1] + r[2, 2] * normals[j, 2]
            value, gx, gy, gz = _lookup(codes, gradient_codes, offsets[c], shapes[c],
                                        origins[c], spacings[c], steps[c], x, y, z)
            norm = math.sqrt(gx * gx + gy * gy + gz * gz)
            if norm > _TINY:
                gx, gy, gz = gx / norm, gy / norm, gz / norm
            else:
                gx, gy, gz = 0.0, 0.0, 1.0
            error = (gx - nx) ** 2 + (gy - ny) ** 2 + (gz - nz) ** 2
            gaussian = -0.5 * ((value / sigma_d) ** 2 + error / sigma_n ** 2) - log_z
            if outlier_probability > 0:
                a, b = keep + gaussian, flat
                high = max(a, b)
                gaussian = high + math.log1p(math.exp(min(a, b) - high))
            acc += gaussian
        total[i] = acc
    return total


@njit(cache=True)
def distances(codes, gradient_codes, offsets, shapes, origins, spacings, steps, classes,
              rotations, translations, points):
    """Signed distance of each world point under each hypothesis: (k, m) float."""
    k, m = len(classes), len(points)
    out = np.empty((k, m))
    for i in range(k):
        c = classes[i]
        r = rotations[i]
        t = translations[i]
        for j in range(m):
            dx, dy, dz = points[j, 0] - t[0], points[j, 1] - t[1], points[j, 2] - t[2]
            x = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
            y = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            z = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            out[i, j] = _lookup(codes, gradient_codes, offsets[c], shapes[c], origins[c],
                                spacings[c], steps[c], x, y, z)[0]
    return out


@njit(cache=True)
def align(frames, points, classes, first, second, observed_rotations, observed_translations,
          observed_alpha, query):
    """Poses putting model pairs onto observed pairs (what :func:`~.ppf.align_pairs` computes).

    Parameters
    ----------
    frames : (C, F, 3, 3) float
        Each feature point's rotation of its normal onto +x.
    points : (C, F, 3) float
    classes, first, second : (k,) int
        Each model pair: its class and feature points.
    observed_rotations, observed_translations, observed_alpha : (q, 3, 3), (q, 3), (q,)
        The observed pairs' :func:`~.ppf.local_frames`.
    query : (k,) int
        The observed pair of each model pair.

    Returns
    -------
    rotations : (k, 3, 3)
    translations : (k, 3)
    """
    k = len(classes)
    rotations = np.empty((k, 3, 3))
    translations = np.empty((k, 3))
    turned = np.empty((3, 3))
    shifted = np.empty(3)
    for i in range(k):
        rm = frames[classes[i], first[i]]
        p1 = points[classes[i], first[i]]
        p2 = points[classes[i], second[i]]
        d0, d1, d2 = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
        alpha_m = -math.atan2(rm[2, 0] * d0 + rm[2, 1] * d1 + rm[2, 2] * d2,
                              rm[1, 0] * d0 + rm[1, 1] * d1 + rm[1, 2] * d2)
        q = query[i]
        rs, ts = observed_rotations[q], observed_translations[q]
        angle = alpha_m - observed_alpha[q]
        cos, sin = math.cos(angle), math.sin(angle)
        for col in range(3):  # R_x(angle) R_m
            turned[0, col] = rm[0, col]
            turned[1, col] = cos * rm[1, col] - sin * rm[2, col]
            turned[2, col] = sin * rm[1, col] + cos * rm[2, col]
        # object_to_world = T_g(s)^-1 R_x T_g(m): R = R_s^T R_x R_m,
        # t = R_s^T (-(R_x R_m) p1 - t_s)
        for row in range(3):
            shifted[row] = -(turned[row, 0] * p1[0] + turned[row, 1] * p1[1]
                             + turned[row, 2] * p1[2]) - ts[row]
        for row in range(3):
            for col in range(3):
                rotations[i, row, col] = (rs[0, row] * turned[0, col] + rs[1, row] * turned[1, col]
                                          + rs[2, row] * turned[2, col])
            translations[i, row] = (rs[0, row] * shifted[0] + rs[1, row] * shifted[1]
                                    + rs[2, row] * shifted[2])
    return rotations, translations


@njit(cache=True)
def pairs_below(codes, gradient_codes, offsets, shapes, origins, spacings, steps, classes,
                rotations, translations, points, low, high, level, pose, point, value,
                gradient):
    """The ``(hypothesis, point)`` pairs whose signed distance is below ``level``.

    A point outside its hypothesis's class box ``low``-``high`` (object frame) is taken
    to lie above ``level`` unlooked (:meth:`~.prior_bank.PriorBank.near_boxes`). The
    pairs found are written to ``pose``, ``point`` (int), ``value`` and ``gradient``
    (object frame, unit length), each at least ``k m`` long, in order of hypothesis then
    point.

    Returns
    -------
    int
        How many pairs were written.
    """
    found = 0
    for i in range(len(classes)):
        c = classes[i]
        r = rotations[i]
        t = translations[i]
        for j in range(len(points)):
            dx, dy, dz = points[j, 0] - t[0], points[j, 1] - t[1], points[j, 2] - t[2]
            x = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
            if x < low[c, 0] or x > high[c, 0]:
                continue
            y = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            if y < low[c, 1] or y > high[c, 1]:
                continue
            z = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            if z < low[c, 2] or z > high[c, 2]:
                continue
            distance, gx, gy, gz = _lookup(codes, gradient_codes, offsets[c], shapes[c],
                                           origins[c], spacings[c], steps[c], x, y, z)
            if not distance - level < 0:
                continue
            norm = math.sqrt(gx * gx + gy * gy + gz * gz)
            if norm > _TINY:
                gx, gy, gz = gx / norm, gy / norm, gz / norm
            else:
                gx, gy, gz = 0.0, 0.0, 1.0
            pose[found], point[found], value[found] = i, j, distance
            gradient[found, 0], gradient[found, 1], gradient[found, 2] = gx, gy, gz
            found += 1
    return found
