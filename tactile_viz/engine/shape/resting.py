"""How an object rests on a table: its stable poses (trimesh) and its lowest points.

An object at rest on a plane lies in one of a few stable poses, turned about the vertical,
its lowest point on the plane (``trimesh.poses.compute_stable_poses``: the quasi-static
chance of landing on each face of the convex hull when dropped).
"""

import functools
import warnings

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from .meshes import bare_mesh

MIN_PROBABILITY = 0.02  # stable poses rarer than this are left out
MAX_POSES = 12
HULL_VERTICES = 1000  # stable poses of a larger hull are found on this many of its vertices


@functools.lru_cache(maxsize=64)
def stable_rotations(model):
    """The stable poses of ``model`` on a plane whose normal is +z.

    A hull of more than ``HULL_VERTICES`` vertices is thinned to that many (a fixed random
    choice) first: trimesh took 94 s on a smooth ball's 10,002 and 4.5 s on a vase's 4,420.
    The object's centre of mass is kept. The poses are kept in the model's disk cache by
    its mesh's content: trimesh took 2.9 s of a 6.1 s table trial on the bundled objects
    in every new process.

    Returns
    -------
    rotations : (k, 3, 3) float
        Object frame to a frame whose +z is up; at least one (the identity when trimesh
        finds none).
    probabilities : (k,) float
        Summing to 1.
    """
    cache, content = getattr(model, "cache", None), getattr(model, "content_hash", None)
    if cache is None or content is None:
        return _stable_rotations(model.mesh)
    arrays = cache.get_or_build(
        "stable1", content, {"min_probability": MIN_PROBABILITY, "max_poses": MAX_POSES,
                             "hull_vertices": HULL_VERTICES},
        lambda: dict(zip(("rotations", "probabilities"), _stable_rotations(model.mesh))))
    return arrays["rotations"], arrays["probabilities"]


def _stable_rotations(mesh):
    mesh = bare_mesh(mesh)
    try:
        # Degenerate hull faces divide by zero inside trimesh: they get no probability.
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            transforms, probabilities = trimesh.poses.compute_stable_poses(
                _thinned_hull(mesh), center_mass=_centre_of_mass(mesh), n_samples=1)
    except Exception:  # noqa: BLE001 -- a degenerate hull: no preferred pose
        transforms, probabilities = np.eye(4)[None], np.ones(1)
    probabilities = np.asarray(probabilities, float)
    keep = np.flatnonzero(probabilities >= MIN_PROBABILITY)[:MAX_POSES]
    if len(keep) == 0:
        keep = np.arange(min(1, len(probabilities)))
    if len(keep) == 0:
        return np.eye(3)[None], np.ones(1)
    rotations = np.asarray(transforms)[keep, :3, :3]
    probabilities = probabilities[keep] / probabilities[keep].sum()
    return rotations, probabilities


def _thinned_hull(mesh):
    hull = mesh.convex_hull
    if len(hull.vertices) <= HULL_VERTICES:
        return hull
    keep = np.random.default_rng(0).choice(len(hull.vertices), HULL_VERTICES, replace=False)
    return trimesh.convex.convex_hull(hull.vertices[keep])


def _centre_of_mass(mesh):
    return mesh.center_mass if mesh.is_volume else mesh.centroid


@functools.lru_cache(maxsize=64)
def hull_points(model):
    """The vertices of ``model``'s convex hull, (h, 3), object frame: where its lowest
    point in any pose lies."""
    mesh = bare_mesh(model.mesh)
    try:
        return np.asarray(mesh.convex_hull.vertices, float)
    except Exception:  # noqa: BLE001 -- a flat or degenerate mesh: all its vertices
        return np.asarray(mesh.vertices, float)


def lowest_heights(points, rotations, translations, up, floor_point):
    """The height above a plane of the lowest of ``points`` at each pose.

    Parameters
    ----------
    points : (h, 3) float, object frame
    rotations : (n, 3, 3) float
    translations : (n, 3) float
        ``object_to_world`` poses.
    up : (3,) float
        The plane's upward unit normal.
    floor_point : (3,) float
        A point of the plane, world frame.

    Returns
    -------
    (n,) float, scene units
    """
    # up . (R p + t) - up . q = (R^T up) . p + up . (t - q)
    tilted = np.einsum("nij,i->nj", rotations, up)
    return (tilted @ points.T).min(axis=1) + (translations - floor_point) @ up


def resting_pose(model, scene, rng=None, max_offset=0.5):
    """A random stable pose of ``model`` on the scene's table: a stable pose drawn by its
    probability, turned about the vertical at random, its lowest point on the plane, its
    centre within ``max_offset`` size units of the table point horizontally.

    Returns
    -------
    rotation : (3, 3) float
    translation : (3,) float
        ``object_to_world``.
    """
    rng = np.random.default_rng(rng)
    rotations, probabilities = stable_rotations(model)
    stable = rotations[rng.choice(len(rotations), p=probabilities)]
    turn = Rotation.from_rotvec(rng.uniform(0, 2 * np.pi) * np.array([0.0, 0.0, 1.0]))
    to_world = _z_to(scene.up)
    rotation = to_world @ turn.as_matrix() @ stable
    offset = rng.uniform(-1.0, 1.0, size=3) * max_offset * model.size_unit
    offset -= (offset @ scene.up) * scene.up
    translation = scene.table_point + offset
    low = lowest_heights(hull_points(model), rotation[None], translation[None], scene.up,
                         scene.table_point)[0]
    return rotation, translation - low * scene.up


def _z_to(up):
    """A rotation taking +z to ``up``."""
    z = np.array([0.0, 0.0, 1.0])
    if np.allclose(up, z):
        return np.eye(3)
    rotation, _ = Rotation.align_vectors(up[None], z[None])
    return rotation.as_matrix()


def seeds_on_table(points, normals, hull, rotations, position, normal, up, floor_point,
                   normal_tolerance, height_tolerance, turns=8):
    """Poses of one prior that rest on the table in one of its stable poses and put one of
    its feature points on a contact: the first touch's hypotheses where a table is known.

    A stable pose fixes the feature's normal up to a turn about the vertical; the contact's
    normal then fixes the turn (its vertical part must match within ``normal_tolerance``),
    the contact fixes the translation, and the pose is kept when its lowest point lies
    within ``height_tolerance`` of the plane. A feature whose normal is vertical leaves the
    turn free: ``turns`` turns are spread over the circle.

    Parameters
    ----------
    points, normals : (f, 3) float, object frame
        The prior's feature points and their outward unit normals.
    hull : (h, 3) float, object frame
        Its convex hull's vertices (:func:`hull_points`).
    rotations : (k, 3, 3) float
        Its stable poses (:func:`stable_rotations`), object frame to a frame whose +z is up.
    position, normal : (3,) float, world frame
        The contact.
    up, floor_point : (3,) float, world frame
        The table's upward unit normal and a point of it.
    normal_tolerance : float
        Largest difference of the vertical components of the two unit normals.
    height_tolerance : float
        Scene units.
    turns : int

    Returns
    -------
    rotations : (m, 3, 3) float
    translations : (m, 3) float
        ``object_to_world`` poses.
    """
    to_world = _z_to(np.asarray(up, float))
    local = to_world.T @ np.asarray(normal, float)  # the contact's normal, table frame
    turned = np.einsum("kij,fj->kfi", rotations, normals)  # (k, f, 3), before the turn
    pose, feature = np.nonzero(np.abs(turned[..., 2] - local[2]) <= normal_tolerance)
    if len(pose) == 0:
        return np.zeros((0, 3, 3)), np.zeros((0, 3))
    q = turned[pose, feature]
    if np.hypot(local[0], local[1]) < 1e-3:  # a level contact: its normal fixes no turn
        free = np.ones(len(q), bool)
    else:
        free = np.hypot(q[:, 0], q[:, 1]) < 0.05
    yaw = np.arctan2(local[1], local[0]) - np.arctan2(q[:, 1], q[:, 0])
    spread = 2 * np.pi * np.arange(turns) / turns
    pose = np.concatenate([pose[~free], np.repeat(pose[free], turns)])
    feature = np.concatenate([feature[~free], np.repeat(feature[free], turns)])
    yaw = np.concatenate([yaw[~free], np.tile(spread, int(free.sum()))])
    cos, sin = np.cos(yaw), np.sin(yaw)
    turn = np.zeros((len(yaw), 3, 3))
    turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = cos, -sin, sin, cos
    turn[:, 2, 2] = 1.0
    world = to_world @ turn @ rotations[pose]
    translations = position - np.einsum("nij,nj->ni", world, points[feature])
    gap = lowest_heights(hull, world, translations, np.asarray(up, float),
                         np.asarray(floor_point, float))
    keep = np.abs(gap) <= height_tolerance
    # Onto the plane: the contact then moves by the gap along up, within the tolerance.
    return world[keep], translations[keep] - gap[keep, None] * np.asarray(up, float)
