"""Shape distances (directed and two-way Hausdorff distances on dense surface samples) and
pose differences; every length in scene units."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .transforms import transform_points

# The paper's success threshold for the pose and reconstruction errors (TWD, for objects
# whose longest side is 6): an estimate within 0.6, 10% of the object's size, counts as right.
ERROR_THRESHOLD = 0.6
PAPER_SIZE = 6.0


def error_threshold(size=PAPER_SIZE):
    """The success threshold for an object whose longest side is ``size`` (scene units):
    the paper's 0.6 on 6 units, 10% of the size."""
    return ERROR_THRESHOLD * (float(size) / PAPER_SIZE)


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


def pose_difference(model, rotation, translation, truth):
    """Rotation and translation errors of an estimated pose of the truth's own shape.

    Parameters
    ----------
    model : ObjectModel
        The estimate's shape; only the truth's shape (same content hash) has comparable
        frames.
    rotation : (3, 3) float
    translation : (3,) float, scene units
        The estimate's ``object_to_world``.
    truth : GroundTruth

    Returns
    -------
    angle_deg : float or None
        The rotation angle of ``R_truth^T R``, degrees, without regard to the shape's
        symmetries (a bottle turned about its axis counts; the TWD of :func:`pose_error`
        does not); None for another shape.
    distance : float or None
        ``|t - t_truth|``: how far the estimate's object centre (the bounding box's) is from
        the truth's, scene units; None for another shape.
    """
    if model.content_hash != truth.model.content_hash:
        return None, None
    relative = np.asarray(truth.rotation).T @ np.asarray(rotation)
    cosine = np.clip((np.trace(relative) - 1) / 2, -1.0, 1.0)
    return (float(np.degrees(np.arccos(cosine))),
            float(np.linalg.norm(np.asarray(translation) - truth.translation)))
