"""The GPIS fit of a session kept from step to step (beyond the paper, which refits from
scratch): the Gram matrix and its lower Cholesky factor are extended by a block when
observations are appended, the kernel scale takes its Newton step only every few fits or
when the data ask for it, and the posterior mean is summed by a compiled loop.

Extending a factor ``L`` of ``K11`` to ``K = [[K11, K12], [K21, K22]]``:
``L21 = (L^-1 K12)^T`` and ``L22 = chol(K22 - L21 L21^T)`` (the Schur complement), which
costs ``O(m^2 k)`` for ``k`` new rows instead of ``O(m^3)``. The leading block of a
Cholesky factor is the factor of the leading block, so a cache also serves any prefix of
its rows (a rolled-back step). The cache is keyed by content (the rows' positions and
components, the kernel, scale and noise): anything else refactors in full, as
:func:`~.gpis.fit_gpis` does.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular

from .gpis import (
    _LOG_2PI,
    GPISFit,
    WendlandKernel,
    as_kernel,
    indefinite_nugget,
    kernel_blocks,
    newton_step_log_scale,
    observations,
    row_noise,
    stable_cholesky,
)
from .gpis_compiled import compiled_corrections


@dataclass(frozen=True, eq=False)
class GramCache:
    """A Gram matrix and its factor for reuse by the next fit (immutable).

    Attributes
    ----------
    rows : (m, 4) float
        Each observed row's position (world frame) and component (0 value, 1-3 gradient).
    kernel : ThinPlateKernel or WendlandKernel
    nugget : float
        Added to the diagonal of ``gram0`` (an indefinite thin-plate Gram matrix).
    gram0 : (m, m) float
        ``K0`` (scale 1) of the rows, nugget included.
    scale, jitter : float
    noise : (float, float)
        The value rows' and the gradient rows' noise variance (:func:`~.gpis.row_noise`):
        the factor is that of ``scale gram0 + diag(noise) + jitter I``.
    factor : (m, m) float
        Lower Cholesky factor.
    inverse_rows : (m,) float
        Squared norms of the rows of ``factor^-1``: their sum is the trace of ``K^-1``.
    """

    rows: np.ndarray
    kernel: object
    nugget: float
    gram0: np.ndarray
    scale: float
    noise: tuple
    jitter: float
    factor: np.ndarray
    inverse_rows: np.ndarray


def extend_cholesky(factor, cross, corner):
    """The lower Cholesky factor of ``[[A, cross], [cross^T, corner]]`` from that of ``A``.

    Parameters
    ----------
    factor : (p, p) float
        Lower factor of ``A``.
    cross : (p, k) float
    corner : (k, k) float

    Returns
    -------
    (p + k, p + k) float

    Raises
    ------
    LinAlgError
        When the Schur complement ``corner - L21 L21^T`` is not positive definite.
    """
    p, k = cross.shape
    lower = solve_triangular(factor, cross, lower=True, check_finite=False).T
    schur = corner - lower @ lower.T
    result = np.zeros((p + k, p + k), order="F")  # LAPACK's order: solves do not copy it
    result[:p, :p] = factor
    result[p:, :p] = lower
    result[p:, p:] = cholesky(schur, lower=True, check_finite=False)
    return result


def inverse_row_norms(factor, start=0, head=None):
    """Squared norms of rows ``start:`` of ``factor^-1`` (lower triangular): (m - start,).

    ``head`` is ``factor[:start, :start]`` when the caller holds it as an array of its own
    (a solve against a slice copies it)."""
    if start == 0:
        inverse = solve_triangular(factor, np.eye(len(factor)), lower=True, check_finite=False)
        return np.sum(inverse**2, axis=1)
    head = factor[:start, :start] if head is None else head
    # Rows of L^-1 past the head: [-L22^-1 L21 L11^-1, L22^-1].
    bridge = solve_triangular(head, factor[start:, :start].T, lower=True, trans="T",
                              check_finite=False)
    corner_inverse = solve_triangular(factor[start:, start:], np.eye(len(factor) - start),
                                      lower=True, check_finite=False)
    return np.sum((corner_inverse @ bridge.T) ** 2, axis=1) + np.sum(corner_inverse**2, axis=1)


def observed_rows(points, kept):
    """Position and component (0 value, 1-3 gradient) of each observed row: (m, 4) float."""
    return np.column_stack([points[kept // 4], kept % 4]).astype(float)


def _common_prefix(old, new):
    """How many leading rows two (., 4) arrays share exactly."""
    count = min(len(old), len(new))
    differ = np.flatnonzero(np.any(old[:count] != new[:count], axis=1))
    return int(differ[0]) if len(differ) else count


def _gram_rows(points, kept, start, kernel):
    """Rows ``start:`` of ``K0`` of the observed rows ``kept``: (m - start, m)."""
    owners = kept[start:] // 4
    unique, local = np.unique(owners, return_inverse=True)
    blocks = kernel_blocks(points[unique], points, kernel)[:, kept]
    return blocks[4 * local.ravel() + kept[start:] % 4]


def _gram(cache, points, kept, kernel):
    """``K0`` of the observed rows and its nugget, reusing ``cache``'s leading rows.

    Returns
    -------
    gram0 : (m, m) float
    nugget : float
    shared : int
        How many leading rows came from the cache (their factor is reusable).
    rows : (m, 4) float
        :func:`observed_rows`.
    """
    rows = observed_rows(points, kept)
    shared = 0
    if cache is not None and cache.kernel == kernel:
        shared = _common_prefix(cache.rows, rows)
    if shared == 0:
        return kernel_blocks(points, points, kernel)[np.ix_(kept, kept)], 0.0, 0, rows
    if shared == len(kept):
        return cache.gram0[:shared, :shared], cache.nugget, shared, rows
    new = _gram_rows(points, kept, shared, kernel)
    gram0 = np.empty((len(kept), len(kept)))
    gram0[:shared, :shared] = cache.gram0[:shared, :shared]
    gram0[shared:] = new
    gram0[:shared, shared:] = new[:, :shared].T
    gram0[shared:, shared:] += cache.nugget * np.eye(len(kept) - shared)
    return gram0, cache.nugget, shared, rows


def _full_factor(gram0, nugget, scale, noise):
    """``(gram0, nugget, factor, jitter)`` by a full factorisation of
    ``scale gram0 + diag(noise)`` (``noise`` (m,) per row), a nugget added to ``gram0``
    when jitter alone does not make it positive definite (as fit_gpis)."""
    eye = np.eye(len(gram0))
    try:
        factor, jitter = stable_cholesky(scale * gram0 + np.diag(noise))
    except LinAlgError:
        extra = indefinite_nugget(gram0)
        gram0, nugget = gram0 + extra * eye, nugget + extra
        factor, jitter = stable_cholesky(scale * gram0 + np.diag(noise))
    return gram0, nugget, factor, jitter


def _noise_pair(noise):
    """``(value, gradient)`` noise variances from such a pair or one float for both."""
    value, gradient = np.broadcast_to(np.asarray(noise, dtype=float), (2,))
    return float(value), float(gradient)


def _row_noise(rows, noise):
    """The noise variance of each of ``rows`` ((m, 4), :func:`observed_rows`)."""
    return row_noise(rows[:, 3], *noise)


def cached_factor(cache, points, kept, kernel, scale, noise):
    """The Gram matrix and factor of the observed rows, extended from ``cache`` when the
    kernel, scale and noise are the same and its rows lead the new ones.

    Parameters
    ----------
    cache : GramCache or None
    points : (n, 3) float, world frame
    kept : (m,) int
        Observed rows of the ``4 n`` [value, gradient] components.
    kernel : ThinPlateKernel or WendlandKernel
    scale : float
    noise : float or (float, float)
        The value rows' and the gradient rows' noise variance (one float: both).

    Returns
    -------
    GramCache
    """
    noise = _noise_pair(noise)
    gram0, nugget, shared, rows = _gram(cache, points, kept, kernel)
    same = shared and cache.scale == scale and cache.noise == noise
    if same and shared == len(kept):  # nothing new (a refit, a rolled-back step)
        return GramCache(rows, kernel, nugget, gram0, scale, noise, cache.jitter,
                         cache.factor[:shared, :shared], cache.inverse_rows[:shared])
    if same:
        diagonal = _row_noise(rows[shared:], noise) + cache.jitter
        corner = scale * gram0[shared:, shared:] + np.diag(diagonal)
        try:
            factor = extend_cholesky(cache.factor[:shared, :shared],
                                     scale * gram0[:shared, shared:], corner)
        except LinAlgError:
            pass  # the Schur complement is not positive definite: refactor in full
        else:
            norms = np.concatenate([cache.inverse_rows[:shared], inverse_row_norms(
                factor, shared, cache.factor[:shared, :shared])])
            return GramCache(rows, kernel, nugget, gram0, scale, noise, cache.jitter,
                             factor, norms)
    gram0, nugget, factor, jitter = _full_factor(gram0, nugget, scale, _row_noise(rows, noise))
    return GramCache(rows, kernel, nugget, gram0, scale, noise, jitter, factor,
                     inverse_row_norms(factor))


def _likelihood(cache, residual):
    """``alpha`` and the log marginal likelihood of ``residual`` under ``cache``'s factor."""
    alpha = cho_solve((cache.factor, True), residual, check_finite=False)
    value = (-0.5 * residual @ alpha - np.sum(np.log(np.diag(cache.factor)))
             - 0.5 * len(residual) * _LOG_2PI)
    return alpha, float(value)


def scale_score(cache, residual, alpha):
    """The gradient of the log marginal likelihood in ``log a`` over its standard deviation
    under the model (``sqrt(m / 2)``, the Fisher information's bound): about N(0, 1) when
    the scale fits the data, large when a Newton step would move it.

    The trace ``tr(S K^-1)`` takes each row's noise times its row of ``L^-1``'s squared
    norm instead of ``K^-1``'s diagonal entry: the same sum, exact when the noise is the
    same on every row, a trigger's approximation when the gradient rows' differs."""
    m = len(residual)
    if m == 0:
        return 0.0
    value, gradient_rows = cache.noise[0] + cache.jitter, cache.rows[:, 3] > 0
    extra = cache.noise[1] - cache.noise[0]  # the gradient rows' noise beyond the values'
    weighted = (value * alpha) @ alpha + extra * (alpha[gradient_rows] @ alpha[gradient_rows])
    trace = (value * float(np.sum(cache.inverse_rows))
             + extra * float(np.sum(cache.inverse_rows[gradient_rows])))
    gradient = 0.5 * (residual @ alpha - weighted) - 0.5 * (m - trace)
    return float(gradient / np.sqrt(0.5 * m))


def _newton(cache, residual, alpha, value):
    """One accepted Newton step on ``log a`` (halved up to six times, as fit_gpis):
    ``(cache, alpha, value)`` at the new scale, or the inputs when no step is accepted."""
    noise = _row_noise(cache.rows, cache.noise)
    step = newton_step_log_scale(cache.gram0, residual, cache.scale, noise, cache.factor,
                                 alpha)
    for _ in range(6):
        if abs(step) < 1e-12:
            break
        candidate = cache.scale * np.exp(step)
        try:
            gram0, nugget, factor, jitter = _full_factor(cache.gram0, cache.nugget,
                                                         candidate, noise)
        except LinAlgError:
            step /= 2
            continue
        trial = GramCache(cache.rows, cache.kernel, nugget, gram0, candidate, cache.noise,
                          jitter, factor, cache.inverse_rows)
        trial_alpha, trial_value = _likelihood(trial, residual)
        if trial_value >= value:
            trial = replace(trial, inverse_rows=inverse_row_norms(factor))
            return trial, trial_alpha, trial_value
        step /= 2
    return cache, alpha, value


def fit_gpis_incremental(points, normals, prior, kernel, cache=None, scale=1.0,
                         noise_variance=1e-4, refit=True, refit_score=np.inf,
                         noncontacts=None, noncontact_value=0.1,
                         gradient_noise_variance=None):
    """:func:`~.gpis.fit_gpis` reusing ``cache``, with the Newton step on the scale taken
    only when ``refit`` or when :func:`scale_score` exceeds ``refit_score``.

    Parameters
    ----------
    points, normals, prior, kernel, scale, noise_variance, noncontacts, noncontact_value
    gradient_noise_variance
        As :func:`~.gpis.fit_gpis`.
    cache : GramCache or None
        The previous fit's (any content: only what matches is reused).
    refit : bool
        Take the Newton step whatever the score.
    refit_score : float
        Take it also when the score's size exceeds this.

    Returns
    -------
    fit : GPISFit
        With ``compiled`` set (:func:`~.gpis_compiled.compiled_corrections` sums its mean).
    cache : GramCache or None
        For the next fit (None without observations).
    refitted : bool
        Whether the Newton step was tried.
    """
    kernel = as_kernel(kernel)
    everything, kept, residual, _ = observations(points, normals, prior, noncontacts,
                                                 noncontact_value)
    if len(everything) == 0:
        return fit_gpis_empty(everything, kernel, scale, prior), None, False
    noise = _noise_pair(noise_variance if gradient_noise_variance is None
                        else (noise_variance, gradient_noise_variance))
    cache = cached_factor(cache, everything, kept, kernel, float(scale), noise)
    alpha, value = _likelihood(cache, residual)
    refitted = bool(refit) or abs(scale_score(cache, residual, alpha)) > refit_score
    if refitted:
        cache, alpha, value = _newton(cache, residual, alpha, value)
    weights = np.zeros(4 * len(everything))
    weights[kept] = alpha
    fit = GPISFit(everything, kept, float(cache.scale), kernel, _row_noise(cache.rows, noise),
                  cache.factor, weights, value, prior, compiled=True)
    return fit, cache, refitted


def fit_gpis_empty(everything, kernel, scale, prior):
    """The fit without observations: the prior itself."""
    return GPISFit(everything, np.zeros(0, dtype=int), float(scale), kernel, np.zeros(0),
                   np.zeros((0, 0)), np.zeros(0), 0.0, prior, compiled=True)


def corrections(x, y, weights, kernel):
    """:func:`~.gpis_compiled.compiled_corrections` for a kernel object
    (:class:`~.gpis.ThinPlateKernel` or :class:`~.gpis.WendlandKernel`)."""
    return compiled_corrections(x, y, weights, kernel.radius,
                                isinstance(kernel, WendlandKernel))
