import numpy as np
import pytest
import trimesh

from tactile_viz.engine.shape.sdf import ExactDistance, normalise_rows
from tactile_viz.experiments.sdf_speed import near_surface_points


def test_sphere_grid_matches_analytic_distance(sphere_model, rng):
    points = rng.uniform(-4.0, 4.0, size=(5000, 3))
    values, gradients = sphere_model.sdf.evaluate(points)
    analytic = np.linalg.norm(points, axis=1) - 3.0
    inside_grid = np.all(np.abs(points) <= sphere_model.sdf.upper, axis=1)
    # The icosphere's facets sit up to ~0.01 inside the true sphere.
    assert np.abs(values - analytic)[inside_grid].max() < 0.05
    radial = normalise_rows(points)
    near = inside_grid & (np.abs(analytic) < 1.0)
    assert np.min(np.einsum("ij,ij->i", gradients[near], radial[near])) > 0.99


def test_evaluate_keeps_leading_shape(sphere_model):
    values, gradients = sphere_model.sdf.evaluate(np.zeros((2, 5, 3)))
    assert values.shape == (2, 5) and gradients.shape == (2, 5, 3)


def test_outside_grid_fallback_is_positive_upper_bound(sphere_model, rng):
    directions = normalise_rows(rng.normal(size=(500, 3)))
    far = directions * rng.uniform(5.0, 500.0, size=(500, 1))
    values, gradients = sphere_model.sdf.evaluate(far)
    exact = sphere_model.exact.signed_distance(far)
    assert np.all(values > 0)
    assert np.all(values >= exact - 0.05)
    assert np.all(values <= exact * 1.8 + 0.1)  # the box corner detour is bounded by sqrt(3)
    np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0)
    assert np.min(np.einsum("ij,ij->i", gradients, directions)) > 0


def test_fallback_is_continuous_at_grid_border(sphere_model):
    grid = sphere_model.sdf
    border = np.array([[grid.upper[0], 0.3, -0.2]])
    inside = border - [1e-7, 0, 0]
    outside = border + [1e-7, 0, 0]
    assert sphere_model.sdf.distance(inside)[0] == pytest.approx(
        sphere_model.sdf.distance(outside)[0], abs=1e-5)


@pytest.mark.slow
def test_grid_is_cached_on_disk(sphere_model, tmp_path):
    grid = sphere_model.sdf
    files = list(tmp_path.glob("sdf5-*.npz"))
    assert len(files) == 1
    again = type(sphere_model)(sphere_model.name, sphere_model.mesh, cache=sphere_model.cache)
    np.testing.assert_array_equal(again.sdf.values, grid.values)
    finer = sphere_model.with_params(sdf_resolution=32)
    assert finer.sdf.shape != grid.shape
    assert len(list(tmp_path.glob("sdf5-*.npz"))) == 2


@pytest.mark.slow
def test_corrupt_cache_entry_is_rebuilt(sphere_model, tmp_path):
    values = sphere_model.sdf.values
    (entry,) = tmp_path.glob("sdf5-*.npz")
    entry.write_bytes(entry.read_bytes()[:100])
    rebuilt = type(sphere_model)(sphere_model.name, sphere_model.mesh, cache=sphere_model.cache)
    np.testing.assert_allclose(rebuilt.sdf.values, values)


@pytest.mark.slow
def test_bundled_grid_sdf_accuracy(bundled):
    """On every bundled object: error < 2% of the length, signs right beyond one voxel."""
    for name, model in bundled.items():
        rng = np.random.default_rng(7)
        points = near_surface_points(model, 2000, rng)
        values, gradients = model.sdf.evaluate(points)
        exact = model.exact.signed_distance(points)
        error = np.abs(values - exact)
        assert error.max() < 0.02 * model.length, f"{name}: max error {error.max():.3f}"
        far = np.abs(exact) > model.sdf.spacing
        assert np.all(np.sign(values[far]) == np.sign(exact[far])), f"{name}: wrong sign"
        np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0, atol=1e-9)


def _fork(cache):
    """Four 0.08-unit tines, apart from the handle, on a 6-unit fork: thinner than two
    voxels at 24 over the padded 8 units."""
    import trimesh

    from tactile_viz.engine.shape.objects import ModelParams, ObjectModel

    parts = [trimesh.creation.box((1.6, 0.3, 3.0))]
    parts += [trimesh.creation.box((0.12, 0.08, 3.0), trimesh.transformations.translation_matrix(
        (x, 0.0, 3.1))) for x in (-0.6, -0.2, 0.2, 0.6)]
    mesh = trimesh.util.concatenate(parts)
    params = ModelParams(sdf_resolution=24, sdf_max_resolution=24, n_features=50)
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, "fork", params=params, cache=cache)


def test_a_grid_is_refined_until_it_resolves_thin_parts(tmp_path):
    import trimesh

    from tactile_viz.engine.io.cache import ArrayCache
    from tactile_viz.engine.shape.objects import SURFACE_CHECKS
    from tactile_viz.engine.shape.sdf_build import MAX_REFINED_NODES, THIN_MISSES, missed_share

    coarse = _fork(ArrayCache(tmp_path))
    assert coarse.grid_resolution == 24
    samples, _ = trimesh.sample.sample_surface(coarse.mesh, SURFACE_CHECKS, seed=1)
    _, closest, face = coarse.exact.query(samples)
    normals = coarse.mesh.face_normals[face]
    folded = missed_share(coarse.sdf, closest, normals)
    assert folded > THIN_MISSES  # the tines fold
    fine = coarse.with_params(sdf_max_resolution=256)
    assert fine.grid_resolution > 24 and fine.sdf.codes.size <= MAX_REFINED_NODES
    assert missed_share(fine.sdf, closest, normals) <= THIN_MISSES
    # The choice is cached: a new model of the same mesh reads it without a fit.
    again = type(fine)(fine.name, fine.mesh, fine.params, fine.cache)
    assert again.grid_resolution == fine.grid_resolution and "exact" not in again.__dict__


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_refined_grid_is_exact_near_the_surface_and_the_coarse_exact_field_beyond(scale,
                                                                                    rng):
    """A grid refined past an exact grid's resolution (48 voxels past 24, as a thin cup's
    128 past 64) holds the exact grid's values within the band and, beyond it, a field as
    close to the distance as the unrefined exact grid's; tiny and huge."""
    from tactile_viz.engine.shape.sdf import ExactDistance
    from tactile_viz.engine.shape.sdf_build import REFINED_BAND, build_sdf_grid, grid_layout

    mesh = _cup(wall=0.3)
    exact = ExactDistance(mesh.vertices * scale, mesh.faces)
    bounds, padding = mesh.bounds * scale, 0.5 * scale
    refined = build_sdf_grid(exact, bounds, 48, padding, band=REFINED_BAND,
                             exact_resolution=24)
    fine, coarse = (build_sdf_grid(exact, bounds, r, padding) for r in (48, 24))
    spacing = grid_layout(bounds, 48, padding)[1]
    points = rng.uniform(bounds[0] - padding, bounds[1] + padding, (6000, 3))
    truth = exact.signed_distance(points)
    value = {name: grid.evaluate(points)[0]
             for name, grid in (("refined", refined), ("fine", fine), ("coarse", coarse))}
    near = np.abs(truth) < 2 * spacing  # every corner of its cell within the band
    assert near.sum() > 500 and (~near).sum() > 500
    np.testing.assert_allclose(value["refined"][near], value["fine"][near],
                               atol=1e-3 * spacing)
    error = {name: np.median(np.abs(v[~near] - truth[~near]) / np.abs(truth[~near]))
             for name, v in value.items()}
    assert error["refined"] <= 1.2 * error["coarse"]
    assert error["fine"] < error["refined"]  # the far field is the coarse one, not exact


def test_a_refined_grid_is_banded_by_its_key_only_where_grids_are_exact(tmp_path):
    """The grid of a thin shape refined past ``sdf_resolution`` is keyed (and built) exact
    within ``REFINED_BAND`` voxels; an unrefined grid's key is as before, and a banded
    preset's refined grid keeps its own band."""
    from tactile_viz.engine.io.cache import ArrayCache
    from tactile_viz.engine.shape.sdf_build import REFINED_BAND

    fork = _fork(ArrayCache(tmp_path)).with_params(sdf_max_resolution=256)
    assert fork.grid_resolution > 24
    assert fork._sdf_params() == {"resolution": fork.grid_resolution,
                                  "padding": fork._padding, "band": REFINED_BAND,
                                  "exact_resolution": 24}
    assert fork._grid_params(24) == {"resolution": 24, "padding": fork._padding}
    banded = fork.with_params(sdf_exact_band=2.0)
    assert banded._grid_params(48) == {"resolution": 48, "padding": fork._padding,
                                       "band": 2.0}


def test_a_compact_shape_keeps_its_grid(sphere_model):
    refining = sphere_model.with_params(sdf_max_resolution=256)
    assert refining.grid_resolution == sphere_model.params.sdf_resolution


def _numpy_interpolate(codes, gradient_codes, offset, shape, origin, spacing, value_step,
                       points):
    """``interpolate`` as numpy expressions (what the compiled loop replaced)."""
    spacing = np.asarray(spacing, dtype=float)[..., None]
    clamped = np.clip(points, origin, origin + spacing * (shape - 1))
    position = (clamped - origin) / spacing
    base = np.minimum(position.astype(np.int64), shape - 2)
    fx, fy, fz = np.moveaxis(position - base, -1, 0)
    nz, nyz = shape[..., 2], shape[..., 1] * shape[..., 2]
    index = offset + base[..., 0] * nyz + base[..., 1] * nz + base[..., 2]
    value, gradient = np.zeros(points.shape[:-1]), np.zeros(points.shape)
    for dx, wx in ((0, 1 - fx), (1, fx)):
        for dy, wy in ((0, 1 - fy), (1, fy)):
            wxy = wx * wy
            for dz, wz in ((0, 1 - fz), (1, fz)):
                weight = wxy * wz
                corner = index + (dx * nyz + dy * nz + dz)
                value += weight * np.take(codes, corner)
                gradient += weight[..., None] * np.take(gradient_codes, corner, axis=0)
    outside = np.linalg.norm(points - clamped, axis=-1)
    away = outside > 0
    gradient[away] = (points - clamped)[away] / outside[away][:, None]
    return value * value_step + outside, normalise_rows(gradient)


def test_compiled_interpolation_is_numpys_to_the_bit(sphere_model, rng):
    # Every trajectory stays the same only if every value and gradient is rounded as the
    # numpy expressions rounded them: inside the grid, beyond it, on its nodes and faces.
    grid = sphere_model.sdf
    codes, gradients = grid.codes.reshape(-1), grid.gradient_codes.reshape(-1, 3)
    shape = np.array(grid.shape)
    points = np.concatenate([rng.normal(scale=4.0, size=(301, 3)),
                             grid.origin + grid.spacing * rng.integers(0, 8, size=(20, 3)),
                             [grid.upper, grid.origin, grid.upper + 5.0]])
    expected = _numpy_interpolate(codes, gradients, 0, shape, grid.origin, grid.spacing,
                                  grid.value_step, points)
    values, normals = grid.evaluate(points)
    assert np.array_equal(values, expected[0]) and np.array_equal(normals, expected[1])
    # Several grids at once, broadcast per row (the prior bank's call).
    stacked = grid.evaluate(points.reshape(2, -1, 3))
    assert np.array_equal(stacked[0].ravel(), values)


def test_the_nearest_face_is_the_signed_querys_without_its_sign(bundled, rng):
    """``nearest_face`` (the noisy novelty test's look-up) skips only the inside test."""
    exact = bundled["mug_1"].exact
    points = bundled["mug_1"].mesh.sample(300) + rng.normal(0.0, 0.2, (300, 3))
    signed, closest, face = exact.query(points)
    distance, nearest = exact.nearest_face(points)
    np.testing.assert_array_equal(distance, np.abs(signed))
    np.testing.assert_array_equal(nearest, face)
    normals = exact.face_normal(nearest)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    # Points just outside a face lie along its outward normal from their closest point.
    outside = signed > 1e-3
    along = np.einsum("ij,ij->i", points[outside] - closest[outside], normals[outside])
    assert np.median(along / signed[outside]) > 0.99


def _cup(wall=0.5, sections=48):
    """A closed cup: a revolved profile with a cavity (its nodes in several regions)."""
    import trimesh

    z = np.linspace(wall, 3.0, 12)
    profile = np.vstack([[0, 0], [1.5, 0], np.column_stack([np.full(12, 1.5), z]),
                         np.column_stack([np.full(12, 1.5 - wall), z[::-1]]), [0, wall]])
    return trimesh.creation.revolve(profile, sections=sections)


@pytest.mark.parametrize("open_surface", [False, True])
def test_a_grid_asks_the_winding_number_where_it_must_and_gets_every_nodes_sign(open_surface):
    from tactile_viz.engine.shape.sdf import ExactDistance
    from tactile_viz.engine.shape.sdf_build import build_sdf_grid, grid_layout

    mesh = _cup()
    faces = mesh.faces[5:] if open_surface else mesh.faces  # a hole: nothing is skipped
    exact = ExactDistance(mesh.vertices, faces)
    assert exact.closed is not open_surface
    grid = build_sdf_grid(exact, mesh.bounds, resolution=40, padding=0.5)
    origin, spacing, counts = grid_layout(mesh.bounds, 40, 0.5)
    axes = [origin[i] + spacing * np.arange(counts[i]) for i in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    every = type(grid).from_values(origin, spacing,  # every node asked, as before
                                   exact.signed_distance(nodes).reshape(tuple(counts)))
    for name, array in grid.to_arrays().items():
        np.testing.assert_array_equal(array, every.to_arrays()[name], err_msg=name)
    far = np.abs(grid.values) > 1.5 * spacing  # regions inside the wall, the cavity, outside
    assert (grid.values[far] < 0).any() and (grid.values[far] > 0).any()


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_sign_parts_join_neighbours_no_surface_can_pass_between(scale):
    """Nodes along a line crossed by a plane between the second and third: distances 1.5,
    0.5, 0.5, 1.5, 2.5 voxels. The first two join (1.5 + 0.5 > 1: no surface point lies
    between them), the two beside the plane do not (0.5 + 0.5), the rest join the third."""
    from tactile_viz.engine.shape.sdf_build import sign_parts

    spacing = 0.7 * scale
    distance = np.array([1.5, 0.5, 0.5, 1.5, 2.5]) * spacing
    part, count = sign_parts(distance, (5, 1, 1), spacing)
    assert count == 2
    assert part[0] == part[1] != part[2] == part[3] == part[4]
    alone, many = sign_parts(distance, (5, 1, 1), spacing, linked=False)
    assert many == 4 and len(np.unique(alone)) == 4  # the far ones a region, each near one


def test_linked_signs_ask_fewer_winding_numbers_for_the_same_grid():
    """A cup's grid: the same signs as a part for each node within a voxel, from fewer
    winding numbers (the two a part asks, and the near nodes that no neighbour joins)."""
    from tactile_viz.engine.shape.sdf import ExactDistance
    from tactile_viz.engine.shape.sdf_build import (
        _exact_distance,
        _grid_inside,
        _node_positions,
        grid_layout,
    )

    mesh = _cup(wall=0.3)
    exact = ExactDistance(mesh.vertices, mesh.faces)
    origin, spacing, counts = grid_layout(mesh.bounds, 40, 0.5)
    shape = tuple(int(n) for n in counts)
    nodes = _node_positions(origin, spacing, shape)
    distance = _exact_distance(exact, nodes, np.arange(int(np.prod(shape))))
    asked = []
    inside = exact.inside

    def counted(points):
        asked.append(len(points))
        return inside(points)

    exact.inside = counted
    separate = _grid_inside(exact, nodes, distance, shape, spacing, linked=False)
    alone, asked[:] = sum(asked), []
    linked = _grid_inside(exact, nodes, distance, shape, spacing)
    np.testing.assert_array_equal(linked, separate)
    assert sum(asked) < 0.7 * alone


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_inside_test_is_the_winding_numbers_and_skips_points_beyond_the_box(scale,
                                                                              rng):
    """Points outside the mesh's bounding box are outside (their winding number is below
    1/2), on a closed mesh and on an open one (a box without its lid); the rest keep the
    winding number's answer."""
    import trimesh

    from tactile_viz.engine.shape.sdf import ExactDistance

    closed = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    lidless = closed.submesh([np.flatnonzero(closed.face_normals[:, 2] < 0.5)],
                             append=True)
    for mesh in (closed, lidless):
        exact = ExactDistance(mesh.vertices * scale, mesh.faces)
        points = rng.uniform(-1.5, 1.5, (4000, 3)) * scale
        winding = exact._winding.winding_number(points) > 0.5
        np.testing.assert_array_equal(exact.inside(points), winding)
        beyond = np.any(np.abs(points) > np.array([1.0, 0.5, 0.25]) * scale, axis=1)
        assert beyond.any() and not exact.inside(points[beyond]).any()
        assert exact.inside(np.zeros((1, 3)))[0]  # the lid's gap leaves the middle in


def _every_node(exact, origin, spacing, counts):
    axes = [origin[i] + spacing * np.arange(counts[i]) for i in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return exact.query(nodes)[0].reshape(tuple(counts))


@pytest.mark.parametrize(("band", "scale"), [(2.0, 1.0), (4.0, 1e-3), (4.0, 1e3)])
def test_a_banded_grid_is_exact_near_the_surface_and_close_beyond(band, scale):
    """A banded grid holds the exact distance at every node within ``band`` voxels of the
    surface, exact signs everywhere, and beyond the band a value within some share of the
    distance, the less the wider the band (a cup: a cavity and concave seams, where
    interpolation cuts corners; tiny and huge)."""
    from tactile_viz.engine.shape.sdf import ExactDistance
    from tactile_viz.engine.shape.sdf_build import build_sdf_grid, grid_layout

    mesh = _cup(wall=0.3)
    exact = ExactDistance(mesh.vertices * scale, mesh.faces)
    bounds = mesh.bounds * scale
    origin, spacing, counts = grid_layout(bounds, 48, 1.0 * scale)
    truth = _every_node(exact, origin, spacing, counts)
    grid = build_sdf_grid(exact, bounds, resolution=48, padding=1.0 * scale, band=band)
    plain = build_sdf_grid(exact, bounds, resolution=48, padding=1.0 * scale)
    near = np.abs(truth) < band * spacing
    # Within the band the values are the exact grid's (to its 16-bit steps, which differ
    # by the largest value) and every sign is the exact one.
    step = max(grid.value_step, plain.value_step)
    np.testing.assert_allclose(grid.values[near], plain.values[near], rtol=0, atol=step)
    np.testing.assert_array_equal(np.sign(grid.values), np.sign(plain.values))
    assert (~near).mean() > 0.5  # most nodes are interpolated
    error = np.abs(grid.values - truth)
    assert np.all(error[~near] <= (0.1 + 0.4 / band) * np.abs(truth[~near]) + step)


def test_a_banded_distance_is_the_exact_one_on_a_small_grid():
    """At or below the coarsest size nothing is interpolated."""
    from tactile_viz.engine.shape.sdf import ExactDistance
    from tactile_viz.engine.shape.sdf_build import banded_distance, grid_layout

    mesh = _cup()
    exact = ExactDistance(mesh.vertices, mesh.faces)
    origin, spacing, counts = grid_layout(mesh.bounds, 12, 0.5)
    np.testing.assert_array_equal(banded_distance(exact, origin, spacing, counts, 1.0),
                                  np.abs(_every_node(exact, origin, spacing, counts)))


def test_a_banded_prior_keeps_its_own_cache_entries(tmp_path):
    """Exact and banded grids of one mesh are separate cache entries; the exact one keeps
    the key it had before bands."""
    from tactile_viz.engine.io.cache import ArrayCache

    model = _fork(ArrayCache(tmp_path))
    banded = model.with_params(sdf_exact_band=3.0)
    assert model._sdf_params() == {"resolution": 24, "padding": model._padding}
    assert banded._sdf_params() == {**model._sdf_params(), "band": 3.0}
    assert not np.array_equal(model.sdf.codes, banded.sdf.codes)
    assert model.sdf.shape == banded.sdf.shape


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_pseudonormal_sign_is_the_winding_numbers(scale):
    # Points at every distance from a box, a ball, a ring (concave edges) and about their
    # vertices and edges: the same signed distance as the winding number's off the
    # surface; two pieces (which may overlap) keep the winding number.
    rng = np.random.default_rng(4)
    ring = trimesh.creation.annulus(r_min=0.3, r_max=1.0, height=0.5)
    for mesh in (trimesh.creation.box((1.0, 0.6, 0.3)), trimesh.creation.icosphere(2), ring):
        exact = ExactDistance(mesh.vertices * scale, mesh.faces)
        assert exact._pseudonormals is not None
        points = np.vstack([mesh.vertices, mesh.triangles_center,
                            (mesh.vertices[mesh.edges_unique].mean(axis=1))]) * scale
        points = np.vstack([points + rng.normal(0.0, s * scale, points.shape)
                            for s in (1e-4, 1e-2, 0.3)])
        expected, closest, face = exact.query(points)
        near, near_closest, near_face = exact.query_near(points)
        np.testing.assert_allclose(near, expected, atol=1e-9 * scale)
        np.testing.assert_array_equal(near_face, face)
    two = trimesh.util.concatenate([trimesh.creation.box((1, 1, 1)),
                                    trimesh.creation.box((1, 1, 1)).apply_translation([0.5] * 3)])
    exact = ExactDistance(two.vertices * scale, two.faces)
    assert exact._pseudonormals is None
    inside = np.array([[0.6, 0.6, 0.6], [0.2, 0.2, 0.2]]) * scale
    np.testing.assert_array_equal(exact.query_near(inside)[0] < 0, [True, True])
