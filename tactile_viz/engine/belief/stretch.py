"""A hypothesis's residuals weighed as a stretch of its shape (beyond the paper): a look-alike
of another size or proportion misfits as the prior stretched, noise does not.

A shape ``S`` stretched by ``I + E`` (``E`` symmetric and small) moves its surface point
``x`` of outward normal ``n`` out by ``n . E x``, so a right hypothesis's residuals
(contacts off its surface, positive outside) are noise about 0, and a look-alike's are::

    r_i = sum_ab E_ab n_ia x_ib + n_i . t + (x_i x n_i) . w + noise

with ``t``, ``w`` what is left of the pose fit (translation, small turn). Projected off
the pose's six columns, the six stretch coefficients ``beta`` of the regressors
``g_i = (n_x x, n_y y, n_z z, n_x y + n_y x, n_x z + n_z x, n_y z + n_z y)`` are
Gaussian about 0 for a right hypothesis, with covariance ``s^2 (G^T G)^-1`` (``s`` each
residual's noise) plus ``b^2 / L^2`` on each (``b`` what a place may share, as in
:mod:`.grouped`, over the contacts' RMS spread ``L``), so::

    T = beta^T Cov^-1 beta  ~  chi^2(6)

A 10 cm mug against its copy 4% larger at 2 mm / 2 degrees: ``beta`` 2-3.5% on each
axis, p 4e-11 at 200 contacts, where the place means of :mod:`.grouped` gave 1e-6 and the
chi-squared test of all residuals passed; the mug against itself: ``beta`` within 1.6%
from 30 contacts on, p 0.5-0.99.
"""

import numpy as np
from scipy.special import chdtrc

from ..transforms import inverse_transform_points_batch
from .pose_refinement import POSE_PARAMETERS

STRETCH_PARAMETERS = 6
RANK_TOLERANCE = 1e-9  # of the largest: directions of G^T G below it are not tested


def stretch_regressors(points, normals):
    """``(n, 6)`` float: each contact's residual per unit of the six stretch
    coefficients (``xx, yy, zz, xy, xz, yz``), in the frame and units of ``points``."""
    x, n = points, normals
    return np.column_stack([n[:, 0] * x[:, 0], n[:, 1] * x[:, 1], n[:, 2] * x[:, 2],
                            n[:, 0] * x[:, 1] + n[:, 1] * x[:, 0],
                            n[:, 0] * x[:, 2] + n[:, 2] * x[:, 0],
                            n[:, 1] * x[:, 2] + n[:, 2] * x[:, 1]])


def stretch_p(residuals, points, normals, noise2, shared2=0.0, trim=0.0):
    """The p-value of a hypothesis's stretch (see the module): how unlikely a right
    hypothesis leaves residuals this much like its shape stretched.

    Parameters
    ----------
    residuals : (n,) float
        Signed residuals of the contacts, scene units.
    points, normals : (n, 3) float
        The contacts and their measured outward unit normals in the hypothesis's object
        frame.
    noise2 : float
        Each residual's noise variance ``s^2``, squared scene units.
    shared2 : float
        What the contacts of a place may share, ``b^2``, squared scene units.
    trim : float
        Share of the contacts, the farthest off, left out (the pose fits' outliers).

    Returns
    -------
    p : float
        1 with too few contacts, a non-finite input or nothing to test (contacts on one
        plane test only what they can); 0 for a right hypothesis's variance of 0 with a
        stretch.
    beta : (6,) float
        The fitted stretch (``xx, yy, zz, xy, xz, yz``; 0.01: 1% larger than the shape).
    """
    residuals = np.asarray(residuals, dtype=float).reshape(-1)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    none = 1.0, np.zeros(STRETCH_PARAMETERS)
    if (len(residuals) <= POSE_PARAMETERS + STRETCH_PARAMETERS
            or not (np.all(np.isfinite(residuals)) and np.all(np.isfinite(points))
                    and np.all(np.isfinite(normals)))):
        return none
    kept = np.ones(len(residuals), bool)
    drop = int(np.ceil(trim * len(residuals)))
    if drop:
        kept[np.argsort(-np.abs(residuals), kind="stable")[:drop]] = False
    r, n = residuals[kept], normals[kept]
    x = points[kept] - points[kept].mean(axis=0)
    # The pose's columns (a ball's turns are none: x parallel to n), orthonormal.
    u, singular, _ = np.linalg.svd(np.column_stack([n, np.cross(x, n)]), full_matrices=False)
    pose = u[:, singular > np.sqrt(RANK_TOLERANCE) * max(float(singular.max()), 1e-300)]
    g = stretch_regressors(x, n)
    g = g - pose @ (pose.T @ g)                 # the pose fit takes what it can
    r = r - pose @ (pose.T @ r)
    eigenvalues, axes = np.linalg.eigh(g.T @ g)
    tested = eigenvalues > RANK_TOLERANCE * max(float(eigenvalues.max()), 1e-300)
    if not tested.any():
        return none
    w, v = eigenvalues[tested], axes[:, tested]
    coefficients = (v.T @ (g.T @ r)) / w        # least squares, along G^T G's axes
    beta = v @ coefficients
    spread2 = float(np.mean(np.sum(x**2, axis=1)))
    variance = float(noise2) / w + float(shared2) / max(spread2, 1e-300)
    if not np.all(variance > 0):
        return (0.0 if np.any(coefficients != 0) else 1.0), beta
    statistic = float(np.sum(coefficients**2 / variance))
    return float(chdtrc(int(tested.sum()), statistic)), beta


def contact_frame(pf, rotation, translation):
    """The filter's contacts and their measured normals in a pose's object frame,
    ``(n, 3)`` each."""
    points = inverse_transform_points_batch(pf.contact_positions, rotation[None],
                                            translation[None])[0]
    normals = inverse_transform_points_batch(pf.contact_normals, rotation[None])[0]
    return points, normals
