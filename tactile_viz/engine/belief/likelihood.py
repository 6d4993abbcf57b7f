"""The measurement likelihood of tactile observations, in log space.

A contact at ``x`` with normal ``n`` under a hypothesis ``z`` (class and pose) is Gaussian
in the signed distance ``f(x, z)`` (observed 0) and in the normal (observed ``n``, predicted
the SDF gradient), with ``Sigma = diag(sigma_d^2, sigma_n^2 I3)``; its largest value is
``1 / Z`` with ``Z = (2 pi)^2 sqrt(det Sigma)``. A non-contact at ``x`` says ``f > 0``:
``log Phi(f / sigma_d)``.

Beyond the paper, a contact may be an outlier (a wrong reading): with probability ``eps``
it comes from a flat density ``exp(-OUTLIER_NATS) / Z``, the Gaussian's value some four
standard deviations out, so one wrong contact costs a hypothesis at most
``log(1 / eps) + OUTLIER_NATS`` instead of killing it (``eps = 0``: the paper's Gaussian).
"""

import numpy as np
from scipy.special import log_ndtr, logsumexp

OUTLIER_NATS = 8.0  # the outlier density's distance below the Gaussian's peak, in nats


def log_normaliser(sigma_d, sigma_n):
    """``log Z`` of the contact likelihood."""
    return 2 * np.log(2 * np.pi) + np.log(sigma_d) + 3 * np.log(sigma_n)


def log_contact_likelihood(distance, predicted_normal, observed_normal, sigma_d, sigma_n,
                           outlier_probability=0.0):
    """Log-likelihood of contacts.

    Parameters
    ----------
    distance : (...) float
        Predicted signed distance at the contact positions.
    predicted_normal : (..., 3) float
        Predicted unit normals there (same frame as ``observed_normal``).
    observed_normal : (..., 3) float
    sigma_d, sigma_n : float
    outlier_probability : float
        ``eps`` of the outlier mixture (0: the Gaussian alone).

    Returns
    -------
    (...) float
    """
    normal_error = np.sum((predicted_normal - observed_normal) ** 2, axis=-1)
    log_z = log_normaliser(sigma_d, sigma_n)
    gaussian = -0.5 * (np.square(distance / sigma_d) + normal_error / sigma_n**2) - log_z
    if outlier_probability <= 0:
        return gaussian
    # p = (1 - eps) N + eps exp(-OUTLIER_NATS) / Z
    return np.logaddexp(np.log1p(-outlier_probability) + gaussian,
                        np.log(outlier_probability) - OUTLIER_NATS - log_z)


def log_noncontact_likelihood(distance, sigma_d):
    """Log-probability that non-contact points lie outside: ``log Phi(f / sigma_d)``."""
    return log_ndtr(np.asarray(distance) / sigma_d)


def normalise_log_weights(log_weights):
    """Log weights shifted so that their exponentials sum to one.

    If every weight is zero (all ``-inf``) nothing tells the hypotheses apart: they become
    uniform instead of ``-inf - (-inf) = NaN``.
    """
    log_weights = np.asarray(log_weights, dtype=float)
    total = logsumexp(log_weights)
    if total == -np.inf:
        return np.full(log_weights.shape, -np.log(max(log_weights.size, 1)))
    return log_weights - total
