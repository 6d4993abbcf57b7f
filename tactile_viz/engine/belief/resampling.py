"""Resampling and merging particles: stochastic universal sampling (paper, Algorithm 1) and
the merging of near-identical poses (beyond the paper)."""

import numpy as np
from scipy.spatial.transform import Rotation

from .likelihood import normalise_log_weights


def stochastic_universal_resampling(weights, count, rng):
    """Copies of each particle drawn by stochastic universal sampling.

    Parameters
    ----------
    weights : (N,) float
        Normalised weights.
    count : int
        Number of draws.
    rng : numpy.random.Generator

    Returns
    -------
    (N,) int
        Copies per particle; they sum to ``count``, and every particle whose weight exceeds
        ``1 / count`` gets at least one.
    """
    cumulative = np.cumsum(weights)
    cumulative /= cumulative[-1]
    positions = (rng.random() + np.arange(count)) / count
    drawn = np.minimum(np.searchsorted(cumulative, positions, side="right"), len(weights) - 1)
    return np.bincount(drawn, minlength=len(weights))


def merge_close_poses(particles, distance, angle):
    """Particles of one class whose poses share a cell of ``distance`` (translation) by
    ``angle`` (rotation vector, radians) become one: the heaviest's pose with their summed
    weight.

    Point-pair sampling proposes the same pose many times over from different pairs; they
    carry one hypothesis, so merging them bounds the particle count without changing what
    the filter believes (to within the cell).

    Parameters
    ----------
    particles : Particles
    distance, angle : float
        Positive cell sizes.

    Returns
    -------
    Particles
        Normalised; the input itself when no two share a cell.
    """
    if len(particles) < 2:
        return particles
    rotation_vectors = Rotation.from_matrix(particles.rotations).as_rotvec()
    keys = np.column_stack([particles.classes,
                            np.floor(particles.translations / distance),
                            np.floor(rotation_vectors / angle)]).astype(np.int64)
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.ravel()
    if group.max() + 1 == len(particles):
        return particles
    order = np.lexsort((-particles.log_weights, group))
    first = np.r_[True, group[order][1:] != group[order][:-1]]
    heads = order[first]
    merged = particles.take(heads)
    # Summed in each group's own scale: the head is its heaviest, so no sum underflows
    # (a group of zero weights keeps weight zero instead of 0/0).
    head_log_weight = merged.log_weights[np.argsort(group[heads])][group]
    head_log_weight = np.where(np.isfinite(head_log_weight), head_log_weight, 0.0)
    sums = np.bincount(group, np.exp(particles.log_weights - head_log_weight))
    with np.errstate(divide="ignore"):
        log_weights = normalise_log_weights(merged.log_weights + np.log(sums[group[heads]]))
    return type(merged)(merged.classes, merged.rotations, merged.translations, log_weights)
