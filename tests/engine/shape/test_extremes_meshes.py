"""Meshes and signed distances at the extremes.

Files at scales 1e-3 and 1e3 give the same object model as at scale 1; thin parts (the
legs of the bundled chairs, a needle thinner than a voxel) keep usable distances and are
found by the simulator; a dense mesh is decimated with a warning; the SDF grid far
outside its box stays finite and positive.
"""

import inspect
import warnings

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import (
    Contact,
    ContactSimulator,
    GroundTruth,
    MeshError,
    MeshWarning,
    ModelParams,
    ObjectModel,
    PriorLibrary,
    load_mesh,
    prepare_mesh,
)
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.io.cache import ArrayCache
from tactile_viz.engine.shape.meshes import DECIMATED_FACES, MAX_FACES
from tactile_viz.engine.shape.metrics import surface_samples


def _ellipsoid():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    mesh.apply_scale([1.0, 0.6, 0.4])
    return mesh


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The ellipsoid at scale 1 as a model with a coarse private SDF grid."""
    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    mesh = _ellipsoid()
    params = ModelParams(sdf_resolution=24, n_features=60)
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, "ellipsoid", params, cache,
                                   longest_side=6.0)


@pytest.mark.parametrize("suffix", [".stl", ".ply", ".obj"])
@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_scaled_files_give_the_same_model(tmp_path, reference, scale, suffix):
    """Scale and offset are removed on loading; the SDF grid and the feature points built
    from the file match those of the unscaled mesh (STL stores float32)."""
    mesh = _ellipsoid()
    mesh.apply_scale(scale)
    mesh.apply_translation(np.array([3.0, -1.0, 2.0]) * scale)
    path = tmp_path / f"ellipsoid{suffix}"
    mesh.export(path)
    model = ObjectModel.from_file(path, params=reference.params, cache=ArrayCache(tmp_path),
                                  longest_side=6.0)
    assert model.length == pytest.approx(6.0)
    np.testing.assert_allclose(model.mesh.bounds, reference.mesh.bounds, atol=1e-5)
    # Within the grids' 16-bit value steps (each a 65,535th of the largest value).
    np.testing.assert_allclose(model.sdf.values, reference.sdf.values,
                               atol=2 * reference.sdf.value_step)
    points, normals = model.features
    assert np.all(np.isfinite(points)) and np.allclose(np.linalg.norm(normals, axis=1), 1)
    assert np.abs(reference.exact.signed_distance(points)).max() < 1e-4


@pytest.mark.parametrize("distance", [10.0, 1e3, 1e6])
def test_sdf_grid_far_outside_is_finite_and_positive(reference, distance):
    directions = trimesh.creation.icosphere(subdivisions=1).vertices
    values, gradients = reference.sdf.evaluate(distance * directions)
    exact = reference.exact.signed_distance(distance * directions)
    assert np.all(np.isfinite(values)) and np.all(values > 0)
    np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0)
    # The fallback is a bound of the right size: distance to the box plus the clamped value.
    np.testing.assert_allclose(values, exact, rtol=0.2)
    assert np.all(np.sum(gradients * directions, axis=1) > 0.5)  # pointing away


# ----------------------------------------------------------------- thin parts
def _thin_surface_points(model, count=3000, max_thickness=0.3):
    """Surface points (with outward normals) where the part is thinner than
    ``max_thickness`` along the normal, and the thickness there."""
    points = surface_samples(model, count, seed=0)
    _, closest, face = model.exact.query(points)
    normals = model.exact.surface_normal(closest, face)
    depths = np.linspace(0.01, max_thickness, 30)
    inner = closest[:, None, :] - depths[None, :, None] * normals[:, None, :]
    values = model.exact.signed_distance(inner.reshape(-1, 3)).reshape(len(points), -1)
    through = values > 0
    thin = through.any(axis=1)
    thickness = depths[np.argmax(through, axis=1)]
    return closest[thin], normals[thin], thickness[thin]


@pytest.mark.parametrize("name", ["office_chair", "home_chair"])
def test_chair_legs_keep_usable_distances(bundled, name):
    """Parts about two voxels thick: the grid is near zero on their surface, its gradient
    follows the true normal and its sign is right in the middle of the part."""
    model = bundled[name]
    points, normals, thickness = _thin_surface_points(model)
    assert len(points) >= 20, "the chair should have thin parts"
    values, gradients = model.sdf.evaluate(points)
    assert np.abs(values).max() < 0.05
    assert np.all(np.sum(gradients * normals, axis=1) > 0.7)
    middle = points - 0.5 * thickness[:, None] * normals
    assert np.all(model.sdf.distance(middle) < 0)


@pytest.mark.parametrize("name", ["office_chair", "home_chair"])
def test_simulator_does_not_pass_through_chair_legs(bundled, name):
    model = bundled[name]
    points, normals, _ = _thin_surface_points(model)
    truth = GroundTruth(model, np.eye(3), np.zeros(3))
    simulator = ContactSimulator(truth)
    for point, normal in zip(points[:40], normals[:40]):
        # From just outside, straight through the part and 1 unit beyond it.
        observation = simulator.probe([point + 0.1 * normal, point - 1.0 * normal])
        assert isinstance(observation, Contact)
        assert abs(truth.signed_distance(observation.position[None])[0]) <= 0.01
        assert np.linalg.norm(observation.position - point) < 0.05


@pytest.fixture(scope="module")
def needle(tmp_path_factory):
    """A 6 x 0.05 x 0.05 needle: thinner than the 0.125 voxel of the default SDF grid."""
    box = trimesh.creation.box(extents=(6.0, 0.05, 0.05))
    return ObjectModel.from_arrays(box.vertices, box.faces, "needle",
                                   cache=ArrayCache(tmp_path_factory.mktemp("needle")))


def test_needle_thinner_than_a_voxel(needle):
    """No grid node lies inside, so the grid cannot go negative; on the surface it stays
    within a voxel of zero, and the simulator still finds the needle."""
    assert needle.mesh.is_watertight and needle.length == pytest.approx(6.0)
    voxel = needle.sdf.spacing
    assert voxel > 0.05
    points = surface_samples(needle, 500, seed=1)
    values = needle.sdf.distance(points)
    assert np.all(np.isfinite(values)) and np.abs(values).max() <= voxel * np.sqrt(3) / 2
    truth = GroundTruth(needle, np.eye(3), np.zeros(3))
    simulator = ContactSimulator(truth)
    for x in np.linspace(-2.5, 2.5, 11):
        observation = simulator.probe([[x, 0, 1.0], [x, 0, -1.0]])
        assert isinstance(observation, Contact)
        assert observation.normal[2] > np.cos(np.radians(3))


@pytest.mark.slow
def test_needle_is_recognised_among_blunt_priors(needle, tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=3)
    box = trimesh.creation.box(extents=(6, 3, 2))
    cache = ArrayCache(tmp_path)
    library = PriorLibrary([needle,
                            ObjectModel.from_arrays(sphere.vertices, sphere.faces, "ball",
                                                    cache=cache),
                            ObjectModel.from_arrays(box.vertices, box.faces, "box", cache=cache)])
    truth = GroundTruth(needle, np.eye(3), np.array([0.5, 0.0, 0.0]))
    simulator = ContactSimulator(truth)
    rng = np.random.default_rng(0)
    particle_filter = ParticleFilter(library, rng=0)
    for _ in range(12):
        point = truth.surface_points(1, rng)[0]
        _, _, normal = truth.closest(point[None])
        state = particle_filter.update(simulator.probe([point + normal[0], point - normal[0]]))
    assert np.all(np.isfinite(state.particles.log_weights))
    assert state.map_class == "needle" and not state.novel


# ----------------------------------------------------------------- huge meshes
def test_decimation_path_on_a_small_limit():
    """The decimation above ``max_faces`` (fast here with a small limit): a warning naming
    the source and the counts, a closed surface close to the original."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=3.0)  # 5,120 faces
    with pytest.warns(MeshWarning, match=r"ball: decimated from 5120 to \d+ faces"):
        mesh = prepare_mesh(sphere.vertices, sphere.faces, source="ball", max_faces=1000,
                            longest_side=6.0)
    assert len(mesh.faces) <= 1000 and mesh.is_watertight and mesh.volume > 0
    assert mesh.metadata["decimated_from"] == 5120
    assert mesh.extents.max() == pytest.approx(6.0)
    radius = np.linalg.norm(mesh.vertices, axis=1)
    assert np.all(np.abs(radius - 3.0) < 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no decimation, no warning
        assert len(prepare_mesh(sphere.vertices, sphere.faces, max_faces=None).faces) == 5120


def test_a_dense_scan_loads_decimated(tmp_path):
    """A 47,200-face sphere file over a cap of 20,000 faces is read, checked, decimated to
    the cap with a MeshWarning, and stays within 0.005 of the true sphere: the path a
    1,196,000-face scan takes by default (over ``MAX_FACES``, to ``DECIMATED_FACES``), at a
    25th of the size (its time is a benchmark's to measure: a 2-million-face one took 20 s
    alone and 136 s under load)."""
    assert inspect.signature(load_mesh).parameters["max_faces"].default == MAX_FACES
    assert MAX_FACES > DECIMATED_FACES
    sphere = trimesh.creation.uv_sphere(radius=3.0, count=[120, 100])
    cap = 20_000
    assert len(sphere.faces) > 2 * cap
    path = tmp_path / "dense.ply"
    sphere.export(path)
    with pytest.warns(MeshWarning, match=rf"dense.ply: decimated from {len(sphere.faces)} "
                                         rf"to {cap} faces"):
        mesh = load_mesh(path, max_faces=cap)
    assert len(mesh.faces) == cap
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.extents.max() == pytest.approx(6.0)
    radius = np.linalg.norm(mesh.vertices, axis=1)
    assert np.abs(radius - 3.0).max() < 5e-3


def test_bad_mesh_arrays_at_the_extremes():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    for scale in (1e-300, 1e300):
        with pytest.raises(MeshError):
            prepare_mesh(sphere.vertices * scale * np.array([1, 1, 0]), sphere.faces,
                         source="flat")
    # At their own size they are refused with a hint; normalised they are still spheres.
    for scale in (1e-150, 1e150):
        with pytest.raises(MeshError, match="units long.*give the file's units"):
            prepare_mesh(sphere.vertices * scale, sphere.faces)
    huge = prepare_mesh(sphere.vertices * 1e150, sphere.faces, longest_side=6.0)
    assert huge.extents.max() == pytest.approx(6.0)
    tiny = prepare_mesh(sphere.vertices * 1e-150, sphere.faces, longest_side=6.0)
    np.testing.assert_allclose(tiny.vertices, huge.vertices, atol=1e-6)
    metres = prepare_mesh(sphere.vertices * 1e150, sphere.faces, scale=1e-150)  # a unit factor
    np.testing.assert_allclose(metres.vertices * 3.0, huge.vertices, atol=1e-5)
