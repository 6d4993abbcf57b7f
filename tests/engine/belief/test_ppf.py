import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from scipy.spatial.transform import Rotation

from tactile_viz.engine.belief.ppf import (
    PairTable,
    align_pairs,
    is_degenerate,
    neighbour_bins,
    pair_features,
    quantise,
    rotation_to_x,
)
from tactile_viz.engine.transforms import (
    inverse_transform_points,
    inverse_transform_points_batch,
    random_pose,
    transform_points,
)

SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])
poses = st.tuples(st.integers(0, 2**32 - 1), st.floats(-10, 10), st.floats(-10, 10),
                  st.floats(-10, 10))


def _pose(seed, x, y, z):
    return Rotation.random(random_state=seed).as_matrix(), np.array([x, y, z])


@pytest.fixture(scope="module")
def mug_features(bundled):
    return bundled["mug_1"].features


@SETTINGS
@given(pose=poses, i=st.integers(0, 199), j=st.integers(0, 199))
def test_alignment_recovers_pose(mug_features, pose, i, j):
    points, normals = mug_features
    rotation, translation = _pose(*pose)
    p1, n1, p2, n2 = points[i], normals[i], points[j], normals[j]
    if i == j or is_degenerate(p1, n1, p2, n2):
        return
    world = transform_points(np.stack([p1, p2]), rotation, translation)
    found_r, found_t = align_pairs((p1[None], n1[None], p2[None]),
                                   (world[:1], (rotation @ n1)[None], world[1:]))
    np.testing.assert_allclose(found_r[0], rotation, atol=1e-6)
    np.testing.assert_allclose(found_t[0], translation, atol=1e-6)


@SETTINGS
@given(pose=poses, i=st.integers(0, 199), j=st.integers(0, 199))
def test_features_are_invariant_under_rigid_motion(mug_features, pose, i, j):
    points, normals = mug_features
    rotation, translation = _pose(*pose)
    moved = transform_points(points[[i, j]], rotation, translation)
    turned = normals[[i, j]] @ rotation.T
    np.testing.assert_allclose(
        pair_features(moved[0], turned[0], moved[1], turned[1]),
        pair_features(points[i], normals[i], points[j], normals[j]), atol=1e-9)


def test_rotation_to_x_handles_parallel_and_antiparallel():
    normals = np.array([[1.0, 0, 0], [-1.0, 0, 0], [-1.0, 1e-13, 0], [0, 0, 1.0]])
    rotations = rotation_to_x(normals)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", rotations, normals),
                               np.tile([1.0, 0, 0], (4, 1)), atol=1e-9)
    np.testing.assert_allclose(rotations @ np.transpose(rotations, (0, 2, 1)),
                               np.tile(np.eye(3), (4, 1, 1)), atol=1e-9)


def test_degenerate_pairs_are_flagged():
    p1, p2 = np.zeros(3), np.array([1.0, 0, 0])
    up, along = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    assert is_degenerate(p1, along, p2, up)          # d parallel to n1
    assert is_degenerate(p1, up, p2, -along)         # d antiparallel to n2
    assert is_degenerate(p1, up, p1, up)             # zero distance
    assert not is_degenerate(p1, up, p2, up)         # parallel normals still fix a pose


def test_pair_table_has_all_usable_ordered_pairs(mug_features):
    points, normals = mug_features
    table = PairTable.build(points, normals)
    first, second = np.nonzero(~np.eye(200, dtype=bool))
    usable = ~is_degenerate(points[first], normals[first], points[second], normals[second])
    assert len(first) == 39800 and len(table) == usable.sum()
    assert np.all(np.diff(table.keys) > 0) and table.starts[-1] == len(table)
    assert table.first.dtype == np.uint8  # 200 feature points fit a byte


def test_lookup_finds_the_pair_itself_and_neighbours_find_more(mug_features):
    points, normals = mug_features
    table = PairTable.build(points, normals)
    features = pair_features(points[[3, 10]], normals[[3, 10]], points[[50, 120]],
                             normals[[50, 120]])
    query, classes, first, second = table.lookup(features)
    assert np.all(classes == 0)
    for q, (i, j) in enumerate([(3, 50), (10, 120)]):
        assert np.any((query == q) & (first == i) & (second == j))
    assert len(table.lookup(features, neighbours=1)[0]) > len(query)


def test_nearest_bins_are_the_distance_neighbours_and_the_closer_angle_neighbours():
    step = np.radians(12.0)
    features = np.array([[0.34, 0.4 * step, 1.0, 2.9], [0.26, 2.6 * step, 3.1, 0.1]])
    bins = neighbour_bins(features, 0.1, step, neighbours=1)
    assert bins.shape == (2, 24, 4)
    own = quantise(features, 0.1, step)
    np.testing.assert_array_equal(bins[:, 0], own)
    np.testing.assert_array_equal(np.unique(bins[0, :, 0]), [2, 3, 4])  # the distance: both
    # An angle 0.4 steps lies above the centre of bin 0, so its neighbour is bin 1; one at
    # 2.6 steps below that of bin 3, so its neighbour is bin 2.
    np.testing.assert_array_equal(np.unique(bins[0, :, 1]), [0, 1])
    np.testing.assert_array_equal(np.unique(bins[1, :, 1]), [2, 3])
    assert np.all(np.abs(bins - own[:, None]) <= 1)
    assert len({tuple(b) for b in bins[0]}) == 24
    assert neighbour_bins(features, neighbours=2).shape == (2, 81, 4)


def test_nearest_bins_find_a_pair_whose_feature_crossed_a_bin_edge(mug_features):
    """Noise that moves an observed feature less than half a step, across the bin edge in
    every component: the own bin misses the true pair, the 24 nearest bins find it."""
    points, normals = mug_features
    table = PairTable.build(points, normals)
    steps = np.array([table.distance_step] + [table.angle_step] * 3)
    first, second = np.nonzero(~np.eye(len(points), dtype=bool))
    features = pair_features(points[first], normals[first], points[second], normals[second])
    scaled = features / steps
    offset = scaled - np.rint(scaled)
    # A usable pair whose feature lies off the middle of its bin in every component.
    pick = np.flatnonzero(np.all(np.abs(offset) > 0.15, axis=1)
                          & ~is_degenerate(points[first], normals[first], points[second],
                                           normals[second]))[0]
    i, j = first[pick], second[pick]
    # Just across the nearer edge: less than half a step away, in the next bin.
    edge = np.rint(scaled[pick]) + 0.5 * np.sign(offset[pick])
    noisy = ((edge + 0.02 * np.sign(offset[pick])) * steps)[None]
    assert np.all(np.abs(noisy[0] - features[pick]) < 0.5 * steps)
    assert np.all(quantise(noisy, table.distance_step, table.angle_step)
                  != quantise(features[pick], table.distance_step, table.angle_step))

    def found(neighbours):
        _, _, f, s = table.lookup(noisy, neighbours)
        return bool(np.any((f == i) & (s == j))), len(f)

    assert not found(0)[0]
    (near, n_near), (every, n_every) = found(1), found(2)
    assert near and every
    assert n_near < n_every


def test_lookup_of_an_unseen_feature_is_empty(mug_features):
    table = PairTable.build(*mug_features)
    query, _, first, second = table.lookup(np.array([[100.0, 1.0, 1.0, 1.0]]))
    assert len(query) == len(first) == len(second) == 0


def test_pair_table_cached_with_model(bundled):
    model = bundled["vase_1"]
    assert model.pair_table() is model.pair_table()
    coarse = model.pair_table(distance_step=0.2, angle_step_deg=20)
    assert len(np.unique(coarse.keys)) < len(np.unique(model.pair_table().keys))


def test_combined_table_finds_each_class_as_its_own_table(mug_features, rng):
    points, normals = mug_features
    other = points[::-1] * 0.9, normals[::-1]
    tables = [PairTable.build(points, normals), PairTable.build(*other)]
    combined = PairTable.combine(tables)
    assert len(combined) == sum(len(t) for t in tables)
    picks = rng.integers(0, 200, size=(30, 2))
    picks = picks[picks[:, 0] != picks[:, 1]]
    features = pair_features(points[picks[:, 0]], normals[picks[:, 0]], points[picks[:, 1]],
                             normals[picks[:, 1]])
    query, classes, first, second = combined.lookup(features, neighbours=1)
    for c, table in enumerate(tables):
        alone = table.lookup(features, neighbours=1)
        mine = classes == c
        np.testing.assert_array_equal(query[mine], alone[0])
        np.testing.assert_array_equal(first[mine], alone[2])
        np.testing.assert_array_equal(second[mine], alone[3])


def test_combining_tables_of_other_steps_is_an_error(mug_features):
    with pytest.raises(ValueError, match="different key steps"):
        PairTable.combine([PairTable.build(*mug_features),
                           PairTable.build(*mug_features, distance_step=0.2)])


def test_the_batched_inverse_transform_is_each_poses_own():
    """R_k^T (p - t_k) for k poses at once (one matrix product) equals the transform of
    each pose in turn, with and without translations, for tiny and huge coordinates."""
    rng = np.random.default_rng(3)
    for scale in (1e-6, 1.0, 1e6):
        poses = [random_pose(rng, scale) for _ in range(5)]
        rotations = np.array([r for r, _ in poses])
        translations = np.array([t for _, t in poses])
        points = rng.normal(scale=scale, size=(7, 3))
        batch = inverse_transform_points_batch(points, rotations, translations)
        turned = inverse_transform_points_batch(points, rotations)
        assert batch.shape == turned.shape == (5, 7, 3)
        for k, (rotation, translation) in enumerate(poses):
            np.testing.assert_allclose(batch[k], inverse_transform_points(
                points, rotation, translation), rtol=0, atol=1e-12 * scale)
            np.testing.assert_allclose(turned[k], points @ rotation, rtol=0,
                                       atol=1e-12 * scale)
