"""Gaussian process implicit surface with derivative observations (paper, Section III-E).

Each contact is an observation of the implicit function ``f`` and its gradient at a point:
value 0 and gradient equal to the observed normal (4 numbers). The prior mean is the MAP
object's signed distance and gradient, so the posterior keeps the prior's shape where there
are no data and bends it through the contacts. The thin-plate kernel

    k(x, x') = a (2 r^3 - 3 R r^2 + R^3),  r = |x - x'|

with its first and second derivatives gives the covariance of values and gradients. ``R``
must exceed the largest distance between any two points involved by a margin (at
``R = max distance`` the Gram matrix is indefinite), and the scale ``a`` takes one Newton
step on the log marginal likelihood per fit, in ``log a`` so that it stays positive.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular
from scipy.linalg.lapack import dpotri
from scipy.spatial.distance import cdist
from skimage.measure import marching_cubes

_CHUNK = 4096  # query points per kernel block
_LOG_2PI = np.log(2 * np.pi)


def kernel_blocks(x, y, radius):
    """Thin-plate covariance (``a = 1``) between [value, gradient] observations.

    Parameters
    ----------
    x : (p, 3) float
    y : (q, 3) float
    radius : float
        ``R``; larger than every distance between points of ``x`` and ``y``.

    Returns
    -------
    (4p, 4q) float
        Row ``4 i + c`` is component ``c`` (0 value, 1-3 gradient) at ``x[i]``, likewise for
        columns and ``y``.
    """
    diff = x[:, None, :] - y[None, :, :]
    r = np.linalg.norm(diff, axis=-1)
    blocks = np.empty(r.shape + (4, 4))
    blocks[..., 0, 0] = 2 * r**3 - 3 * radius * r**2 + radius**3
    first = 6 * diff * (r - radius)[..., None]
    blocks[..., 1:, 0] = first            # cov(df(x)/dx_i, f(y))
    blocks[..., 0, 1:] = -first           # cov(f(x), df(y)/dy_j)
    # (x_i - y_i)(x_j - y_j) / r tends to 0 as r -> 0.
    safe = np.where(r > 0, r, 1.0)
    outer = np.where((r > 0)[..., None, None],
                     diff[..., :, None] * diff[..., None, :] / safe[..., None, None], 0.0)
    blocks[..., 1:, 1:] = -6 * (outer + np.eye(3) * (r - radius)[..., None, None])
    p, q = r.shape
    return blocks.transpose(0, 2, 1, 3).reshape(4 * p, 4 * q)


def value_rows(x, y, radius):
    """Covariance of values at ``x`` with [value, gradient] at ``y`` (``a = 1``): (p, 4q)."""
    diff = x[:, None, :] - y[None, :, :]
    r = np.linalg.norm(diff, axis=-1)
    rows = np.empty(r.shape + (4,))
    rows[..., 0] = 2 * r**3 - 3 * radius * r**2 + radius**3
    rows[..., 1:] = -6 * diff * (r - radius)[..., None]
    return rows.reshape(len(x), -1)


def value_correction(x, y, weights, radius):
    """``value_rows(x, y, radius) @ weights`` without the (p, 4q) matrix: (p,) float.

    With ``D = r - R``, the value-value kernel is ``D^2 (2 r + R)`` and the value-gradient
    kernel is ``-6 D (x - y)``, so both reduce to products of the (p, q) distance matrix
    with vectors (the README's step timings show the gain).
    """
    weights = weights.reshape(-1, 4)
    r = cdist(x, y)
    shifted = r - radius
    values = (shifted**2 * (2 * r + radius)) @ weights[:, 0]
    toward = shifted @ weights[:, 1:]                       # sum_j D_ij g_j, (p, 3)
    offsets = shifted @ np.einsum("ij,ij->i", y, weights[:, 1:])
    return values - 6 * (np.einsum("ij,ij->i", x, toward) - offsets)


def gradient_rows(x, y, radius):
    """Covariance of gradients at ``x`` with [value, gradient] at ``y``: (p, 3, 4q)."""
    diff = x[:, None, :] - y[None, :, :]
    r = np.linalg.norm(diff, axis=-1)
    rows = np.empty(r.shape + (3, 4))
    rows[..., 0] = 6 * diff * (r - radius)[..., None]
    safe = np.where(r > 0, r, 1.0)
    outer = np.where((r > 0)[..., None, None],
                     diff[..., :, None] * diff[..., None, :] / safe[..., None, None], 0.0)
    rows[..., 1:] = -6 * (outer + np.eye(3) * (r - radius)[..., None, None])
    return rows.transpose(0, 2, 1, 3).reshape(len(x), 3, -1)


def stable_cholesky(matrix, max_tries=8):
    """Lower Cholesky factor, adding growing jitter to the diagonal when needed.

    Returns
    -------
    factor : (n, n) float
    jitter : float
        What was added to the diagonal (0 if nothing).
    """
    scale = float(np.mean(np.abs(np.diag(matrix)))) or 1.0
    jitter = 0.0
    for attempt in range(max_tries):
        try:
            return cholesky(matrix + jitter * np.eye(len(matrix)), lower=True,
                            check_finite=False), jitter
        except LinAlgError:
            jitter = scale * 10.0 ** (attempt - 10)
    raise LinAlgError(f"matrix not positive definite even with jitter {jitter:.3g}")


@dataclass(frozen=True, eq=False)
class GPISFit:
    """A fitted GPIS posterior (immutable); see :func:`fit_gpis`.

    Attributes
    ----------
    points : (n, 3) float, world frame
        Contact positions.
    scale : float
        The kernel scale ``a`` after this fit's Newton step.
    radius : float
        The kernel's ``R``.
    noise_variance : float
    factor : (4n, 4n) float
        Lower Cholesky factor of ``a K0 + noise I``.
    alpha : (4n,) float
        ``(a K0 + noise I)^-1 (D - mu(X))``.
    log_marginal_likelihood : float
    prior : callable
        ``prior(points) -> (values, gradients)``.
    """

    points: np.ndarray
    scale: float
    radius: float
    noise_variance: float
    factor: np.ndarray
    alpha: np.ndarray
    log_marginal_likelihood: float
    prior: object

    def mean(self, query):
        """Posterior mean value and gradient: (k,), (k, 3) for (k, 3) world points."""
        query = np.atleast_2d(query)
        values, gradients = self.prior(query)
        values, gradients = np.array(values, dtype=float), np.array(gradients, dtype=float)
        for start in range(0, len(query), _CHUNK):
            part = query[start:start + _CHUNK]
            values[start:start + _CHUNK] += self.scale * value_correction(
                part, self.points, self.alpha, self.radius)
            gradients[start:start + _CHUNK] += self.scale * gradient_rows(
                part, self.points, self.radius) @ self.alpha
        return values, gradients

    def mean_value(self, query):
        """Posterior mean value only (cheaper): (k,)."""
        query = np.atleast_2d(query)
        values = np.array(self.prior(query)[0], dtype=float)
        if len(self.points) == 0:
            return values
        for start in range(0, len(query), _CHUNK):
            part = query[start:start + _CHUNK]
            values[start:start + _CHUNK] += self.scale * value_correction(
                part, self.points, self.alpha, self.radius)
        return values

    def variance(self, query):
        """Posterior variance of the value: (k,) float, never negative."""
        query = np.atleast_2d(query)
        result = np.empty(len(query))
        prior_variance = self.scale * self.radius**3
        if len(self.points) == 0:
            return np.full(len(query), prior_variance)
        for start in range(0, len(query), _CHUNK):
            cross = self.scale * value_rows(query[start:start + _CHUNK], self.points, self.radius)
            reduced = solve_triangular(self.factor, cross.T, lower=True, check_finite=False)
            result[start:start + _CHUNK] = prior_variance - np.sum(reduced**2, axis=0)
        return np.maximum(result, 0.0)


def _log_likelihood_terms(gram0, residual, scale, noise):
    """Cholesky, alpha and log marginal likelihood of ``a K0 + noise I``."""
    factor, jitter = stable_cholesky(scale * gram0 + noise * np.eye(len(gram0)))
    alpha = cho_solve((factor, True), residual, check_finite=False)
    value = (-0.5 * residual @ alpha - np.sum(np.log(np.diag(factor)))
             - 0.5 * len(residual) * _LOG_2PI)
    return factor, alpha, float(value)


def _inverse_from_cholesky(factor):
    """``(L L^T)^-1`` from the lower factor ``L`` (LAPACK potri: a third of the work of
    solving against the identity)."""
    packed, info = dpotri(factor, lower=True)
    if info != 0:
        raise LinAlgError(f"potri failed (info {info})")
    return np.tril(packed) + np.tril(packed, -1).T


def newton_step_log_scale(gram0, residual, scale, noise, factor, alpha, max_step=2.0):
    """One Newton step on ``log a`` for the log marginal likelihood.

    With ``K = a K0 + s I`` and ``B = K^-1``: ``K0 = (K - s I) / a``, so all derivatives
    follow from ``B``, ``alpha = B y`` and ``y``.

    Returns
    -------
    float
        The proposed change of ``log a`` (bounded by ``max_step``).
    """
    n = len(residual)
    inverse = _inverse_from_cholesky(factor)
    trace_b = np.trace(inverse)
    y, s, a = residual, noise, scale
    gradient_a = 0.5 * (y @ alpha - s * alpha @ alpha) / a - 0.5 * (n - s * trace_b) / a
    shifted = y - s * alpha
    quad = shifted @ (alpha - s * (inverse @ alpha)) / a**2
    trace_term = (n - 2 * s * trace_b + s**2 * np.sum(inverse**2)) / a**2
    hessian_a = -quad + 0.5 * trace_term
    gradient = a * gradient_a
    hessian = a**2 * hessian_a + a * gradient_a
    if hessian < 0 and np.isfinite(hessian):
        step = -gradient / hessian
    else:
        step = np.sign(gradient) * max_step
    return float(np.clip(step, -max_step, max_step)) if np.isfinite(step) else 0.0


def fit_gpis(points, normals, prior, radius, scale=1.0, noise_variance=1e-4, newton=True):
    """Fit the GPIS to contacts, taking one Newton step on the kernel scale.

    Parameters
    ----------
    points : (n, 3) float, world frame
    normals : (n, 3) float, unit
    prior : callable
        ``prior(points) -> (values (k,), gradients (k, 3))``, the prior mean.
    radius : float
        Kernel ``R``: at least 1.2 times the largest distance between any training and
        query points.
    scale : float
        Current kernel scale ``a`` (start of the Newton step).
    noise_variance : float
        ``sigma^2`` of the observations (1e-4: sigma matches the 0.01 contact tolerance).
    newton : bool
        Take the Newton step; it is accepted only if the marginal likelihood does not drop
        (with step halving).

    Returns
    -------
    GPISFit
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) == 0:
        return GPISFit(points, float(scale), float(radius), float(noise_variance),
                       np.zeros((0, 0)), np.zeros(0), 0.0, prior)
    prior_values, prior_gradients = prior(points)
    observed = np.hstack([np.zeros((len(points), 1)), normals])
    residual = (observed - np.column_stack([prior_values, prior_gradients])).ravel()
    gram0 = kernel_blocks(points, points, radius)
    factor, alpha, value = _log_likelihood_terms(gram0, residual, scale, noise_variance)
    if newton:
        step = newton_step_log_scale(gram0, residual, scale, noise_variance, factor, alpha)
        for _ in range(6):
            if abs(step) < 1e-12:
                break
            candidate = scale * np.exp(step)
            try:
                trial = _log_likelihood_terms(gram0, residual, candidate, noise_variance)
            except LinAlgError:
                trial = None
            if trial is not None and trial[2] >= value:
                scale, (factor, alpha, value) = candidate, trial
                break
            step /= 2
    return GPISFit(points, float(scale), float(radius), float(noise_variance), factor, alpha,
                   value, prior)


def zero_level_surface(fit, bounds, resolution=32):
    """Marching cubes on the posterior mean over a box.

    Parameters
    ----------
    fit : GPISFit
    bounds : (2, 3) float
        The box (world frame); it should contain the surface with some margin.
    resolution : int
        Cells along the longest side of the box.

    Returns
    -------
    vertices : (v, 3) float, world frame
    faces : (f, 3) int
        Empty arrays when the mean has no zero crossing in the box.
    """
    low, high = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    spacing = float((high - low).max()) / resolution
    counts = np.maximum(np.ceil((high - low) / spacing).astype(int) + 1, 2)
    axes = [low[i] + spacing * np.arange(counts[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    volume = fit.mean_value(grid).reshape(tuple(counts))
    # Close the surface at the box: outside the box counts as outside the object.
    volume = np.pad(volume, 1, constant_values=max(float(volume.max()), spacing))
    if not (volume.min() < 0 < volume.max()):
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices, faces, _, _ = marching_cubes(volume, 0.0, spacing=(spacing,) * 3,
                                           method="lewiner")
    return vertices + low - spacing, faces.astype(np.int64)
