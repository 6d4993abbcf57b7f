import numpy as np
from scipy.spatial import cKDTree

from tactile_viz.engine.belief.features import farthest_point_order


def test_feature_points_lie_on_surface_with_outward_normals(sphere_model):
    points, normals = sphere_model.features
    assert points.shape == (200, 3) and normals.shape == (200, 3)
    assert np.abs(sphere_model.exact.signed_distance(points)).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert np.all(sphere_model.exact.signed_distance(points + 0.05 * normals) > 0.04)
    assert np.all(sphere_model.exact.signed_distance(points - 0.05 * normals) < -0.04)


def test_feature_points_are_evenly_spread(sphere_model):
    points, _ = sphere_model.features
    spacing = cKDTree(points).query(points, k=2)[0][:, 1]
    # 200 disks on a sphere of area 113: a maximal Poisson-disk set has spacing ~0.6-0.8.
    assert spacing.min() > 0.5
    assert spacing.max() < 2 * spacing.min()


def test_feature_points_are_reproducible_and_seeded(sphere_model):
    first = sphere_model.features[0]
    again = type(sphere_model)("s", sphere_model.mesh, cache=type(sphere_model.cache)(False))
    np.testing.assert_allclose(again.features[0], first)
    other = sphere_model.with_params(feature_seed=1)
    assert not np.allclose(other.features[0], first)


def test_farthest_point_order_spreads_points():
    line = np.linspace(0, 1, 101)[:, None] * [1.0, 0.0, 0.0]
    order = farthest_point_order(line, 3, start=0)
    np.testing.assert_allclose(line[order, 0], [0.0, 1.0, 0.5])


def test_bundled_features_on_surface(bundled):
    for name, model in bundled.items():
        points, normals = model.features
        assert points.shape == (200, 3), name
        assert np.abs(model.exact.signed_distance(points)).max() < 1e-6, name
        outward = model.exact.signed_distance(points + 0.02 * normals)
        assert np.mean(outward > 0) > 0.97, name
