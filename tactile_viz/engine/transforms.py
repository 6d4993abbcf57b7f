"""Rigid transforms as ``(R, t)`` pairs.

A pose is named by its frames: ``object_to_world = (R, t)`` maps a point ``p`` in the
object frame to ``R @ p + t`` in the world frame.
"""

import numpy as np
from scipy.spatial.transform import Rotation


def transform_points(points, rotation, translation):
    """Apply ``(R, t)`` to points.

    Parameters
    ----------
    points : (n, 3) float
    rotation : (3, 3) float
    translation : (3,) float

    Returns
    -------
    (n, 3) float
    """
    return np.asarray(points, dtype=float) @ np.asarray(rotation).T + translation


def inverse_transform_points(points, rotation, translation):
    """Apply the inverse of ``(R, t)``: world frame to object frame for a pose
    ``object_to_world``."""
    return (np.asarray(points, dtype=float) - translation) @ np.asarray(rotation)


def inverse_transform_points_batch(points, rotations, translations=None):
    """``points (m, 3)`` (world frame) in each of ``k`` poses' object frames,
    ``R_k^T (p - t_k)``: ``(k, m, 3)``. Without ``translations`` only turned (normals).

    As row vectors, ``p^T R_k``: one batched matrix product (BLAS), several times faster
    than the same sum by ``einsum`` and equal to it up to the last bits."""
    rotations = np.asarray(rotations, dtype=float)
    local = np.matmul(np.asarray(points, dtype=float), rotations)
    if translations is None:
        return local
    return local - np.matmul(np.asarray(translations, dtype=float)[:, None], rotations)


def invert(rotation, translation):
    """Inverse of a rigid transform ``(R, t)``, as ``(R.T, -R.T t)``."""
    rotation = np.asarray(rotation, dtype=float)
    return rotation.T, -rotation.T @ np.asarray(translation, dtype=float)


def compose(first, second):
    """The transform that applies ``first`` and then ``second``; both are ``(R, t)``."""
    (r1, t1), (r2, t2) = first, second
    return r2 @ r1, r2 @ t1 + t2


def to_matrix(rotation, translation):
    """A (4, 4) homogeneous matrix from ``(R, t)``."""
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = translation
    return matrix


def from_matrix(matrix):
    """``(R, t)`` from a (4, 4) homogeneous matrix."""
    matrix = np.asarray(matrix, dtype=float)
    return matrix[:3, :3].copy(), matrix[:3, 3].copy()


def random_pose(rng=None, max_translation=0.0):
    """A uniformly random rotation and a translation uniform in a cube.

    Parameters
    ----------
    rng : int, numpy.random.Generator or None
    max_translation : float
        Each translation component is drawn from ``[-max_translation, max_translation]``.

    Returns
    -------
    rotation : (3, 3) float
    translation : (3,) float
    """
    rng = np.random.default_rng(rng)
    rotation = Rotation.random(random_state=rng).as_matrix()
    translation = rng.uniform(-max_translation, max_translation, size=3)
    return rotation, translation
