"""The stretch test of a hypothesis's residuals (:mod:`tactile_viz.engine.belief.stretch`):
a look-alike of another size or proportion misfits as its shape stretched; noise and
what is left of the pose fit do not."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.belief.stretch import STRETCH_PARAMETERS, stretch_p, stretch_regressors


def _surface(count, scale, rng, shape="box"):
    """Points all round a shape of size ``scale`` and their outward normals."""
    mesh = (trimesh.creation.box((2.0, 1.2, 0.8)) if shape == "box"
            else trimesh.creation.icosphere(3, 1.0))
    points, faces = trimesh.sample.sample_surface(mesh, count, seed=int(rng.integers(1 << 30)))
    return points * scale, mesh.face_normals[faces]


def _stretched(points, normals, stretch):
    """The residuals of contacts on a shape stretched by ``I + stretch`` against it."""
    return np.einsum("ij,jk,ik->i", normals, stretch, points)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_noise_and_pose_leave_p_values_uniform(scale):
    # A right hypothesis: noise, plus a pose a little off (a translation and a turn that
    # the fit leaves): p below 0.01 in about 1% of draws, never below 1e-6.
    rng = np.random.default_rng(3)
    p = []
    for _ in range(300):
        points, normals = _surface(120, scale, rng)
        shift, turn = rng.normal(0.0, 0.01, 3) * scale, rng.normal(0.0, 0.01, 3)
        residuals = (normals @ shift + np.cross(points, normals) @ turn
                     + rng.normal(0.0, 0.02 * scale, len(points)))
        p.append(stretch_p(residuals, points, normals, (0.02 * scale) ** 2)[0])
    p = np.array(p)
    assert np.mean(p < 0.01) < 0.04 and np.mean(p < 0.1) < 0.2 and p.min() > 1e-6


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("shape", ["box", "ball"])
def test_a_look_alike_of_another_size_or_proportion_is_a_stretch(scale, shape):
    # 3% larger, or 4% longer along a turned axis, under noise 2% of the size: the
    # residuals' RMS hardly grows, but their stretch stands out and is measured.
    rng = np.random.default_rng(5)
    points, normals = _surface(200, scale, rng, shape)
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    for stretch in (0.03 * np.eye(3), 0.04 * np.outer(axis, axis)):
        residuals = _stretched(points, normals, stretch) + rng.normal(0.0, 0.02 * scale, 200)
        p, beta = stretch_p(residuals, points, normals, (0.02 * scale) ** 2)
        assert p < 1e-6
        expected = [stretch[0, 0], stretch[1, 1], stretch[2, 2], stretch[0, 1],
                    stretch[0, 2], stretch[1, 2]]
        np.testing.assert_allclose(beta[:3], expected[:3], atol=0.012)
        # granted as a place's shared error, 5% of the size, the same is no misfit
        assert stretch_p(residuals, points, normals, (0.02 * scale) ** 2,
                         (0.05 * scale) ** 2)[0] > 1e-3


def test_regressors_are_the_residual_of_each_coefficient():
    rng = np.random.default_rng(7)
    points, normals = _surface(50, 1.0, rng)
    stretch = np.array([[0.1, 0.2, 0.3], [0.2, 0.4, 0.5], [0.3, 0.5, 0.6]])
    beta = [0.1, 0.4, 0.6, 0.2, 0.3, 0.5]
    np.testing.assert_allclose(stretch_regressors(points, normals) @ beta,
                               _stretched(points, normals, stretch))


def test_degenerate_inputs_give_a_plain_answer():
    rng = np.random.default_rng(9)
    points, normals = _surface(100, 1.0, rng)
    few = 6 + STRETCH_PARAMETERS  # no more than the pose's and the stretch's parameters
    assert stretch_p(np.zeros(few), points[:few], normals[:few], 1.0)[0] == 1.0
    nan = np.r_[np.nan, np.zeros(99)]
    assert stretch_p(nan, points, normals, 1.0)[0] == 1.0
    # contacts on one plane test what they can: finite, noise not flagged
    flat = np.column_stack([rng.uniform(-1, 1, (100, 2)), np.zeros(100)])
    up = np.tile([0.0, 0.0, 1.0], (100, 1))
    p, beta = stretch_p(rng.normal(0.0, 0.01, 100), flat, up, 1e-4)
    assert 0.0 <= p <= 1.0 and np.all(np.isfinite(beta))
    stretch = _stretched(points, normals, 0.01 * np.eye(3))
    assert stretch_p(stretch, points, normals, 0.0)[0] == 0.0
    assert stretch_p(np.zeros(100), points, normals, 0.0)[0] == 1.0
