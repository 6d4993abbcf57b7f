"""Gaussian process implicit surface with derivative observations (paper, Section III-E).

Each contact is an observation of the implicit function ``f`` and its gradient at a point:
value 0 and gradient equal to the observed normal (4 numbers). The prior mean is the MAP
object's signed distance and gradient, so the posterior keeps the prior's shape where no
datum contradicts it and bends it through the contacts. Two radial kernels give the
covariance of values and gradients:

- :class:`ThinPlateKernel`, the paper's ``k = a (2 r^3 - 3 R r^2 + R^3)``. Its correlation
  falls slowly (``k(r)/k(0)`` is still 0.78 at ``r = 0.3 R``), so a residual at a few
  contacts shifts the field everywhere inside ``R``; at ``R`` equal to the largest distance
  (the paper's choice) the Gram matrix with derivative observations is indefinite, and a
  nugget (jitter) just larger than its most negative eigenvalue is added to the kernel.
- :class:`WendlandKernel`, the compactly supported ``k = a (1 - r/c)^4_+ (4 r/c + 1)``
  (Wendland's C2 function, positive definite in 3-D, twice differentiable so that gradient
  observations have a covariance): a contact corrects the prior only within the support
  ``c``, and beyond it the prior shape survives with the prior variance.

Optionally (beyond the paper) non-contacts where the prior puts the surface or the inside
enter as value-only pseudo-observations ``f = m > 0`` with noise ``(m / 2)^2``: a probe
that passed through the prior's phantom part removes it there. The scale ``a`` takes one
Newton step on the log marginal likelihood per fit, in ``log a`` so that it stays positive.
"""

import hashlib
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular
from scipy.linalg.lapack import dpotri
from scipy.spatial.distance import cdist

from .gpis_compiled import compiled_corrections, compiled_kernel_blocks, compiled_value_rows
from .gpis_prior import (  # noqa: F401
    CarvedPrior,
    carved_prior,
    free_space_cut,
    noncontact_observations,
    observations,
    row_noise,
)

_CHUNK = 4096  # query points per kernel block
_LOG_2PI = np.log(2 * np.pi)


@dataclass(frozen=True)
class ThinPlateKernel:
    """The paper's thin-plate kernel (``a = 1``): ``2 r^3 - 3 R r^2 + R^3``.

    Attributes
    ----------
    radius : float
        ``R``; the paper takes the largest distance between the points involved.
    """

    radius: float

    @property
    def at_zero(self):
        """``k(0)``: the prior variance of a value."""
        return self.radius**3

    def profile(self, r, second=True):
        """``k(r)``, ``g = k'(r) / r`` and ``g'(r)`` (None unless ``second``) on an array
        of distances."""
        big = self.radius
        r2 = r * r
        return (2 * r2 * r - 3 * big * r2 + big**3, 6 * (r - big),
                np.full_like(r, 6.0) if second else None)


@dataclass(frozen=True)
class WendlandKernel:
    """Wendland's compactly supported C2 kernel (``a = 1``): ``(1 - s)^4 (4 s + 1)``,
    ``s = r / c`` (0 beyond the support ``c``).

    Attributes
    ----------
    support : float
        ``c``: how far a contact's correction of the prior reaches.
    """

    support: float

    @property
    def at_zero(self):
        return 1.0

    @property
    def radius(self):
        return self.support

    def profile(self, r, second=True):
        c = self.support
        rest = np.clip(1.0 - r / c, 0.0, None)
        rest2 = rest * rest  # products, not powers: this runs on every (grid node, point) pair
        rest3 = rest2 * rest
        value = rest3 * rest * (4 / c * r + 1)
        rest3 *= -20 / c**2
        return value, rest3, (60 / c**3) * rest2 if second else None


def as_kernel(kernel):
    """A kernel object; a plain number is a thin-plate ``R`` (the paper's kernel)."""
    if isinstance(kernel, (ThinPlateKernel, WendlandKernel)):
        return kernel
    return ThinPlateKernel(float(kernel))


def _pair_terms(x, y, kernel):
    diff = x[:, None, :] - y[None, :, :]
    r = np.linalg.norm(diff, axis=-1)
    value, g, dg = as_kernel(kernel).profile(r)
    # (x_i - y_i)(x_j - y_j) / r tends to 0 as r -> 0.
    safe = np.where(r > 0, r, 1.0)
    outer = np.where((r > 0)[..., None, None],
                     diff[..., :, None] * diff[..., None, :] / safe[..., None, None], 0.0)
    hessian = -(dg[..., None, None] * outer + np.eye(3) * g[..., None, None])
    return diff, value, g, hessian


def kernel_blocks(x, y, kernel):
    """Covariance (``a = 1``) between [value, gradient] observations.

    Parameters
    ----------
    x : (p, 3) float
    y : (q, 3) float
    kernel : ThinPlateKernel, WendlandKernel or float
        A float is a thin-plate ``R``.

    Returns
    -------
    (4p, 4q) float
        Row ``4 i + c`` is component ``c`` (0 value, 1-3 gradient) at ``x[i]``, likewise for
        columns and ``y``: ``[[k, -g d^T], [g d, -(g' d d^T / r + g I)]]`` with
        ``d = x_i - y_j`` (:func:`_pair_terms`), summed by a compiled loop.
    """
    kernel = as_kernel(kernel)
    return compiled_kernel_blocks(x, y, kernel.radius, isinstance(kernel, WendlandKernel))


def value_rows(x, y, kernel):
    """Covariance of values at ``x`` with [value, gradient] at ``y`` (``a = 1``): (p, 4q),
    ``[k, -g d^T]`` per point of ``y`` (compiled loop)."""
    kernel = as_kernel(kernel)
    return compiled_value_rows(x, y, kernel.radius, isinstance(kernel, WendlandKernel))


def value_correction(x, y, weights, kernel):
    """``value_rows(x, y, kernel) @ weights`` without the (p, 4q) matrix: (p,) float.

    The value-value kernel is ``k(r)`` and the value-gradient kernel ``-g(r) (x - y)``, so
    both reduce to products of (p, q) matrices of the distances with vectors.
    """
    weights = weights.reshape(-1, 4)
    value, g, _ = as_kernel(kernel).profile(cdist(x, y), second=False)
    toward = g @ weights[:, 1:]                              # sum_j g_ij w_j, (p, 3)
    offsets = g @ np.einsum("ij,ij->i", y, weights[:, 1:])
    return value @ weights[:, 0] - (np.einsum("ij,ij->i", x, toward) - offsets)


def gradient_rows(x, y, kernel):
    """Covariance of gradients at ``x`` with [value, gradient] at ``y``: (p, 3, 4q)."""
    diff, _, g, hessian = _pair_terms(x, y, kernel)
    rows = np.empty(g.shape + (3, 4))
    rows[..., 0] = g[..., None] * diff
    rows[..., 1:] = hessian
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
            shifted = matrix + jitter * np.eye(len(matrix)) if jitter else matrix
            return cholesky(shifted, lower=True, check_finite=False), jitter
        except LinAlgError:
            jitter = scale * 10.0 ** (attempt - 10)
    raise LinAlgError(f"matrix not positive definite even with jitter {jitter:.3g}")


def indefinite_nugget(gram):
    """The diagonal shift that makes a symmetric ``gram`` positive definite: just over its
    most negative eigenvalue's size (0 when it has none).

    ``gram + nugget I`` is the Gram matrix of the kernel plus a nugget (white noise of that
    variance), so training rows and cross-covariances stay consistent, unlike eigenvalue
    clipping, which changes the training covariance alone.
    """
    smallest = float(np.linalg.eigvalsh(gram)[0])
    if smallest > 0:
        return 0.0
    return 1.01 * -smallest + 1e-12 * float(np.abs(np.diag(gram)).max())


@dataclass(frozen=True, eq=False)
class GPISFit:
    """A fitted GPIS posterior (immutable); see :func:`fit_gpis`.

    Attributes
    ----------
    points : (n, 3) float, world frame
        Observation positions: the contacts, then any non-contact pseudo-observations.
    kept : (m,) int
        The rows of the ``4 n`` [value, gradient] components that are observed (all four at
        a contact, the value only at a non-contact).
    scale : float
        The kernel scale ``a`` after this fit's Newton step.
    kernel : ThinPlateKernel or WendlandKernel
    noise : (m,) float
        Observation noise variance of each kept row.
    factor : (m, m) float
        Lower Cholesky factor of ``a K0 + diag(noise)``.
    alpha : (4n,) float
        ``(a K0 + diag(noise))^-1 (D - mu(X))`` on the kept rows, 0 elsewhere.
    log_marginal_likelihood : float
    prior : callable
        ``prior(points) -> (values, gradients)``.
    compiled : bool
        Sum the mean's value correction by a compiled loop (the same sum, rounded
        differently; :mod:`.gpis_incremental`).
    cut : FreeSpaceCut or None
        Balls of space known to be empty removed from the posterior mean's solid (beyond
        the paper; :func:`cut_free_space`); the variance is the fit's.
    """

    points: np.ndarray
    kept: np.ndarray
    scale: float
    kernel: object
    noise: np.ndarray
    factor: np.ndarray
    alpha: np.ndarray
    log_marginal_likelihood: float
    prior: object
    compiled: bool = False
    cut: object = None

    @property
    def radius(self):
        """The kernel's reach: thin-plate ``R`` or Wendland support ``c``."""
        return self.kernel.radius

    @property
    def prior_variance(self):
        """Variance of a value far from (or without) any observation."""
        return self.scale * self.kernel.at_zero

    def mean(self, query):
        """Posterior mean value and gradient: (k,), (k, 3) for (k, 3) world points."""
        query = np.atleast_2d(query)
        values, gradients = self.prior(query)
        values, gradients = np.array(values, dtype=float), np.array(gradients, dtype=float)
        for start in range(0, len(query) if len(self.points) else 0, _CHUNK):
            part = query[start:start + _CHUNK]
            values[start:start + _CHUNK] += self.scale * self._correction(part)
            gradients[start:start + _CHUNK] += self.scale * gradient_rows(
                part, self.points, self.kernel) @ self.alpha
        if self.cut is not None:
            self.cut(query, values, gradients)
        return values, gradients

    def _correction(self, query):
        """``value_rows(query, points) @ alpha``: (k,)."""
        if self.compiled:
            return compiled_corrections(query, self.points, np.ravel(self.alpha),
                                        self.kernel.radius,
                                        isinstance(self.kernel, WendlandKernel))
        return value_correction(query, self.points, self.alpha, self.kernel)

    def mean_value(self, query):
        """Posterior mean value only (cheaper): (k,)."""
        query = np.atleast_2d(query)
        values = np.array(self.prior(query)[0], dtype=float)
        for start in range(0, len(query) if len(self.points) else 0, _CHUNK):
            part = query[start:start + _CHUNK]
            values[start:start + _CHUNK] += self.scale * self._correction(part)
        if self.cut is not None:
            self.cut(query, values)
        return values

    def variance(self, query):
        """Posterior variance of the value: (k,) float, never negative."""
        query = np.atleast_2d(query)
        if len(self.points) == 0:
            return np.full(len(query), self.prior_variance)
        result = np.empty(len(query))
        for start in range(0, len(query), _CHUNK):
            cross = value_rows(query[start:start + _CHUNK], self.points, self.kernel)
            if len(self.kept) < cross.shape[1]:  # some non-contact rows are not observed
                cross = cross[:, self.kept]
            cross *= self.scale
            reduced = solve_triangular(self.factor, cross.T, lower=True, check_finite=False)
            result[start:start + _CHUNK] = self.prior_variance - np.sum(reduced**2, axis=0)
        return np.maximum(result, 0.0)


def held_out_errors(fit):
    """How far the posterior mean fitted without each contact (an observation point with
    its value and gradient rows) lies from it: ``(c,)`` float, scene units, for the ``c``
    points whose four rows are kept, in their order; the value of the held-out residual
    ``(C^-1)_BB^-1 (C^-1 y)_B`` of each block ``B`` (leave-one-out in closed form,
    Rasmussen and Williams 2006, sec. 5.4.2).

    What a touch the fit has not seen may miss its surface by: a learned shape's own
    error at the contacts it was learned from.
    """
    rows = np.asarray(fit.kept)
    full = np.flatnonzero(np.bincount(rows // 4, minlength=len(fit.points)) == 4)
    if len(full) == 0:
        return np.zeros(0)
    rows = 4 * full[:, None] + np.arange(4)
    position = np.empty(4 * len(fit.points), dtype=np.int64)
    position[fit.kept] = np.arange(len(fit.kept))  # kept rows need not be in order
    positions = position[rows]
    inverse = _inverse_from_cholesky(fit.factor)
    blocks = inverse[positions[:, :, None], positions[:, None, :]]
    residual = np.linalg.solve(blocks, fit.alpha[rows][..., None])[..., 0]
    return np.abs(residual[:, 0])


def _log_likelihood_terms(gram0, residual, scale, noise):
    """Cholesky, alpha and log marginal likelihood of ``a K0 + diag(noise)``."""
    matrix = scale * gram0
    matrix.flat[::len(matrix) + 1] += noise
    factor, _ = stable_cholesky(matrix)
    return (factor, *_terms_of_factor(factor, residual))


def _terms_of_factor(factor, residual):
    """Alpha and log marginal likelihood of the observations' ``residual`` under the
    covariance whose lower Cholesky factor is ``factor``."""
    alpha = cho_solve((factor, True), residual, check_finite=False)
    value = (-0.5 * residual @ alpha - np.sum(np.log(np.diag(factor)))
             - 0.5 * len(residual) * _LOG_2PI)
    return alpha, float(value)


FACTORS_KEPT = 2  # factors a ``factors`` cache holds (each 14 MB at 330 contacts)


def _factor_key(everything, kept, kernel, scale, noise):
    """What a fit's covariance ``a K0 + diag(noise)`` is made of, hashed: two fits with
    the same key have the same Cholesky factor, whatever their prior means."""
    digest = hashlib.blake2b(digest_size=16)
    for array in (everything, kept, noise):
        digest.update(np.ascontiguousarray(array).tobytes())
    return kernel, float(scale), digest.hexdigest()


def _first_terms(everything, kept, residual, kernel, scale, noise, factors):
    """``(gram0 or None, factor, alpha, log marginal likelihood)`` of a fit's first
    evaluation, the factor taken from ``factors`` (a dict cache by content, or None) when
    the same covariance was factored before (``gram0`` then None: not computed)."""
    key = None if factors is None else _factor_key(everything, kept, kernel, scale, noise)
    if key in (factors or {}):
        factor = factors[key]
        return (None, factor, *_terms_of_factor(factor, residual))
    gram0 = kernel_blocks(everything, everything, kernel)
    if len(kept) < len(gram0):  # some non-contact rows are not observed
        gram0 = gram0[np.ix_(kept, kept)]
    try:
        terms = _log_likelihood_terms(gram0, residual, scale, noise)
    except LinAlgError:  # thin-plate R too small: jitter as a nugget of the kernel
        gram0 = gram0 + indefinite_nugget(gram0) * np.eye(len(gram0))
        terms = _log_likelihood_terms(gram0, residual, scale, noise)
    if key is not None:
        while len(factors) >= FACTORS_KEPT:
            del factors[next(iter(factors))]
        factors[key] = terms[0]
    return (gram0, *terms)


def _inverse_from_cholesky(factor):
    """``(L L^T)^-1`` from the lower factor ``L`` (LAPACK potri: a third of the work of
    solving against the identity)."""
    packed, info = dpotri(factor, lower=True)
    if info != 0:
        raise LinAlgError(f"potri failed (info {info})")
    # The upper triangle from the lower one, in place: adding a transposed view cost 0.24 s
    # at 1,600 rows (a 390-contact fit), this 0.04 s, the same numbers.
    inverse = np.tril(packed)
    inverse += np.triu(inverse.T, 1)
    return inverse


def newton_step_log_scale(gram0, residual, scale, noise, factor, alpha, max_step=2.0):
    """One Newton step on ``log a`` for the log marginal likelihood.

    With ``K = a K0 + S``, ``S = diag(noise)`` and ``B = K^-1``: ``K0 = (K - S) / a``, so
    all derivatives follow from ``B``, ``alpha = B y`` and ``y``.

    Returns
    -------
    float
        The proposed change of ``log a`` (bounded by ``max_step``).
    """
    n = len(residual)
    s = np.broadcast_to(np.asarray(noise, dtype=float), (n,))
    inverse = _inverse_from_cholesky(factor)
    trace_bs = float(np.diag(inverse) @ s)
    y, a = residual, scale
    gradient_a = 0.5 * (y @ alpha - alpha @ (s * alpha)) / a - 0.5 * (n - trace_bs) / a
    shifted = y - s * alpha
    quad = shifted @ (alpha - inverse @ (s * alpha)) / a**2
    trace_term = (n - 2 * trace_bs + s @ (inverse**2) @ s) / a**2
    hessian_a = -quad + 0.5 * trace_term
    gradient = a * gradient_a
    hessian = a**2 * hessian_a + a * gradient_a
    if hessian < 0 and np.isfinite(hessian):
        step = -gradient / hessian
    else:
        step = np.sign(gradient) * max_step
    return float(np.clip(step, -max_step, max_step)) if np.isfinite(step) else 0.0


def fit_gpis(points, normals, prior, kernel, scale=1.0, noise_variance=1e-4, newton=True,
             noncontacts=None, noncontact_value=0.1, refuting=None,
             gradient_noise_variance=None, factors=None):
    """Fit the GPIS to contacts, taking one Newton step on the kernel scale.

    Parameters
    ----------
    points : (n, 3) float, world frame
    normals : (n, 3) float, unit
    prior : callable
        ``prior(points) -> (values (k,), gradients (k, 3))``, the prior mean.
    kernel : ThinPlateKernel, WendlandKernel or float
        A float is a thin-plate ``R`` (at least the largest distance between any training
        and query points; an indefinite Gram matrix gets a nugget, see
        :func:`indefinite_nugget`).
    scale : float
        Current kernel scale ``a`` (start of the Newton step).
    noise_variance : float
        ``sigma^2`` of the contact observations (1e-4: sigma matches the 0.01 tolerance).
    newton : bool
        Take the Newton step; it is accepted only if the marginal likelihood does not drop
        (with step halving).
    noncontacts : (k, 3) float, optional
        Positions known to be outside the object (beyond the paper): those where the prior
        value is below ``noncontact_value`` observe ``f = noncontact_value`` with the
        contacts' noise variance.
    noncontact_value : float
    refuting : (q, 3) float, optional
        Positions outside the object that observe ``f = noncontact_value`` whatever the
        prior there (:func:`~.gpis_prior.refuted_fit`).
    gradient_noise_variance : float, optional
        That of the contacts' gradient (normal) rows; None: ``noise_variance`` (the
        paper's one sigma).
    factors : dict, optional
        Cholesky factors by the content of their covariance (observation points, kept
        rows, kernel, scale, noise), read and filled without a Newton step: fits of the same
        observations under other prior means share it (a stopping session's final
        candidates, six of seven alike at a capped 8 cm cup's last step). The fit is the
        same to the bit.

    Returns
    -------
    GPISFit
    """
    kernel = as_kernel(kernel)
    everything, kept, residual, noise = observations(points, normals, prior, noncontacts,
                                                     noncontact_value, noise_variance,
                                                     refuting, gradient_noise_variance)
    if len(everything) == 0:
        return GPISFit(everything, np.zeros(0, dtype=int), float(scale), kernel, np.zeros(0),
                       np.zeros((0, 0)), np.zeros(0), 0.0, prior)
    gram0, factor, alpha, value = _first_terms(everything, kept, residual, kernel, scale,
                                               noise, None if newton else factors)
    if newton:
        step = newton_step_log_scale(gram0, residual, scale, noise, factor, alpha)
        for _ in range(6):
            if abs(step) < 1e-12:
                break
            candidate = scale * np.exp(step)
            try:
                trial = _log_likelihood_terms(gram0, residual, candidate, noise)
            except LinAlgError:
                trial = None
            if trial is not None and trial[2] >= value:
                scale, (factor, alpha, value) = candidate, trial
                break
            step /= 2
    weights = np.zeros(4 * len(everything))
    weights[kept] = alpha
    return GPISFit(everything, kept, float(scale), kernel, noise, factor, weights, value, prior,
                   compiled=True)


def cut_free_space(fit, free_points, contacts, radius, keep_within=0.0, normals=None,
                   disk=0.0):
    """``fit`` with balls about ``free_points`` cut out of its mean's solid, each at most
    ``radius`` and never reaching a contact (:func:`carved_prior`'s balls), except within
    ``keep_within`` of a contact; the fit itself is not changed.

    The prior's carve removes a wrong prior's phantom parts; this one removes what the
    posterior's correction makes where probes found nothing: the thin-plate correction
    reaches the whole box, and under sensor noise it can put surface far from every
    contact. A miss there changes neither the carved prior (already outside) nor the
    correction, so without the cut the exploration would aim at such a part again and
    again. Near the contacts the correction is the data's, and a ball there would dent a
    thin part a probe passed close by: ``keep_within`` (the session's ``eps``, the
    distance at which a contact covers the surface) keeps it.

    Returns
    -------
    GPISFit
    """
    return replace(fit, cut=free_space_cut(free_points, contacts, radius,
                                           keep_within=keep_within, normals=normals,
                                           disk=disk))
