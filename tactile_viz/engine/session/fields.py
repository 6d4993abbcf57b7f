"""Callables and point sets a session builds: a model's SDF at a pose or averaged over
poses, the values of a field, the space below a tangent plane, thinned free-space samples,
and how deep a probe goes (how far out it starts, :func:`free_approach`, is exploration's,
re-exported here). The callables are classes, not closures, so that a session pickles (the
app steps it in another process)."""

import numpy as np

from ..belief.prior_bank import grid_of
from ..explore.exploration import free_approach  # noqa: F401 (re-exported: the session's)
from ..shape.metrics import first_per_cell


class PosedSDF:
    """A model's SDF placed at a pose: ``field(points) -> (values (k,), gradients (k, 3))``
    for (k, 3) world points. Callables of a session are classes, not closures, so that a
    session pickles (the app steps it in another process); this one holds the model, not
    its grid, so that a pickle can name the model instead of copying the grid."""

    def __init__(self, model, rotation, translation):
        self.model, self.rotation, self.translation = model, rotation, translation

    def __call__(self, points):
        values, gradients = grid_of(self.model).evaluate(
            (np.atleast_2d(points) - self.translation) @ self.rotation)
        return values, gradients @ self.rotation.T


class MixedSDF:
    """A model's SDF averaged over poses: ``sum_k w_k f_k(points)`` for the field ``f_k``
    at pose ``k`` and weights ``w`` summing to 1, values (k,) and gradients (k, 3). Where
    the poses agree (a surface they all place alike, or one turned within itself) it is
    the model's surface; a part whose place they disagree on by more than its thickness
    (a mug's handle about a cup's free axis) lies outside for most and fades."""

    def __init__(self, model, rotations, translations, weights):
        self.fields = [PosedSDF(model, r, t) for r, t in zip(rotations, translations)]
        self.weights = np.asarray(weights, dtype=float) / float(np.sum(weights))

    def __call__(self, points):
        values, gradients = 0.0, 0.0
        for weight, field in zip(self.weights, self.fields):
            v, g = field(points)
            values, gradients = values + weight * v, gradients + weight * g
        return values, gradients


def prior_poses(particles, class_index, rotation, translation, count):
    """The poses a prior's cover averages over: ``(rotation, translation)`` in the place of
    the class's heaviest particle, then its ``count - 1`` next heaviest, and their
    weights relative to the heaviest's ((k, 3, 3), (k, 3), (k,); k at most ``count``, 1
    without particles)."""
    if particles is None or count <= 1:
        return rotation[None], translation[None], np.ones(1)
    index = np.flatnonzero(particles.classes == class_index)
    index = index[np.argsort(-particles.log_weights[index], kind="stable")][:count]
    if len(index) <= 1:
        return rotation[None], translation[None], np.ones(1)
    log_w = particles.log_weights[index]
    rotations = np.concatenate([rotation[None], particles.rotations[index[1:]]])
    translations = np.concatenate([translation[None], particles.translations[index[1:]]])
    return rotations, translations, np.exp(log_w - log_w.max())


class ValueOf:
    """The values of a field returning ``(values, gradients)``."""

    def __init__(self, field):
        self.field = field

    def __call__(self, points):
        return self.field(points)[0]


class BelowTangentPlane:
    """``min(signed height above the plane through position, outside(points))``: the full
    depth across the tangent plane, short of what ``outside`` predicts."""

    def __init__(self, position, normal, outside):
        self.position, self.normal, self.outside = position, normal, outside

    def __call__(self, points):
        return np.minimum((points - self.position) @ self.normal, self.outside(points))


def free_space_points(points, path, spacing):
    """``points`` plus samples of a missed probe ``path``, one per grid cell of ``spacing``.

    Returns
    -------
    (k, 3) float
    """
    length = float(np.linalg.norm(path[-1] - path[0]))
    count = max(2, int(np.ceil(length / spacing)) + 1)
    samples = path[0] + np.linspace(0.0, 1.0, count)[:, None] * (path[-1] - path[0])
    return thin_points(np.vstack([points, samples]), spacing)


def thin_points(points, spacing):
    """The first of ``points`` in each grid cell of size ``spacing`` (order kept)."""
    if len(points) == 0:
        return points
    return points[first_per_cell(points, spacing)]


def deepest_inside(estimate, target, normal, max_depth, samples=21):
    """How far to probe inward from ``target``: to the point the estimated surface puts
    deepest inside (within ``max_depth``), so that a miss there is a non-contact that the
    estimate most strongly contradicts; probing farther could leave a thin part again."""
    depths = np.linspace(0.0, max_depth, samples)
    values = estimate(target - depths[:, None] * normal)
    return float(max(depths[int(np.argmin(values))], max_depth / (samples - 1)))
