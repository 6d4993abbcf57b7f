"""The GPIS under a noisy sensor: the edge tilt its gradient rows allow a normal."""

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from tactile_viz.engine.shape.gpis import ThinPlateKernel, fit_gpis
from tactile_viz.engine.shape.gpis_prior import edge_tilt
from tactile_viz.engine.shape.level_set import zero_level_surface


def test_the_edge_tilt_grows_as_the_root_of_the_noise_over_the_size():
    assert edge_tilt(0.0, 0.1) == 0.0
    assert edge_tilt(0.002, 0.1, gain=0.0) == 0.0
    assert edge_tilt(0.002, 0.0) == 0.0  # no size: nothing to compare the noise with
    assert edge_tilt(0.002, 0.02) == pytest.approx(np.sqrt(0.1))
    assert edge_tilt(0.008, 0.08, gain=2.0) == pytest.approx(2 * edge_tilt(0.002, 0.02))
    # Scale-free: the same share of the size gives the same tilt in any unit.
    assert edge_tilt(2.0, 150.0) == pytest.approx(edge_tilt(0.002, 0.15))


def _noisy_cube_contacts(rng, side=0.02, count=150, position=0.002, degrees=2.0):
    cube = trimesh.creation.box((side,) * 3)
    points, faces = trimesh.sample.sample_surface(cube, count, seed=int(rng.integers(1 << 30)))
    axes = rng.normal(size=(count, 3))
    angles = rng.normal(0.0, np.radians(degrees), count)
    normals = np.array([trimesh.transformations.rotation_matrix(a, v)[:3, :3] @ n for a, v, n
                        in zip(angles, axes, cube.face_normals[faces])])
    return cube, points + rng.normal(0.0, position, points.shape), normals


def _ball_prior(radius):
    def prior(points):
        norm = np.linalg.norm(points, axis=1)
        return norm - radius, points / np.maximum(norm, 1e-12)[:, None]
    return prior


def _fitted_error(cube, contacts, normals, gradient_variance, position=0.002):
    """The two-way Hausdorff distance (share of the side) from the surface of a fit whose
    kernel scale was taken to its likelihood's maximum, as over a session's fits."""
    low, high = cube.bounds + np.array([[-0.006], [0.006]])
    kernel = ThinPlateKernel(1.2 * np.linalg.norm(high - low))
    scale = 1.0 / kernel.radius**3
    for _ in range(12):
        fit = fit_gpis(contacts, normals, _ball_prior(0.01), kernel, scale=scale,
                       noise_variance=position**2, gradient_noise_variance=gradient_variance)
        scale = fit.scale
    vertices, faces = zero_level_surface(fit, (low, high), 32)
    ours = trimesh.sample.sample_surface(trimesh.Trimesh(vertices, faces), 4000, seed=0)[0]
    truth = trimesh.sample.sample_surface(cube, 4000, seed=0)[0]
    return max(cKDTree(truth).query(ours)[0].max(),
               cKDTree(ours).query(truth)[0].max()) / cube.extents.max(), scale


def test_the_edge_tilt_keeps_a_noisy_cubes_fit_from_bending_to_the_noise(rng):
    # A 2 cm cube touched at 2 mm / 2 degrees: held to their 2 degrees, the normals beside
    # its edges (of the other face, placed across the edge by the noise) raise the fitted
    # scale, and the surface bends to the noise; allowed the edge tilt it lies nearer.
    tight, loose = [], []
    for _ in range(4):
        cube, contacts, normals = _noisy_cube_contacts(rng)
        error, tight_scale = _fitted_error(cube, contacts, normals, np.radians(2.0) ** 2 / 2)
        tight.append(error)
        tilt = np.hypot(np.radians(2.0), edge_tilt(0.002, 0.02))
        error, loose_scale = _fitted_error(cube, contacts, normals, tilt**2 / 2)
        loose.append(error)
        assert loose_scale < tight_scale / 2
    # One draw's farthest contact can hold both near its own offset (30% of the side).
    assert np.mean(loose) < np.mean(tight) - 0.03
