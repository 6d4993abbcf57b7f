import dataclasses
import types

import numpy as np
import pytest
from scipy.linalg import cho_solve
from scipy.spatial.distance import pdist

from tactile_viz.engine.shape.gpis import (
    ThinPlateKernel,
    WendlandKernel,
    _inverse_from_cholesky,
    _pair_terms,
    carved_prior,
    cut_free_space,
    fit_gpis,
    gradient_rows,
    indefinite_nugget,
    kernel_blocks,
    stable_cholesky,
    value_correction,
    value_rows,
)
from tactile_viz.engine.shape.gpis_prior import CUT_TIE, REFUTE_MOST, joined_cut, refuted_fit
from tactile_viz.engine.shape.level_set import box_closure, zero_level_surface
from tactile_viz.engine.shape.metrics import directed_hausdorff, surface_samples


def _kernel(x, y, radius):
    r = np.linalg.norm(x - y)
    return 2 * r**3 - 3 * radius * r**2 + radius**3


def _wendland(x, y, support):
    s = min(np.linalg.norm(x - y) / support, 1.0)
    return (1 - s) ** 4 * (4 * s + 1)


@pytest.fixture(scope="module")
def mug_data(bundled):
    """Contacts on mug_2 with true normals, and mug_1's SDF as the prior mean."""
    truth, prior_model = bundled["mug_2"], bundled["mug_1"]
    samples = surface_samples(truth, 60, seed=3)
    _, points, faces = truth.exact.query(samples)
    normals = truth.exact.surface_normal(points, faces)
    return points, normals, (lambda p: prior_model.sdf.evaluate(p)), prior_model


@pytest.mark.parametrize("kernel, function", [
    (ThinPlateKernel(9.0), lambda x, y: _kernel(x, y, 9.0)),
    (WendlandKernel(2.5), lambda x, y: _wendland(x, y, 2.5))])
def test_kernel_derivative_blocks_match_finite_differences(rng, kernel, function):
    x, y, h = rng.normal(size=(3, 3)), rng.normal(size=(4, 3)), 1e-5
    x[2] = y[3] + [3.0, 0, 0]  # beyond the Wendland support
    radius = kernel
    _kernel = lambda a, b, _: function(a, b)  # noqa: E731
    blocks = kernel_blocks(x, y, radius)
    for i in range(3):
        for j in range(4):
            for a in range(3):
                ea = np.eye(3)[a]
                d_dx = (_kernel(x[i] + h * ea, y[j], radius)
                        - _kernel(x[i] - h * ea, y[j], radius)) / (2 * h)
                d_dy = (_kernel(x[i], y[j] + h * ea, radius)
                        - _kernel(x[i], y[j] - h * ea, radius)) / (2 * h)
                assert blocks[4 * i + 1 + a, 4 * j] == pytest.approx(d_dx, rel=1e-6)
                assert blocks[4 * i, 4 * j + 1 + a] == pytest.approx(d_dy, rel=1e-6)
                for b in range(3):
                    eb, h = np.eye(3)[b], 1e-3  # second differences need a larger step
                    second = (_kernel(x[i] + h * ea, y[j] + h * eb, radius)
                              - _kernel(x[i] + h * ea, y[j] - h * eb, radius)
                              - _kernel(x[i] - h * ea, y[j] + h * eb, radius)
                              + _kernel(x[i] - h * ea, y[j] - h * eb, radius)) / (4 * h * h)
                    assert blocks[4 * i + 1 + a, 4 * j + 1 + b] == pytest.approx(
                        second, rel=1e-5, abs=1e-5)
                h = 1e-5
    np.testing.assert_allclose(value_rows(x, y, radius), blocks[::4])
    np.testing.assert_allclose(gradient_rows(x, y, radius)[:, 1], blocks[2::4])


def _numpy_blocks(x, y, kernel):
    """``kernel_blocks`` as numpy arrays (what the compiled loop replaced)."""
    diff, value, g, hessian = _pair_terms(x, y, kernel)
    blocks = np.empty(value.shape + (4, 4))
    blocks[..., 0, 0] = value
    blocks[..., 1:, 0] = g[..., None] * diff
    blocks[..., 0, 1:] = -(g[..., None] * diff)
    blocks[..., 1:, 1:] = hessian
    return blocks.transpose(0, 2, 1, 3).reshape(4 * len(x), 4 * len(y))


@pytest.mark.parametrize("kernel", [ThinPlateKernel(14.0), ThinPlateKernel(1e-3),
                                    WendlandKernel(2.5), WendlandKernel(1e4)])
def test_compiled_kernel_rows_are_numpys_to_the_bit(rng, kernel):
    # The compiled loops replace numpy's (p, q, 3, 3) temporaries; every trajectory stays
    # the same only if every entry is rounded as numpy rounds it.
    x, y = rng.normal(scale=3.0, size=(40, 3)), rng.normal(scale=3.0, size=(25, 3))
    x[3], y[7] = y[5], y[6]  # zero distances, across and within the sets
    assert np.array_equal(kernel_blocks(x, y, kernel), _numpy_blocks(x, y, kernel))
    assert np.array_equal(kernel_blocks(y, y, kernel), _numpy_blocks(y, y, kernel))
    assert np.array_equal(value_rows(x, y, kernel), _numpy_blocks(x, y, kernel)[::4])


@pytest.mark.parametrize("kernel", [12.0, WendlandKernel(3.0)])
def test_value_correction_matches_the_kernel_rows(rng, kernel):
    x, y = rng.uniform(-4, 4, size=(50, 3)), rng.uniform(-3, 3, size=(7, 3))
    weights = rng.normal(size=4 * len(y))
    x[0] = y[2]  # a query on a contact (r = 0)
    np.testing.assert_allclose(value_correction(x, y, weights, kernel),
                               value_rows(x, y, kernel) @ weights, rtol=1e-12, atol=1e-9)


def test_wendland_gram_with_gradients_is_positive_definite(bundled):
    model = bundled["office_chair"]
    points = surface_samples(model, 200, seed=1)
    for support in (0.5, 2.0, 8.0):
        gram = kernel_blocks(points, points, WendlandKernel(support))
        assert np.linalg.eigvalsh(gram).min() > -1e-9


def test_wendland_keeps_the_prior_beyond_its_support(mug_data):
    # The issue this kernel answers: with the thin-plate kernel a few contacts that
    # disagree with the prior move the field everywhere; with a compact kernel nothing
    # changes farther than the support from every contact.
    points, normals, prior, _ = mug_data
    few, few_normals = points[:5], normals[:5]
    query = np.random.default_rng(0).uniform(-4, 4, size=(3000, 3))
    far = np.min(np.linalg.norm(query[:, None] - few[None], axis=-1), axis=1) > 1.5
    local = fit_gpis(few, few_normals, prior, WendlandKernel(1.5))
    np.testing.assert_allclose(local.mean_value(query[far]), prior(query[far])[0], atol=1e-12)
    np.testing.assert_allclose(local.variance(query[far]), local.prior_variance)
    near_values, near_gradients = local.mean(few)
    assert np.abs(near_values).max() < 0.02
    assert np.abs(near_gradients - few_normals).max() < 0.05
    radius = 1.2 * np.ptp(np.vstack([few, query]), axis=0).max() * np.sqrt(3)
    whole = fit_gpis(few, few_normals, prior, radius)
    moved = np.abs(whole.mean_value(query[far]) - prior(query[far])[0])
    assert np.median(moved) > 0.05


def test_thin_plate_at_the_largest_distance_is_projected_and_fits(mug_data):
    points, normals, prior, _ = mug_data
    largest = pdist(points).max()
    gram = kernel_blocks(points, points, largest)
    assert np.linalg.eigvalsh(gram).min() < -1.0  # indefinite, as measured
    nugget = indefinite_nugget(gram)
    assert np.linalg.eigvalsh(gram + nugget * np.eye(len(gram))).min() > 0
    fit = fit_gpis(points, normals, prior, largest)
    values, gradients = fit.mean(points)
    variance = fit.variance(points + 0.3)
    # The nugget needed exceeds the gradients' own variance (6 R): the fit stays finite but
    # no longer honours the contacts, which is why the sessions' thin-plate R is measured
    # on the reconstruction box's diagonal (see SessionParams.gpis_radius_factor).
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(variance))
    assert np.all(np.isfinite(gradients)) and np.isfinite(fit.log_marginal_likelihood)


def test_a_noncontact_inside_the_prior_pushes_the_surface_away(mug_data):
    points, normals, prior, prior_model = mug_data
    candidates = np.random.default_rng(1).uniform(-3, 3, size=(2000, 3))
    inside = candidates[np.argmin(prior(candidates)[0])][None]  # the deepest point
    assert prior(inside)[0][0] < -0.2
    kernel = WendlandKernel(3.0)
    plain = fit_gpis(points[:10], normals[:10], prior, kernel)
    carved = fit_gpis(points[:10], normals[:10], prior, kernel, noncontacts=inside,
                      noncontact_value=0.1)
    assert plain.mean_value(inside)[0] < 0 < carved.mean_value(inside)[0]
    assert len(carved.points) == 11 and len(carved.kept) == 41
    # A non-contact the prior already puts outside adds nothing.
    outside = inside + [[20.0, 0, 0]]
    same = fit_gpis(points[:10], normals[:10], prior, kernel, noncontacts=outside)
    assert len(same.points) == 10


def test_carved_prior_cuts_balls_and_keeps_the_rest(mug_data):
    points, _, prior, _ = mug_data
    candidates = np.random.default_rng(2).uniform(-3, 3, size=(4000, 3))
    free = candidates[np.argsort(prior(candidates)[0])[:3]]  # deep inside the prior
    carved = carved_prior(prior, free, points, radius=0.6)
    values, gradients = carved(free)
    allowed = np.minimum(0.6, np.min(np.linalg.norm(free[:, None] - points[None], axis=-1), 1))
    np.testing.assert_allclose(values, allowed)
    # CSG: the cut reaches |m| beyond its ball into the prior's inside, no farther.
    reach = 0.6 + np.abs(prior(candidates)[0])
    far = np.min(np.linalg.norm(candidates[:, None] - free[None], axis=-1), axis=1) > reach
    np.testing.assert_array_equal(carved(candidates[far])[0], prior(candidates[far])[0])
    # Where the cut wins, the gradient is the cut's: finite differences agree.
    inside_cut = free + [[0.2, 0.1, -0.1]]
    step = 1e-6
    for axis in range(3):
        offset = np.zeros(3)
        offset[axis] = step
        numeric = (carved(inside_cut + offset)[0] - carved(inside_cut - offset)[0]) / (2 * step)
        np.testing.assert_allclose(carved(inside_cut)[1][:, axis], numeric, atol=1e-5)
    # No ball reaches past a contact (it stays on or inside the carved shape), and a zero
    # radius keeps the prior itself.
    assert np.all(carved(points)[0] <= np.maximum(prior(points)[0], 0) + 1e-12)
    assert carved_prior(prior, free, points, radius=0.0) is prior
    assert carved_prior(prior, np.zeros((0, 3)), points, radius=0.6) is prior


def test_touches_of_one_spot_take_one_gradient_from_the_carve():
    # Probes that missed beside a contact from two sides: the contact lies on the rim of
    # both balls, where a rounding error would pick either's gradient (or the prior's),
    # and two touches a micron apart would disagree by 90 degrees. Tied values give one
    # gradient: the prior's if it ties, else the tied balls' mean.
    def sphere(radius):
        def field(points):
            length = np.linalg.norm(points, axis=1)
            return length - radius, points / length[:, None]
        return field

    contacts = np.array([[1.0, 0.0, 0.0], [1.0, -1e-6, -1e-6]])
    free = np.array([[1.0, 0.3, 0.0], [1.0, 0.0, -0.5]])
    deep = carved_prior(sphere(1.1), free, contacts, radius=0.6)  # the prior 0.1 inside
    values, gradients = deep(contacts)
    np.testing.assert_allclose(values, 0.0, atol=1e-5)
    np.testing.assert_allclose(gradients, [[0.0, 0.5**0.5, -(0.5**0.5)]] * 2, atol=1e-4)
    on = carved_prior(sphere(1.0), free, contacts, radius=0.6)  # the prior through them
    np.testing.assert_allclose(on(contacts)[1], [[1.0, 0.0, 0.0]] * 2, atol=1e-5)
    # Off the ties the cut is the CSG difference, its gradient the winning ball's.
    inside = np.array([[1.0, 0.2, 0.0]])
    np.testing.assert_allclose(deep(inside)[0], 0.2, atol=1e-9)
    np.testing.assert_allclose(deep(inside)[1], [[0.0, 1.0, 0.0]], atol=1e-9)
    # The two touches lie well within the tie's tolerance (of the largest ball, 0.5).
    assert np.linalg.norm(contacts[1] - contacts[0]) < CUT_TIE * 0.5 / 100


def test_carving_corrects_a_refuted_part_and_keeps_the_prior_elsewhere(mug_data):
    # A wrong prior (mug_1) meets contacts on the truth (mug_2); probes through the prior's
    # part that the truth lacks remove it from the posterior's inside, while the prior's
    # inside away from any probe or contact is kept.
    points, normals, prior, _ = mug_data
    candidates = np.random.default_rng(4).uniform(-3, 3, size=(6000, 3))
    distance_to_contacts = np.min(np.linalg.norm(candidates[:, None] - points[None], axis=-1), 1)
    refuted = candidates[(prior(candidates)[0] < -0.1) & (distance_to_contacts > 1.0)][:20]
    kernel = WendlandKernel(2.0)
    carved = fit_gpis(points, normals, carved_prior(prior, refuted, points, 0.6), kernel)
    plain = fit_gpis(points, normals, prior, kernel)
    assert np.all(carved.mean_value(refuted) > 0)
    assert np.mean(plain.mean_value(refuted) < 0) > 0.5
    inside = prior(candidates)[0] < -0.1
    untouched = candidates[inside & (np.min(np.linalg.norm(
        candidates[:, None] - refuted[None], axis=-1), 1) > 0.6 - prior(candidates)[0])]
    assert len(untouched) > 100
    kept = np.mean((carved.mean_value(untouched) < 0) == (plain.mean_value(untouched) < 0))
    assert kept > 0.95


def test_the_estimate_is_cut_where_probes_found_nothing(mug_data):
    # The posterior's own inside far from every contact (where a thin-plate correction can
    # put a phantom part) is removed where a probe passed; at the contacts and away from
    # the balls the mean, and everywhere the variance, are the fit's.
    points, normals, prior, _ = mug_data
    plain = fit_gpis(points, normals, prior, ThinPlateKernel(12.0))
    candidates = np.random.default_rng(5).uniform(-3, 3, size=(6000, 3))
    distance_to_contacts = np.min(np.linalg.norm(candidates[:, None] - points[None], axis=-1), 1)
    far_inside = (plain.mean_value(candidates) < -0.05) & (distance_to_contacts > 1.0)
    refuted = candidates[far_inside][:20]
    assert len(refuted) == 20
    cut = cut_free_space(plain, refuted, points, 0.6)
    np.testing.assert_allclose(cut.mean_value(refuted), 0.6)
    np.testing.assert_array_equal(cut.mean_value(points), plain.mean_value(points))
    np.testing.assert_array_equal(cut.variance(candidates[:50]), plain.variance(candidates[:50]))
    reach = 0.6 + np.abs(plain.mean_value(candidates))
    far = np.min(np.linalg.norm(candidates[:, None] - refuted[None], axis=-1), axis=1) > reach
    np.testing.assert_array_equal(cut.mean(candidates[far])[0], plain.mean(candidates[far])[0])
    np.testing.assert_allclose(cut.mean(refuted)[0], cut.mean_value(refuted))
    assert cut_free_space(plain, refuted, points, 0.0).cut is None
    # Within keep_within of a contact the fit's mean stands.
    near = refuted[distance_to_contacts[far_inside][:20] < 1.3]
    kept = cut_free_space(plain, refuted, points, 0.6, keep_within=1.3)
    assert len(near)
    np.testing.assert_array_equal(kept.mean_value(near), plain.mean_value(near))


def test_a_second_cut_joins_the_first(mug_data):
    # Two sets of balls cut one after the other: the mean is the largest of the fit's and
    # both cuts', and its gradient is that of whichever is largest there.
    points, normals, prior, _ = mug_data
    plain = fit_gpis(points, normals, prior, ThinPlateKernel(12.0))
    candidates = np.random.default_rng(7).uniform(-3, 3, size=(6000, 3))
    distance = np.min(np.linalg.norm(candidates[:, None] - points[None], axis=-1), 1)
    refuted = candidates[(plain.mean_value(candidates) < -0.05) & (distance > 1.0)][:20]
    first = cut_free_space(plain, refuted[:10], points, 0.6)
    second = cut_free_space(plain, refuted[10:], points, 0.6)
    both = dataclasses.replace(plain, cut=joined_cut(first.cut, second.cut))
    np.testing.assert_allclose(both.mean_value(refuted), 0.6)
    np.testing.assert_array_equal(both.mean_value(candidates), np.maximum(
        first.mean_value(candidates), second.mean_value(candidates)))
    values, gradients = both.mean(candidates)
    np.testing.assert_array_equal(values, both.mean_value(candidates))
    # Where the second's balls win by more than a tie (CUT_TIE of the radius).
    theirs = second.mean_value(candidates) > first.mean_value(candidates) + 2 * CUT_TIE * 0.6
    assert theirs.sum() > 100
    np.testing.assert_allclose(gradients[theirs], second.mean(candidates[theirs])[1])
    assert joined_cut(None, first.cut) is first.cut and joined_cut(first.cut, None) is first.cut
    assert joined_cut(None, None) is None


def test_a_miss_refutes_the_fit_only_away_from_the_contacts(mug_data):
    # Free points the fit puts inside observe f = value and push its surface out, round by
    # round; those within keep_within of a contact (a probe beside a thin part) never do.
    points, normals, prior, _ = mug_data
    kernel = ThinPlateKernel(12.0)
    plain = fit_gpis(points, normals, prior, kernel)
    candidates = np.random.default_rng(6).uniform(-3, 3, size=(6000, 3))
    distance = np.min(np.linalg.norm(candidates[:, None] - points[None], axis=-1), 1)
    inside = plain.mean_value(candidates) < -0.05
    far = candidates[inside & (distance > 1.0)][:15]
    near = candidates[inside & (distance < 0.5)][:15]
    assert len(far) == 15 and len(near) == 15
    given = []

    def refit(refuting):
        given.append(refuting)
        return fit_gpis(points, normals, prior, kernel, scale=plain.scale, newton=False,
                        refuting=refuting)

    fit = refuted_fit(plain, np.vstack([far, near]), 0.1, 3, refit, points, keep_within=0.75)
    assert given and all(np.min(np.linalg.norm(g[:, None] - points[None], axis=-1), 1).min() > 0.75
                         for g in given)
    assert np.mean(fit.mean_value(far) > 0) > np.mean(plain.mean_value(far) > 0)
    assert refuted_fit(plain, near, 0.1, 3, refit, points, keep_within=0.75) is plain
    assert refuted_fit(plain, np.zeros((0, 3)), 0.1, 3, refit) is plain


def test_each_refuting_round_adds_the_deepest_few(rng):
    # A fit that puts every free point inside, deeper the farther from the origin.
    class Inside:
        def mean_value(self, points):
            return -np.linalg.norm(points, axis=1)

    free = rng.normal(size=(3 * REFUTE_MOST, 3))
    given = []
    refuted_fit(Inside(), free, 0.1, 2, lambda refuting: given.append(refuting) or Inside())
    assert [len(g) for g in given] == [REFUTE_MOST, 2 * REFUTE_MOST]
    depth = np.linalg.norm(free, axis=1)
    assert np.linalg.norm(given[0], axis=1).min() >= np.sort(depth)[-REFUTE_MOST]


def test_inverse_from_cholesky_matches_a_solve(rng):
    points = rng.normal(size=(6, 3))
    gram = kernel_blocks(points, points, 10.0) + 1e-4 * np.eye(24)
    factor, _ = stable_cholesky(gram)
    inverse = _inverse_from_cholesky(factor)
    np.testing.assert_allclose(inverse, cho_solve((factor, True), np.eye(24)), rtol=1e-8,
                               atol=1e-12)
    np.testing.assert_array_equal(inverse, inverse.T)  # exactly symmetric


def test_kernel_at_zero_distance_is_finite():
    point = np.zeros((1, 3))
    block = kernel_blocks(point, point, 5.0)
    assert np.all(np.isfinite(block))
    np.testing.assert_allclose(block[1:, 1:], 6 * 5.0 * np.eye(3))


def test_posterior_interpolates_contacts(mug_data):
    points, normals, prior, _ = mug_data
    fit = fit_gpis(points, normals, prior, 15.0)
    values, gradients = fit.mean(points)
    assert np.abs(values).max() < 0.02
    assert np.abs(gradients - normals).max() < 0.05
    assert fit.variance(points).max() < 1e-3


def test_variance_grows_away_from_contacts(mug_data):
    points, normals, prior, _ = mug_data
    fit = fit_gpis(points, normals, prior, 15.0)
    near = fit.variance(points + 0.05)
    far = fit.variance(points + 1.5)
    assert np.all(far > near)


def test_posterior_equals_prior_where_data_do_not_disagree(mug_data):
    _, _, prior, prior_model = mug_data
    query = np.random.default_rng(0).uniform(-3, 3, size=(200, 3))
    empty = fit_gpis(np.zeros((0, 3)), np.zeros((0, 3)), prior, 15.0)
    np.testing.assert_allclose(empty.mean_value(query), prior(query)[0])
    np.testing.assert_allclose(empty.variance(query), 15.0**3)
    assert empty.prior_variance == pytest.approx(15.0**3)
    # Contacts on the prior's own surface with its own normals change nothing.
    points, _ = prior_model.features
    _, gradients = prior(points[:40])
    fit = fit_gpis(points[:40], gradients, prior, 15.0)
    np.testing.assert_allclose(fit.mean_value(query), prior(query)[0], atol=0.05)


def test_gram_is_positive_definite_with_duplicates(bundled):
    model = bundled["office_chair"]
    points = surface_samples(model, 360, seed=1)
    points = np.vstack([points, points[:20], points[20:40] + 1e-7])  # 400 with duplicates
    _, closest, faces = model.exact.query(points)
    normals = model.exact.surface_normal(closest, faces)
    radius = 1.2 * np.ptp(closest, axis=0).max() * np.sqrt(3)
    gram = kernel_blocks(closest, closest, radius) + 1e-4 * np.eye(4 * len(closest))
    assert np.linalg.eigvalsh(gram).min() > 0
    fit = fit_gpis(closest, normals, lambda p: model.sdf.evaluate(p), radius)
    assert np.all(np.isfinite(fit.alpha))


def test_newton_step_never_lowers_marginal_likelihood(mug_data):
    points, normals, prior, _ = mug_data
    for scale in [1e-6, 1e-3, 1.0, 1e3]:
        before = fit_gpis(points, normals, prior, 15.0, scale=scale, newton=False)
        after = fit_gpis(points, normals, prior, 15.0, scale=scale)
        assert after.log_marginal_likelihood >= before.log_marginal_likelihood - 1e-9


@pytest.mark.parametrize("scale", [1e-8, 1e8])
def test_extreme_scales_give_no_nan(mug_data, scale):
    points, normals, prior, _ = mug_data
    fit = fit_gpis(points, normals, prior, 15.0, scale=scale)
    query = points + 0.3
    values, gradients = fit.mean(query)
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(gradients))
    assert np.all(np.isfinite(fit.variance(query)))


def test_zero_level_surface_is_near_the_data(mug_data):
    points, normals, prior, prior_model = mug_data
    fit = fit_gpis(points, normals, prior, 15.0)
    bounds = prior_model.mesh.bounds + [[-0.6] * 3, [0.6] * 3]
    vertices, faces = zero_level_surface(fit, bounds, resolution=32)
    assert len(faces) > 100
    spacing = np.ptp(bounds, axis=0).max() / 32
    # Vertices are linear interpolants along grid edges: off the zero set by a fraction of
    # a voxel where the mean curves.
    error = np.abs(fit.mean_value(vertices))
    assert np.percentile(error, 99) < spacing / 2 and error.max() < spacing


def test_banded_surface_matches_the_full_grid(mug_data):
    points, normals, prior, _ = mug_data
    fit = fit_gpis(points[:20], normals[:20], prior, WendlandKernel(2.0))
    bounds = (np.full(3, -3.6), np.full(3, 3.6))
    full_vertices, _ = zero_level_surface(fit, bounds, 31, band=False)  # 32 nodes: odd grid
    band_vertices, band_faces = zero_level_surface(fit, bounds, 31, band=True)
    assert len(band_faces) > 100
    spacing = 7.2 / 31
    assert directed_hausdorff(band_vertices, full_vertices) < 0.05 * spacing
    assert directed_hausdorff(full_vertices, band_vertices) < 0.05 * spacing


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("spacing", [None, 0.07])
def test_box_closure_marks_the_surface_the_box_cuts_off(scale, spacing):
    """A ball cut by its box at z = 0.3: the vertices that close it there are marked, the
    ball's own are not, at any scale and on a kept lattice too."""
    fit = types.SimpleNamespace(mean_value=lambda x: np.linalg.norm(x, axis=1) - scale)
    bounds = (np.full(3, -1.2 * scale), np.array([1.2, 1.2, 0.3]) * scale)
    spacing = None if spacing is None else spacing * scale
    vertices, _ = zero_level_surface(fit, bounds, 24, spacing=spacing)
    closure = box_closure(vertices, bounds, 24, spacing)
    cell = 2.4 * scale / 24 if spacing is None else spacing
    assert closure.any() and not closure.all()
    assert np.all(vertices[closure, 2] > 0.3 * scale)  # past the box's top node
    off_ball = np.abs(np.linalg.norm(vertices[~closure], axis=1) - scale)
    assert off_ball.max() < cell / 2  # the others are the ball's
    whole = (np.full(3, -1.2 * scale), np.full(3, 1.2 * scale))
    inside = zero_level_surface(fit, whole, 24, spacing=spacing)[0]
    assert not box_closure(inside, whole, 24, spacing).any()


def test_fits_of_the_same_observations_share_their_factor_by_content(mug_data, bundled):
    """Two prior means, one set of observations: the second fit takes the first's
    Cholesky factor from ``factors`` and is the uncached fit to the bit; another scale,
    kernel or point set is factored afresh, and the cache keeps ``FACTORS_KEPT``."""
    from tactile_viz.engine.shape.gpis import FACTORS_KEPT

    points, normals, prior, _ = mug_data
    other = lambda p: bundled["mug_2"].sdf.evaluate(p)  # noqa: E731
    kernel = WendlandKernel(3.0)
    factors = {}
    first = fit_gpis(points, normals, prior, kernel, newton=False, factors=factors)
    second = fit_gpis(points, normals, other, kernel, newton=False, factors=factors)
    alone = fit_gpis(points, normals, other, kernel, newton=False)
    assert second.factor is first.factor and len(factors) == 1
    np.testing.assert_array_equal(second.alpha, alone.alpha)
    assert second.log_marginal_likelihood == alone.log_marginal_likelihood
    for changed in (dict(scale=2.0), dict(kernel=WendlandKernel(4.0)),
                    dict(points=points[1:], normals=normals[1:])):
        options = {"points": points, "normals": normals, "kernel": kernel, **changed}
        fit = fit_gpis(options.pop("points"), options.pop("normals"), other,
                       options.pop("kernel"), newton=False, factors=factors, **options)
        assert fit.factor is not first.factor
        assert len(factors) <= FACTORS_KEPT
    untouched = {}
    newton = fit_gpis(points, normals, prior, kernel, newton=True, factors=untouched)
    assert newton.log_marginal_likelihood >= first.log_marginal_likelihood
    assert untouched == {}  # a Newton step's scale moves: its factors are not kept
