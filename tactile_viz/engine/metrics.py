"""Shape distances: directed and two-way Hausdorff distances on dense surface samples."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .transforms import transform_points

# The paper's success threshold for the pose and reconstruction errors (TWD, in the units of
# objects whose longest side is 6): an estimate within 0.6 counts as right.
ERROR_THRESHOLD = 0.6


def directed_hausdorff(from_points, to_points):
    """``max_a min_b |a - b|`` for (n, 3) and (m, 3) point sets (``inf`` if ``to`` is empty)."""
    from_points, to_points = np.atleast_2d(from_points), np.atleast_2d(to_points)
    if len(from_points) == 0:
        return 0.0
    if len(to_points) == 0:
        return float("inf")
    return float(cKDTree(to_points).query(from_points)[0].max())


def two_way_hausdorff(a, b):
    """``max(d_H(a, b), d_H(b, a))``: the paper's TWD."""
    return max(directed_hausdorff(a, b), directed_hausdorff(b, a))


def surface_samples(model, count=4000, seed=0):
    """Area-uniform surface points of a model, object frame, cached per model and count."""
    cache = model.__dict__.setdefault("_surface_samples", {})
    if (count, seed) not in cache:
        points, _ = trimesh.sample.sample_surface(model.mesh, count,
                                                  seed=np.random.default_rng(seed))
        cache[(count, seed)] = points
    return cache[(count, seed)]


def pose_error(model, rotation, translation, truth, count=4000):
    """TWD between ``model`` placed at ``(rotation, translation)`` and the ground truth."""
    estimate = transform_points(surface_samples(model, count), rotation, translation)
    actual = transform_points(surface_samples(truth.model, count), truth.rotation,
                              truth.translation)
    return two_way_hausdorff(estimate, actual)
