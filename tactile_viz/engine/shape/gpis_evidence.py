"""An object-agnostic GPIS prior mean and the evidence that chooses between prior means
(beyond the paper).

The paper's prior mean is the MAP shape. When the library holds nothing like the object
(a ball against a mug, a 2 cm block against 10 cm priors) that shape keeps what nothing
supports: the mug's cavity inside the ball. An ellipsoid fitted to the contacts is the
classic object-agnostic GPIS prior (Williams and Fitzgibbon 2007 used a sphere). The
GP's marginal likelihood of the contacts tells the two apart: with the same kernel, scale
and noise, only the term ``-1/2 r^T K^-1 r`` of the residual ``r = D - mu(X)`` depends on
the prior mean ``mu``.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.optimize import nnls

SHRINK_TOWARD_CENTROID = 0.05  # weight (per contact) pulling the centre to the centroid
MAX_RADIUS_FACTOR = 2.0  # a radius is at most this many times the contacts' extent
TINY = 1e-12


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """An ellipsoid as a GPIS prior mean: ``prior(points) -> (values, gradients)``.

    Attributes
    ----------
    centre : (3,) float, world frame
    axes : (3, 3) float
        Columns are its principal directions (a rotation), world frame.
    radii : (3,) float, scene units
        Its semi-axes along ``axes``.
    """

    centre: np.ndarray
    axes: np.ndarray
    radii: np.ndarray

    def __call__(self, points):
        """Approximate signed distances (k,) and unit outward gradients (k, 3) at
        ``points`` (k, 3): ``k0 (k0 - 1) / k1`` with ``k0 = |y / r|`` and
        ``k1 = |y / r^2|`` in the ellipsoid's frame (exact on a sphere, exact at the
        surface's sign and zero level everywhere)."""
        local = (np.atleast_2d(np.asarray(points, dtype=float)) - self.centre) @ self.axes
        k0 = np.linalg.norm(local / self.radii, axis=1)
        toward = local / self.radii**2
        k1 = np.linalg.norm(toward, axis=1)
        centred = k1 < TINY
        values = np.where(centred, -self.radii.min(),
                          k0 * (k0 - 1) / np.maximum(k1, TINY))
        normals = toward / np.maximum(k1, TINY)[:, None]
        normals[centred] = (0.0, 0.0, 1.0)
        return values, normals @ self.axes.T


def fit_ellipsoid(points, normals, min_radius):
    """The ellipsoid the contacts lie on, as a GPIS prior mean.

    The centre is the point nearest every contact's normal line (they meet at a sphere's
    centre), pulled toward the contacts' centroid where the normals leave it open (a flat
    face's all agree); the axes are the contacts' principal directions about it; the
    radii solve ``sum_k y_k^2 / r_k^2 = 1`` at the contacts by non-negative least squares
    in ``1 / r_k^2``, each within ``[min_radius, 2 x`` the contacts' extent along its axis
    ``+ min_radius]`` (an axis the contacts do not bound gets that extent).

    Parameters
    ----------
    points, normals : (n, 3) float, world frame
        Contact positions and outward unit normals.
    min_radius : float, scene units
        The smallest semi-axis (> 0).

    Returns
    -------
    Ellipsoid or None
        None with fewer than 4 contacts.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    if len(points) < 4:
        return None
    centroid = points.mean(axis=0)
    across = np.eye(3)[None] - normals[:, :, None] * normals[:, None, :]  # I - n n^T
    pull = SHRINK_TOWARD_CENTROID * len(points)
    matrix = across.sum(axis=0) + pull * np.eye(3)
    centre = np.linalg.solve(matrix, np.einsum("kij,kj->i", across, points) + pull * centroid)
    offsets = points - centre
    _, axes = np.linalg.eigh(offsets.T @ offsets)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    local = offsets @ axes
    extent = np.abs(local).max(axis=0)
    inverse_squares, _ = nnls(local**2, np.ones(len(points)))
    radii = np.where(inverse_squares > TINY,
                     1.0 / np.sqrt(np.maximum(inverse_squares, TINY)), extent)
    radii = np.clip(radii, min_radius, MAX_RADIUS_FACTOR * extent + min_radius)
    return Ellipsoid(centre, axes, radii)


def contact_evidence(fit, prior, points, normals):
    """The part of the log marginal likelihood of the contacts that depends on the prior
    mean, ``-1/2 r^T K^-1 r`` with ``r`` their [value, gradient] observations less
    ``prior``, at ``fit``'s kernel, scale and noise (nats; comparable between priors for
    one fit only).

    The contacts are the first rows of ``fit`` and all four components of each are
    observed, so the leading block of its Cholesky factor is the factor of theirs.

    Parameters
    ----------
    fit : GPISFit
        Fitted to ``points`` (and maybe non-contacts after them).
    prior : callable
        ``prior(points) -> (values (n,), gradients (n, 3))``.
    points, normals : (n, 3) float, world frame
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    rows = 4 * len(points)
    if rows == 0:
        return 0.0
    values, gradients = prior(points)
    observed = np.column_stack([np.zeros(len(points)), normals])
    residual = (observed - np.column_stack([values, gradients])).ravel()
    whitened = solve_triangular(fit.factor[:rows, :rows], residual, lower=True,
                                check_finite=False)
    return float(-0.5 * whitened @ whitened)
