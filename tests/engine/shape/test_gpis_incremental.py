"""The incremental GPIS fit: block-extended factors equal full ones, the fall back when the
Schur complement is not positive definite, the lazy scale refit, the sessions' paths."""

import pickle

import numpy as np
import pytest
from scipy.linalg import LinAlgError, cholesky

from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.session import Session, estimate, make_truth, session_preset
from tactile_viz.engine.shape.gpis import (
    ThinPlateKernel,
    WendlandKernel,
    carved_prior,
    fit_gpis,
    kernel_blocks,
    value_correction,
)
from tactile_viz.engine.shape.gpis_incremental import (
    cached_factor,
    corrections,
    extend_cholesky,
    fit_gpis_incremental,
    inverse_row_norms,
    scale_score,
)
from tactile_viz.engine.shape.gpis_prior import edge_tilt
from tactile_viz.engine.shape.gpis_variance import lattice_low, lattice_variance
from tactile_viz.engine.shape.level_set import zero_level_surface
from tactile_viz.engine.shape.metrics import surface_samples


@pytest.fixture(scope="module")
def mug(bundled):
    """Contacts on mug_2 with true normals, mug_1's SDF as the prior mean."""
    truth, prior_model = bundled["mug_2"], bundled["mug_1"]
    _, points, faces = truth.exact.query(surface_samples(truth, 80, seed=5))
    return points, truth.exact.surface_normal(points, faces), prior_model.sdf.evaluate


def _random_points(rng, count):
    points = rng.uniform(-3, 3, size=(count, 3))
    points[5] = points[2]                  # a duplicate
    points[7] = points[3] + 1e-7           # a near duplicate
    return points


@pytest.mark.parametrize("kernel", [ThinPlateKernel(14.0), WendlandKernel(3.0)])
@pytest.mark.parametrize("head", [1, 4, 9])
def test_block_update_equals_full_factor(rng, kernel, head):
    points = _random_points(rng, 12)
    gram = 0.3 * kernel_blocks(points, points, kernel) + 1e-3 * np.eye(48)
    full = cholesky(gram, lower=True)
    start = 4 * head
    extended = extend_cholesky(cholesky(gram[:start, :start], lower=True),
                               gram[:start, start:], gram[start:, start:])
    np.testing.assert_allclose(extended, full, rtol=1e-9, atol=1e-9 * np.abs(full).max())
    inverse = np.linalg.inv(full)
    np.testing.assert_allclose(inverse_row_norms(full, start), np.sum(inverse[start:] ** 2, 1),
                               rtol=1e-6)


def test_cache_extended_contact_by_contact_equals_the_full_factor(rng):
    points, kernel = _random_points(rng, 10), ThinPlateKernel(14.0)
    cache = None
    for count in range(1, 11):
        kept = np.arange(4 * count)
        cache = cached_factor(cache, points[:count], kept, kernel, 0.5, 1e-3)
    gram = kernel_blocks(points, points, kernel)
    np.testing.assert_allclose(cache.gram0, gram, rtol=1e-12, atol=1e-9)
    full = cholesky(0.5 * gram + 1e-3 * np.eye(40), lower=True)
    np.testing.assert_allclose(cache.factor, full, rtol=1e-8, atol=1e-8 * np.abs(full).max())
    # A prefix (a rolled-back step) and a changed scale reuse or refactor correctly.
    shorter = cached_factor(cache, points[:6], np.arange(24), kernel, 0.5, 1e-3)
    np.testing.assert_allclose(shorter.factor, cache.factor[:24, :24])
    rescaled = cached_factor(cache, points, np.arange(40), kernel, 2.0, 1e-3)
    np.testing.assert_allclose(rescaled.factor @ rescaled.factor.T,
                               2.0 * gram + 1e-3 * np.eye(40), atol=1e-8 * np.abs(gram).max())


def test_a_cache_with_its_own_gradient_noise_equals_the_full_factor(rng):
    points, kernel = _random_points(rng, 8), ThinPlateKernel(14.0)
    cache = None
    for count in range(1, 9):
        cache = cached_factor(cache, points[:count], np.arange(4 * count), kernel, 0.5,
                              (1e-3, 2e-2))
    noise = np.tile([1e-3, 2e-2, 2e-2, 2e-2], 8)
    gram = kernel_blocks(points, points, kernel)
    np.testing.assert_allclose(cache.factor @ cache.factor.T,
                               0.5 * gram + np.diag(noise + cache.jitter),
                               atol=1e-8 * np.abs(gram).max())


def test_an_incremental_fit_with_gradient_noise_equals_the_full_fit(mug):
    points, normals, prior = mug
    noisy = points + np.random.default_rng(3).normal(0, 0.05, points.shape)
    kernel, cache, scale = ThinPlateKernel(12.0), None, 1.0
    for count in (2, 10, 30):
        options = {"noise_variance": 2.5e-3, "gradient_noise_variance": 1e-2}
        fit, cache, _ = fit_gpis_incremental(noisy[:count], normals[:count], prior, kernel,
                                             cache, scale, refit=True, **options)
        full = fit_gpis(noisy[:count], normals[:count], prior, kernel, scale=scale, **options)
        assert fit.scale == pytest.approx(full.scale, rel=1e-9)
        query = points[:count] + 0.2
        np.testing.assert_allclose(fit.mean_value(query), full.mean_value(query), atol=1e-8)
        np.testing.assert_allclose(fit.variance(query), full.variance(query), atol=1e-8)
        scale = fit.scale


@pytest.mark.parametrize("gradient_noise", [1e-4, 1e-2])
def test_the_scale_score_is_near_the_likelihoods_gradient_with_gradient_noise(
        mug, gradient_noise):
    points, normals, prior = mug
    noisy = points + np.random.default_rng(4).normal(0, 0.05, points.shape)
    for scale in (0.3, 3.0):
        fit, cache, _ = fit_gpis_incremental(noisy, normals, prior, ThinPlateKernel(12.0),
                                             None, scale, refit=False, noise_variance=2.5e-3,
                                             gradient_noise_variance=gradient_noise)
        alpha = fit.alpha[fit.kept]
        residual = cache.factor @ (cache.factor.T @ alpha)
        noise = fit.noise + cache.jitter
        inverse = np.linalg.inv(cache.factor @ cache.factor.T)
        exact = (0.5 * (residual @ alpha - alpha @ (noise * alpha))
                 - 0.5 * (len(alpha) - np.diag(inverse) @ noise)) / np.sqrt(0.5 * len(alpha))
        assert scale_score(cache, residual, alpha) == pytest.approx(exact, rel=0.05, abs=0.3)


def test_a_schur_complement_that_is_not_positive_definite_refactors_in_full(rng):
    with pytest.raises(LinAlgError):
        extend_cholesky(np.eye(2), np.eye(2), 0.5 * np.eye(2))
    # Thin-plate R far below the distances: the near cluster's Gram matrix is positive
    # definite, the whole one is not, so the block update fails.
    near = rng.uniform(-0.2, 0.2, size=(3, 3))
    points, kernel = np.vstack([near, rng.uniform(-8, 8, size=(6, 3))]), ThinPlateKernel(1.0)
    cache = cached_factor(None, near, np.arange(12), kernel, 1.0, 1e-4)
    assert cache.nugget == 0
    grown = cached_factor(cache, points, np.arange(36), kernel, 1.0, 1e-4)
    assert grown.nugget > 0
    gram = kernel_blocks(points, points, kernel) + grown.nugget * np.eye(36)
    np.testing.assert_allclose(grown.gram0, gram)
    np.testing.assert_allclose(grown.factor @ grown.factor.T,
                               gram + (1e-4 + grown.jitter) * np.eye(36),
                               atol=1e-9 * np.abs(gram).max())


def test_incremental_fit_equals_the_full_fit_when_refitting_every_step(mug):
    points, normals, prior = mug
    kernel, cache, scale = ThinPlateKernel(12.0), None, 1.0
    for count in (1, 2, 10, 30):
        fit, cache, refitted = fit_gpis_incremental(points[:count], normals[:count], prior,
                                                    kernel, cache, scale, refit=True)
        full = fit_gpis(points[:count], normals[:count], prior, kernel, scale=scale)
        assert refitted and fit.scale == pytest.approx(full.scale, rel=1e-9)
        query = points[:count] + 0.2
        np.testing.assert_allclose(fit.mean_value(query), full.mean_value(query), atol=1e-8)
        np.testing.assert_allclose(fit.variance(query), full.variance(query), atol=1e-8)
        scale = fit.scale


def test_lazy_refit_gives_a_mean_near_the_exact_fit(mug):
    points, normals, prior = mug
    kernel, cache, lazy, exact = ThinPlateKernel(12.0), None, 1.0, 1.0
    refits = 0
    for count in range(1, 81):
        fit, cache, refitted = fit_gpis_incremental(points[:count], normals[:count], prior,
                                                    kernel, cache, lazy,
                                                    refit=count % 10 == 0, refit_score=3.0)
        full = fit_gpis(points[:count], normals[:count], prior, kernel, scale=exact)
        lazy, exact, refits = fit.scale, full.scale, refits + refitted
    assert refits < 40  # lazier than every step
    assert lazy == pytest.approx(exact, rel=0.1)
    query = np.vstack([points + 0.2, points - 0.3])
    np.testing.assert_allclose(fit.mean_value(query), full.mean_value(query), atol=1e-3)
    residual = fit.alpha[fit.kept]  # any vector: the score is finite
    assert np.isfinite(scale_score(cache, residual, residual))


@pytest.mark.parametrize("kernel", [ThinPlateKernel(9.0), WendlandKernel(2.0)])
def test_compiled_correction_matches_numpy(rng, kernel):
    x, y = rng.uniform(-4, 4, size=(60, 3)), rng.uniform(-3, 3, size=(9, 3))
    x[0] = y[1]
    weights = rng.normal(size=36)
    np.testing.assert_allclose(corrections(x, y, weights, kernel),
                               value_correction(x, y, weights, kernel), atol=1e-9)


def _novel_session(bundled, preset):
    library = PriorLibrary(bundled[name] for name in ("mug_1", "bottle_1", "vase_1"))
    return Session.simulated(make_truth(bundled["mug_2"], rng=1), library, "gpis-dhd",
                   params=session_preset(preset), seed=1)


def test_paper_preset_refits_in_full_every_step(bundled, monkeypatch):
    params = session_preset("paper")
    assert not params.gpis_incremental and params.gpis_refit_every == 1
    assert params.gpis_box_tolerance == 0
    calls = []
    monkeypatch.setattr(estimate, "fit_gpis_incremental", None)  # must not be called
    monkeypatch.setattr(estimate, "fit_gpis",
                        lambda *args, **kwargs: calls.append(kwargs) or fit_gpis(*args, **kwargs))
    session = _novel_session(bundled, "paper")
    session.run(max_steps=12)
    novel = [s for s in session.snapshots if s.gpis_faces is not None]
    assert novel and len(calls) == len(novel)
    assert all(call["newton"] for call in calls)


def test_a_noisy_sensors_normal_noise_goes_to_the_gradient_rows(bundled, monkeypatch):
    calls = []
    monkeypatch.setattr(estimate, "fit_gpis",
                        lambda *args, **kwargs: calls.append(kwargs) or fit_gpis(*args, **kwargs))
    library = PriorLibrary(bundled[name] for name in ("mug_1", "bottle_1", "vase_1"))
    session = Session.simulated(make_truth(bundled["mug_2"], rng=1), library, "gpis-dhd",
                                params=session_preset("recommended"), seed=1,
                                sensor_noise=(0.05, 3.0))
    session.run(max_steps=12)
    assert calls
    for call in calls:
        # Both carry the GPIS's own noise; the sensor's adds a length to the values and a
        # tilt (radians, half its square along each tangent direction) to the gradients:
        # its normal noise and the edge tilt of its position noise (objects of size 6).
        tilt = np.hypot(np.radians(3.0), edge_tilt(0.05, 6.0))
        assert (call["gradient_noise_variance"] - call["noise_variance"]
                == pytest.approx(tilt**2 / 2 - 0.05**2, rel=1e-9))


def test_a_full_fit_takes_the_scales_newton_step_as_the_data_grow(bundled, monkeypatch):
    params = session_preset("recommended")
    assert not params.gpis_incremental and params.gpis_refit_every > 1
    calls = []
    monkeypatch.setattr(estimate, "fit_gpis", lambda *args, **kwargs: (
        kwargs.get("refuting") is None and calls.append((len(args[0]), kwargs["newton"]))
    ) or fit_gpis(*args, **kwargs))
    session = _novel_session(bundled, "recommended")
    session.run(max_steps=45)
    # One fit a novel step (a stopping session's final candidates follow, without it),
    # besides the refits with refuting non-contacts (gpis_refute_rounds), never Newton's.
    fits = calls[:sum(s.gpis_faces is not None for s in session.snapshots)]
    assert sum(contacts >= 20 for contacts, _ in fits) > 5
    skipped = 0
    for contacts, newton in fits:
        # Every fit under 10 contacts, then every contacts // 10 fits at most.
        assert newton or (contacts >= 20 and skipped + 1 < min(contacts // 10,
                                                                 params.gpis_refit_every))
        skipped = 0 if newton else skipped + 1
    assert not all(newton for _, newton in fits)
    # Between two Newton steps the scale stays.
    scales = [s.gpis_scale for s in session.snapshots if s.gpis_faces is not None]
    assert len(set(scales)) <= sum(newton for _, newton in fits) + 1


def test_fast_session_extends_its_fit_and_goes_on_identically(bundled):
    session = _novel_session(bundled, "fast")
    session.run(max_steps=14)
    assert sum(s.gpis_faces is not None for s in session.snapshots) > 3
    contacts = session.filter.contact_positions
    np.testing.assert_array_equal(session.state.gpis.cache.rows[::4, :3], contacts)
    assert session.state.gpis.variance is not None
    restored = pickle.loads(pickle.dumps(session))
    for _ in range(3):
        ours, theirs = session.step(), restored.step()
        np.testing.assert_array_equal(ours.contacts, theirs.contacts)
        np.testing.assert_array_equal(ours.gpis_vertices, theirs.gpis_vertices)
        np.testing.assert_array_equal(ours.gpis_variance, theirs.gpis_variance)


class _Ball:
    """The signed distance of a ball of radius 3 about the origin."""

    def __call__(self, points):
        length = np.linalg.norm(points, axis=1)
        return length - 3.0, points / np.maximum(length, 1e-12)[:, None]


def test_carved_prior_with_a_bounded_search_is_the_csg_difference(rng):
    free = rng.uniform(-3, 3, size=(30, 3))
    carved = carved_prior(_Ball(), free, np.zeros((0, 3)), 0.6, neighbours=30)
    query = np.vstack([rng.uniform(-3.5, 3.5, size=(3000, 3)), free + 0.1])
    values, gradients = carved(query)
    base = _Ball()(query)[0]
    cuts = 0.6 - np.linalg.norm(query[:, None] - free[None], axis=2)
    np.testing.assert_array_equal(values, np.maximum(base, cuts.max(axis=1)))
    deep = (cuts.max(axis=1) > base) & (cuts.max(axis=1) < 0)
    assert deep.sum() > 10  # inside the prior, beyond every ball, yet cut (CSG)
    np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0)


def _fits_and_grid(mug, count):
    points, normals, prior = mug
    kernel = ThinPlateKernel(12.0)
    before, cache, _ = fit_gpis_incremental(points[:count - 1], normals[:count - 1], prior,
                                            kernel, refit=False, refit_score=np.inf)
    after = fit_gpis_incremental(points[:count], normals[:count], prior, kernel, cache,
                                 refit=False, refit_score=np.inf)[0]
    spacing = 8.0 / 32
    return before, after, lattice_low(np.full(3, -4.0), spacing), spacing


def test_node_variance_extended_by_the_new_rows_equals_a_full_solve(mug):
    before, after, low, spacing = _fits_and_grid(mug, 40)
    vertices = zero_level_surface(after, (low, np.full(3, 4.0)), 32, spacing=spacing)[0]
    _, nodes = lattice_variance(before, vertices, low, spacing)
    extended, _ = lattice_variance(after, vertices, low, spacing, nodes)
    full, _ = lattice_variance(after, vertices, low, spacing)
    np.testing.assert_allclose(extended, full, rtol=1e-7, atol=1e-9 * full.max())


def test_lattice_variance_is_near_the_exact_variance(mug):
    _, fit, low, spacing = _fits_and_grid(mug, 60)
    vertices = zero_level_surface(fit, (low, np.full(3, 4.0)), 32, spacing=spacing)[0]
    interpolated, _ = lattice_variance(fit, vertices, low, spacing)
    exact = fit.variance(vertices)
    error = np.abs(interpolated - exact)
    assert np.percentile(error, 99) < 0.05 * exact.max() and error.max() < 0.1 * exact.max()
    assert exact[np.argmax(interpolated)] > 0.95 * exact.max()
    nodes = low + spacing * np.array([[3, 5, 7], [10, 2, 31]])  # on nodes: exact
    np.testing.assert_allclose(lattice_variance(fit, nodes, low, spacing)[0],
                               fit.variance(nodes), rtol=1e-9)


def test_noncontact_rows_extend_the_factor_after_the_contacts(mug, rng):
    points, normals, prior = mug
    kernel, cache = ThinPlateKernel(12.0), None
    outside = rng.uniform(-3, 3, size=(40, 3))
    for count in (10, 11, 13):
        fit, cache, _ = fit_gpis_incremental(points[:count], normals[:count], prior, kernel,
                                             cache, refit=False, refit_score=np.inf,
                                             noncontacts=outside[:3 * count])
    full = fit_gpis(points[:13], normals[:13], prior, kernel, newton=False,
                    noncontacts=outside[:39])
    assert len(fit.kept) > 4 * 13
    query = points[:13] + 0.2
    np.testing.assert_allclose(fit.mean_value(query), full.mean_value(query), atol=1e-8)
    np.testing.assert_allclose(fit.variance(query), full.variance(query), atol=1e-8)


def test_a_probe_beside_the_prior_cuts_nothing_of_it(rng):
    # Free points 0.2 outside a ball of radius 3 refute nothing of it; with their balls of
    # 0.6 they would cut 0.4 into it. One inside still cuts.
    directions = rng.normal(size=(20, 3))
    beside = 3.2 * directions / np.linalg.norm(directions, axis=1)[:, None]
    through = np.array([[0.0, 0.0, 2.9]])
    free = np.vstack([beside, through])
    surface = 3.0 * directions / np.linalg.norm(directions, axis=1)[:, None]
    old = carved_prior(_Ball(), free, np.zeros((0, 3)), 0.6)
    new = carved_prior(_Ball(), free, np.zeros((0, 3)), 0.6, inside_only=True)
    assert np.all(old(surface)[0] > 0.3)
    np.testing.assert_array_equal(new(surface)[0], _Ball()(surface)[0])
    assert new(through)[0][0] > 0.5
    # Nothing inside: the prior itself.
    assert carved_prior(_Ball(), beside, np.zeros((0, 3)), 0.6, inside_only=True).__class__ is _Ball
