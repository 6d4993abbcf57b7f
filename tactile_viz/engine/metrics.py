"""Shape distances (directed and two-way Hausdorff distances on dense surface samples) and
pose differences; every length in scene units."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .meshes import bare_mesh
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
        points, _ = trimesh.sample.sample_surface(bare_mesh(model.mesh), count,
                                                  seed=np.random.default_rng(seed))
        cache[(count, seed)] = points
    return cache[(count, seed)]


def pose_error(model, rotation, translation, truth, count=4000):
    """TWD between ``model`` placed at ``(rotation, translation)`` and the ground truth."""
    estimate = transform_points(surface_samples(model, count), rotation, translation)
    actual = transform_points(surface_samples(truth.model, count), truth.rotation,
                              truth.translation)
    return two_way_hausdorff(estimate, actual)


SYMMETRY_TOLERANCE = 0.02  # of the longest side: a rotation mapping the surface this close is a symmetry
_FOLDS = (2, 3, 4, 5, 6, 8)


def _rotation(axis, angle):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(angle * np.asarray(axis, float)).as_matrix()


def symmetries(model, count=1000):
    """The shape's rotational symmetries about its principal axes, object frame.

    A rotation about the centre of mass is a symmetry when it maps every surface sample
    within ``SYMMETRY_TOLERANCE`` of the longest side of the surface; the candidate axes are
    the principal axes of inertia. An axis about which rotations by 45 and
    by 30 degrees are symmetries is taken as continuous (a bottle's, a vase's).

    Returns
    -------
    discrete : (g, 3, 3) float
        The group the discrete symmetries found generate (the identity first).
    axis : (3,) float or None
        The continuous symmetry axis, if any.
    """
    cache = model.__dict__.setdefault("_symmetries", {})
    if count in cache:
        return cache[count]
    points = surface_samples(model, count, seed=1)
    mesh = bare_mesh(model.mesh)
    centre = np.asarray(mesh.center_mass)  # on every symmetry axis
    centred = points - centre
    tolerance = SYMMETRY_TOLERANCE * model.length

    def symmetric(rotation):
        # A rotation keeps area, so the samples all landing on the surface is enough.
        moved = centred @ rotation.T + centre
        return np.abs(model.exact.signed_distance(moved)).max() <= tolerance

    axes = np.asarray(mesh.principal_inertia_vectors)
    found, axis = [], None
    with model.transient_exact():
        for candidate in axes:
            if axis is None and all(symmetric(_rotation(candidate, np.radians(a)))
                                    for a in (45, 30)):
                axis = candidate
                continue
            # A fold's generator (one turn of 2 pi / fold) generates the rest with the closure.
            found += [turn for turn in (_rotation(candidate, 2 * np.pi / fold)
                                        for fold in _FOLDS) if symmetric(turn)]
    cache[count] = (_closure(found), axis)
    return cache[count]


def _closure(generators, limit=48):
    """The group ``generators`` generate (at most ``limit`` elements), the identity first."""
    group = [np.eye(3)]
    frontier = list(generators)
    while frontier and len(group) < limit:
        element = frontier.pop()
        if any(np.allclose(element, other, atol=1e-6) for other in group):
            continue
        group.append(element)
        frontier += [element @ g for g in generators]
    return np.array(group)


def rotation_error_deg(model, rotation, truth_rotation):
    """The angle between two orientations of ``model``, degrees, up to its symmetries:
    the smallest over its discrete symmetries, and about a continuous axis only the axis's
    tilt counts."""
    discrete, axis = symmetries(model)
    relative = np.asarray(truth_rotation).T @ np.asarray(rotation)
    best = np.pi
    for symmetry in discrete:
        turned = relative @ symmetry
        if axis is None:
            cosine = (np.trace(turned) - 1) / 2
        else:
            cosine = axis @ turned @ axis
        best = min(best, float(np.arccos(np.clip(cosine, -1.0, 1.0))))
    return float(np.degrees(best))


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
        :func:`rotation_error_deg`: the angle of ``R_truth^T R``, degrees, up to the shape's
        symmetries (about a continuous axis, a bottle's, only the axis's tilt counts);
        None for another shape.
    distance : float or None
        ``|t - t_truth|``: how far the estimate's object centre (the bounding box's) is from
        the truth's, scene units; None for another shape.
    """
    if model.content_hash != truth.model.content_hash:
        return None, None
    return (rotation_error_deg(model, rotation, truth.rotation),
            float(np.linalg.norm(np.asarray(translation) - truth.translation)))
