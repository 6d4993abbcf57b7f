"""The prior bank: every prior's grid, features and point pairs in shared arrays."""

import pickle

import numpy as np
import pytest

from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.belief.prior_bank import PriorBank, bank_for
from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.params import FilterParams

NAMES = ("mug_1", "bottle_1", "guitar_1")


@pytest.fixture
def models(bundled):
    return [bundled[name] for name in NAMES]


def test_bank_evaluates_each_class_as_its_own_grid(models, rng):
    bank = PriorBank(models, 0.1, 12.0)
    classes = rng.integers(0, len(models), size=50)
    points = rng.uniform(-4.5, 4.5, size=(50, 7, 3))  # some beyond the grids
    values, gradients = bank.evaluate(classes, points)
    for c, model in enumerate(models):
        mine = classes == c
        expected_values, expected_gradients = model.sdf.evaluate(points[mine])
        np.testing.assert_allclose(values[mine], expected_values, atol=1e-12)
        np.testing.assert_allclose(gradients[mine], expected_gradients, atol=1e-12)


def test_bank_pairs_are_each_models_table(models):
    bank = PriorBank(models, 0.1, 12.0)
    assert len(bank.pairs) == sum(len(model.pair_table()) for model in models)
    points, normals = models[1].features
    from tactile_viz.engine.belief.ppf import pair_features

    features = pair_features(points[:5], normals[:5], points[5:10], normals[5:10])
    query, classes, first, second = bank.lookup(features)
    alone = models[1].pair_table().lookup(features)
    np.testing.assert_array_equal(first[classes == 1], alone[2])


def test_bank_is_compact(models):
    bank = PriorBank(models, 0.1, 12.0)
    # Measured: 0.4-1.0 MB a bundled prior (grid 5 bytes a node, pairs 4 bytes a pair).
    assert bank.nbytes / len(models) < 1.2e6
    assert bank.codes.dtype == np.int16 and bank.pairs.classes.dtype == np.uint8


def test_filters_over_the_same_priors_share_one_bank(models):
    library = PriorLibrary(models)
    first = ParticleFilter(library, FilterParams()).bank
    assert ParticleFilter(library, FilterParams(), rng=3).bank is first
    assert bank_for(models, 0.2, 12.0) is not first


def test_filter_pickles_without_its_bank(models):
    particle_filter = ParticleFilter(PriorLibrary(models), FilterParams(), rng=0)
    particle_filter.update(Contact([0.0, 0.0, 3.0], [0.0, 0.0, 1.0]))
    copy = pickle.loads(pickle.dumps(particle_filter))
    assert copy._bank is None
    contact = Contact([0.5, 0.0, 2.9], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(copy.update(contact).log_evidence,
                               particle_filter.update(contact).log_evidence)


def test_first_touch_spawns_at_most_max_particles(models):
    params = FilterParams(max_particles=150)
    particle_filter = ParticleFilter(PriorLibrary(models), params, rng=0)
    state = particle_filter.update(Contact([0.0, 0.0, 3.0], [0.0, 0.0, 1.0]))
    # 3 x 200 feature points would be 600 hypotheses; a random 150 of them, every class.
    assert state.n_particles <= 150
    assert set(np.unique(state.particles.classes)) == {0, 1, 2}
    everything = ParticleFilter(PriorLibrary(models), FilterParams(), rng=0)
    assert everything.update(Contact([0.0, 0.0, 3.0], [0.0, 0.0, 1.0])).n_particles == 600


@pytest.mark.parametrize("outliers", [0.0, 0.05])
def test_compiled_likelihood_is_the_numpy_one(models, rng, outliers):
    """The filter's compiled loops against the bank's numpy interpolation and the
    likelihood module, for hypotheses of every class, contacts and non-contacts near and
    beyond the grids."""
    from scipy.spatial.transform import Rotation

    from tactile_viz.engine.belief.likelihood import (
        log_contact_likelihood,
        log_noncontact_likelihood,
    )
    from tactile_viz.engine.belief.particle_filter import Particles

    params = FilterParams(outlier_probability=outliers)
    particle_filter = ParticleFilter(PriorLibrary(models), params, rng=0)
    k = 40
    particles = Particles(rng.integers(0, 3, k), Rotation.random(k, rng).as_matrix(),
                          rng.normal(size=(k, 3)), np.full(k, -np.log(k)))
    contacts = rng.uniform(-5, 5, size=(6, 3))
    normals = Rotation.random(6, rng).apply([0.0, 0.0, 1.0])
    noncontacts = rng.uniform(-5, 5, size=(4, 3))
    got = particle_filter.log_likelihood(particles, contacts, normals, noncontacts)
    local = lambda x: np.einsum("kij,kmi->kmj", particles.rotations,  # noqa: E731
                                x[None] - particles.translations[:, None])
    bank = particle_filter.bank
    values, gradients = bank.evaluate(particles.classes, local(contacts))
    observed = np.einsum("kij,mi->kmj", particles.rotations, normals)
    expected = log_contact_likelihood(values, gradients, observed, params.sigma_d,
                                      params.sigma_n, outliers).sum(axis=1)
    values, _ = bank.evaluate(particles.classes, local(noncontacts))
    expected += log_noncontact_likelihood(values, params.sigma_d).sum(axis=1)
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-9)


def test_compiled_alignment_is_align_pairs(models, rng):
    from tactile_viz.engine.belief import kernels
    from tactile_viz.engine.belief.ppf import align_pairs, local_frames

    bank = PriorBank(models, 0.1, 12.0)
    classes = rng.integers(0, 3, 30)
    first, second = rng.integers(0, 200, 30), rng.integers(0, 200, 30)
    observed = rng.normal(size=(5, 3)), _random_normals(rng, 5), rng.normal(size=(5, 3))
    query = rng.integers(0, 5, 30)
    rotations, translations = kernels.align(bank.frames, bank.points, classes, first, second,
                                            *local_frames(*observed), query)
    expected = align_pairs((bank.points[classes, first], bank.normals[classes, first],
                            bank.points[classes, second]), tuple(o[query] for o in observed))
    np.testing.assert_allclose(rotations, expected[0], atol=1e-9)
    np.testing.assert_allclose(translations, expected[1], atol=1e-9)


def _random_normals(rng, count):
    normals = rng.normal(size=(count, 3))
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_building_a_bank_does_not_keep_the_exact_distances(tmp_path):
    """The libigl trees a cold build needs (some 8 MB a prior) go with the build."""
    import trimesh

    from tactile_viz.engine import ObjectModel
    from tactile_viz.engine.io.cache import ArrayCache

    box = trimesh.creation.box(extents=(6, 3, 2))
    model = ObjectModel.from_arrays(box.vertices, box.faces, "box", cache=ArrayCache(tmp_path))
    PriorBank([model], 0.1, 12.0)
    assert "exact" not in model.__dict__
    model.exact  # noqa: B018 (a model that had them keeps them)
    PriorBank([model], 0.2, 12.0)
    assert "exact" in model.__dict__
