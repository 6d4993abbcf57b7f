"""A hypothesis's residuals weighed by place: calibrated for noise, powerful for a
look-alike's shared misfit, and the decision's ``group_p``."""

import numpy as np
import pytest
import trimesh
from scipy.special import chdtrc

from tactile_viz.engine import ObjectModel, PriorLibrary
from tactile_viz.engine.belief.decision import decide
from tactile_viz.engine.belief.grouped import GROUP_SIZE, contact_groups, grouped_p
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.params import PAPER_SIZE, FilterParams, scaled_lengths


def _sphere(count, seed):
    """``count`` points on a unit sphere and their normals."""
    normals = np.random.default_rng(seed).normal(size=(count, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals.copy(), normals


def test_groups_are_places_and_split_a_thin_walls_faces():
    """About ``n / GROUP_SIZE`` groups; two faces of a wall 0.02 thick, touched at the same
    places, never share a group (their residuals a misfit pushes opposite ways)."""
    rng = np.random.default_rng(0)
    outer = np.c_[rng.uniform(-1, 1, (100, 2)), np.full(100, 0.01)]
    inner = outer - [0.0, 0.0, 0.02]
    points = np.vstack([outer, inner])
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (100, 1)), np.tile([0.0, 0.0, -1.0], (100, 1))])
    groups = contact_groups(points, normals, weight=1.0)
    assert groups.shape == (200,) and groups.max() + 1 == 200 // GROUP_SIZE
    assert not set(groups[:100]) & set(groups[100:])
    assert contact_groups(np.zeros((0, 3)), np.zeros((0, 3)), 1.0).shape == (0,)
    assert np.array_equal(contact_groups(points[:3], normals[:3], 1.0), [0, 0, 0])


def test_a_right_hypothesiss_noise_leaves_uniform_p_values():
    """Gaussian residuals of the stated noise: about 5% of p-values under 0.05, none under
    1e-4 in 400 draws, however the contacts lie; a share ``b`` granted to every group."""
    points, normals = _sphere(200, 1)
    groups = contact_groups(points, normals, 1.0)
    rng = np.random.default_rng(2)
    p = np.array([grouped_p(rng.normal(0.0, 0.3, 200), groups, 0.09) for _ in range(400)])
    assert 0.02 <= np.mean(p < 0.05) <= 0.09 and p.min() > 1e-4
    shared = rng.normal(0.0, 0.1, groups.max() + 1)[groups]  # a reconstruction's own error
    p = np.array([grouped_p(rng.normal(0.0, 0.3, 200) + shared, groups, 0.09, 0.01)
                  for _ in range(100)])
    assert p.min() > 1e-4


def test_a_misfit_shared_by_place_stands_out_long_before_the_sum_of_squares():
    """A misfit of half the noise, shared by the contacts of each place (half the
    places pushed out, half in): the chi-squared test of all the squares barely sees it,
    the group means do."""
    points, normals = _sphere(200, 3)
    groups = contact_groups(points, normals, 1.0)
    rng = np.random.default_rng(4)
    shape = np.where(groups % 2 == 0, 1.0, -1.0) * 0.15  # the noise is 0.3
    residuals = rng.normal(0.0, 0.3, 200) + shape
    everywhere = float(chdtrc(200 - 6, np.sum(residuals**2) / 0.09))
    by_place = grouped_p(residuals, groups, 0.09)
    assert by_place < 1e-6 and everywhere > 1e3 * by_place


def test_the_extremes_and_an_outlier():
    """Few or non-finite residuals are untested (1); with no noise granted a mean off zero
    is a misfit (0), zeros are not; the farthest ``trim`` leave the test."""
    groups = np.zeros(5, np.int64)
    assert grouped_p(np.ones(5), groups, 1.0) == 1.0
    groups = np.arange(40) // 10
    assert grouped_p(np.r_[np.nan, np.zeros(39)], groups, 1.0) == 1.0
    assert grouped_p(np.full(40, 1e-9), groups, 0.0) == 0.0
    assert grouped_p(np.zeros(40), groups, 0.0) == 1.0
    tiny = grouped_p(np.full(40, 1e-9), groups, 1e-300)
    assert 0.0 <= tiny <= 1.0
    residuals = np.random.default_rng(5).normal(0.0, 0.1, 40)
    residuals[0] = 50.0  # one contact far off (a slip)
    assert grouped_p(residuals, groups, 0.01) < 1e-6
    assert grouped_p(residuals, groups, 0.01, trim=0.05) > 1e-4


@pytest.fixture(scope="module")
def cylinders(tmp_path_factory):
    """A cylinder of radius 1.5 and height 6 and its copy 4% larger."""
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    small = trimesh.creation.cylinder(radius=1.5, height=6, sections=64)
    large = small.copy()
    large.apply_scale(1.04)
    return [ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
            for m, name in ((small, "cylinder"), (large, "large"))]


def _decided(library, truth, noise, count=150, seed=0):
    points, faces = trimesh.sample.sample_surface_even(truth.mesh, count, seed=seed)
    points = points + np.random.default_rng(seed).normal(0.0, noise, points.shape)
    params = scaled_lengths(FilterParams(), library.reference_size / PAPER_SIZE)
    pf = ParticleFilter(library, params, rng=seed)
    for point, normal in zip(points, truth.mesh.face_normals[faces]):
        state = pf.update(Contact(point, normal))
    return decide(pf, state, 0.99, floor=noise, same_mode=0.1, localisation=0.01)


def test_a_copy_four_percent_larger_misfits_by_place_and_the_object_does_not(cylinders):
    """The cylinder touched with noise of 0.06 (1% of its size) against a library of its
    copy 4% larger (0.06 off on the side): the place test rejects the copy; the cylinder
    against itself passes it. Without ``localisation`` nothing is tested by place."""
    small, large = cylinders
    copy = _decided(PriorLibrary([large]), small, 0.06)
    assert copy.group_p < 1e-6
    right = _decided(PriorLibrary([small]), small, 0.06)
    assert right.group_p > 1e-4
    params = scaled_lengths(FilterParams(), small.size_unit * 6 / PAPER_SIZE)
    pf = ParticleFilter(PriorLibrary([large]), params, rng=0)
    for contact in [Contact(p, n) for p, n in zip(small.mesh.vertices[:20],
                                                   small.mesh.vertex_normals[:20])]:
        state = pf.update(contact)
    assert decide(pf, state, 0.99, floor=0.06).group_p == 1.0


def test_a_held_decision_is_tested_by_place_too(cylinders):
    """The decided cylinder refitted at a later touch reports the test by place when asked
    (the right shape passes it) and 1 when not."""
    from tactile_viz.engine.belief.held import held_decision

    small, _ = cylinders
    library = PriorLibrary([small])
    points, faces = trimesh.sample.sample_surface_even(small.mesh, 120, seed=3)
    points = points + np.random.default_rng(3).normal(0.0, 0.06, points.shape)
    params = scaled_lengths(FilterParams(), library.reference_size / PAPER_SIZE)
    pf = ParticleFilter(library, params, rng=3)
    for point, normal in zip(points, small.mesh.face_normals[faces]):
        state = pf.update(Contact(point, normal))
    decision = decide(pf, state, 0.99, floor=0.06, same_mode=0.1, localisation=0.01)
    assert decision.decided
    lead = decision.hypotheses[0]
    held = held_decision(pf, state, lead, 0.99, floor=0.06, localisation=0.01)
    assert held is not None and 1e-4 < held.group_p <= 1.0
    assert held_decision(pf, state, lead, 0.99, floor=0.06).group_p == 1.0
