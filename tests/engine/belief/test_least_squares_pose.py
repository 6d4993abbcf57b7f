"""The filter's least-squares refinement of one particle, without the filter."""

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from tactile_viz.engine.belief.pose_refinement import least_squares_pose

from .conftest import box_distance

HALF = np.array([3.0, 1.5, 1.0])  # a 6 x 3 x 2 box


def box_evaluate(classes, points):
    """The box's exact signed distance and outward unit gradient: (k, m), (k, m, 3)."""
    return box_distance(points, HALF)


def _observations(rng, count=40):
    """Contacts on the box's faces (object frame) with their normals, and misses."""
    axis = rng.integers(0, 3, count)
    side = rng.choice([-1.0, 1.0], count)
    points = rng.uniform(-1, 1, (count, 3)) * HALF * 0.9
    points[np.arange(count), axis] = side * HALF[axis]
    normals = np.zeros((count, 3))
    normals[np.arange(count), axis] = side
    misses = rng.uniform(-1, 1, (10, 3)) * (HALF + 1.0)
    misses = misses[box_evaluate(None, misses[None])[0][0] > 0.3]
    return points, normals, misses


def _posed(rotation, translation, points, normals, misses):
    return (
        points @ rotation.T + translation,
        normals @ rotation.T,
        misses @ rotation.T + translation,
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_a_pose_knocked_off_comes_back(seed):
    rng = np.random.default_rng(seed)
    rotation = Rotation.random(random_state=seed).as_matrix()
    translation = rng.uniform(-2, 2, 3)
    contacts, normals, misses = _posed(rotation, translation, *_observations(rng))
    start = Rotation.from_rotvec([0.08, -0.05, 0.06]).as_matrix() @ rotation
    fitted = least_squares_pose(
        box_evaluate,
        0,
        start,
        translation + [0.2, -0.1, 0.15],
        contacts,
        normals,
        misses,
        0.01,
        0.05,
    )
    np.testing.assert_allclose(fitted[0], rotation, atol=1e-6)
    np.testing.assert_allclose(fitted[1], translation, atol=1e-6)


def test_the_batched_jacobian_is_scipys_forward_difference():
    """The same fit as scipy's own two-point Jacobian, one pose a call (the filter's
    refinement before the six poses of a Jacobian were evaluated in one call)."""
    rng = np.random.default_rng(4)
    rotation = Rotation.random(random_state=4).as_matrix()
    translation = rng.uniform(-2, 2, 3)
    contacts, normals, misses = _posed(rotation, translation, *_observations(rng))
    contacts = contacts + rng.normal(0, 0.02, contacts.shape)  # a fit that ends off zero
    start = Rotation.from_rotvec([0.1, 0.02, -0.07]).as_matrix() @ rotation
    shifted = translation + [0.1, 0.1, -0.2]
    centre = contacts.mean(axis=0)
    points = np.vstack([contacts, misses])

    def pose(x):
        turn = Rotation.from_rotvec(x[:3]).as_matrix()
        return turn @ start, turn @ (shifted - centre) + centre + x[3:]

    def residuals(x):
        turned, moved = pose(x)
        values, gradients = box_evaluate(None, ((points - moved) @ turned)[None])
        normal_error = gradients[0, : len(contacts)] - normals @ turned
        outside = np.minimum(values[0, len(contacts) :] - 0.1, 0.0)
        return np.concatenate(
            [values[0, : len(contacts)] / 0.05, normal_error.ravel() / 0.1, outside / 0.05]
        )

    expected = pose(least_squares(residuals, np.zeros(6), method="trf", max_nfev=3, x_scale=0.1).x)
    fitted = least_squares_pose(
        box_evaluate,
        0,
        start,
        shifted,
        contacts,
        normals,
        misses,
        0.05,
        0.1,
        clearance=0.1,
        evaluations=3,
    )
    np.testing.assert_allclose(fitted[0], expected[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fitted[1], expected[1], rtol=0, atol=1e-12)
