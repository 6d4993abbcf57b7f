import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.special import logsumexp

from tactile_viz.engine import (
    Contact,
    ContactSimulator,
    GroundTruth,
    NonContact,
    ObservationError,
    PriorLibrary,
    random_pose,
)
from tactile_viz.engine.belief.particle_filter import (
    ParticleFilter,
    stochastic_universal_resampling,
)
from tactile_viz.engine.explore.simulator import random_touch
from tactile_viz.engine.params import FilterParams
from tactile_viz.engine.presets import PRESETS, noise_matched, preset
from tactile_viz.engine.shape.metrics import pose_error

HOUSEHOLD = ["bottle_1", "mug_1", "ice_cream_1", "guitar_1", "vase_1", "office_chair", "sofa_1"]


@settings(max_examples=200, deadline=None)
@given(raw=st.lists(st.floats(0, 1e6), min_size=1, max_size=200), count=st.integers(1, 500),
       seed=st.integers(0, 2**32 - 1))
def test_sus_keeps_heavy_particles_and_draws_exactly_n(raw, count, seed):
    weights = np.array(raw) + 1e-12
    weights /= weights.sum()
    copies = stochastic_universal_resampling(weights, count, np.random.default_rng(seed))
    assert copies.sum() == count
    assert np.all(copies[weights > 1.0 / count] >= 1)
    assert np.all(copies >= np.floor(weights * count * (1 - 1e-9)))


@pytest.fixture(scope="module")
def known_library(bundled):
    return PriorLibrary(bundled[name] for name in [
        "armadillo", "asian_dragon", "elephant", "bottle_1", "mug_1", "ice_cream_1",
        "guitar_1", "vase_1", "office_chair", "sofa_1"])


def _run(library, truth, steps, seed, params=None):
    rng = np.random.default_rng(seed)
    simulator = ContactSimulator(truth, rng=seed)
    particle_filter = ParticleFilter(library, params, rng=seed)
    for _ in range(steps):
        state = particle_filter.update(simulator.probe(random_touch(truth, rng)))
        weights = state.particles.log_weights
        assert np.all(np.isfinite(weights)) and abs(logsumexp(weights)) < 1e-9
        assert np.isfinite(state.log_evidence)
    return particle_filter, state


@pytest.mark.slow
def test_recognition_on_the_known_set(known_library):
    """10 seeded trials, one per known object, random touches: right class and pose."""
    good = []
    for seed, name in enumerate(known_library.names):
        rotation, translation = random_pose(rng=100 + seed, max_translation=1.0)
        truth = GroundTruth(known_library[name], rotation, translation)
        _, state = _run(known_library, truth, 40, seed)
        error = pose_error(known_library[state.map_class], state.map_rotation,
                           state.map_translation, truth)
        good.append(state.map_class == name and error < 0.6)
    assert sum(good) >= 9, good


def test_known_object_is_judged_known(known_library):
    truth = GroundTruth(known_library["vase_1"], *random_pose(rng=5, max_translation=1.0))
    _, state = _run(known_library, truth, 25, seed=3)
    assert state.map_class == "vase_1" and not state.novel
    assert state.class_posterior["vase_1"] > 0.5


def test_creature_is_novel_among_household_priors(bundled):
    library = PriorLibrary(bundled[name] for name in HOUSEHOLD)
    truth = GroundTruth(bundled["neptune"], *random_pose(rng=8, max_translation=1.0))
    _, state = _run(library, truth, 25, seed=4)
    assert state.novel
    assert state.log_evidence < state.log_threshold


def test_state_reports_what_a_viewer_needs(known_library):
    truth = GroundTruth(known_library["mug_1"], np.eye(3), np.zeros(3))
    particle_filter, state = _run(known_library, truth, 3, seed=0)
    assert state.step == 3 and state.n_contacts == 3 and state.n_noncontacts == 0
    assert sum(state.class_posterior.values()) == pytest.approx(1.0)
    assert set(state.class_posterior) == set(known_library.names)
    assert state.map_rotation.shape == (3, 3) and state.map_translation.shape == (3,)
    assert state.n_particles == len(state.particles.classes) > 0


def test_non_contacts_before_first_contact_and_mixed_steps(known_library):
    particle_filter = ParticleFilter(known_library, rng=0)
    state = particle_filter.update(NonContact([10.0, 0, 0]))
    assert state.particles is None and state.n_noncontacts == 1
    state = particle_filter.update([NonContact([0, 10.0, 0]),
                                    Contact([0, 0, 3.0], [0, 0, 1.0])])
    assert state.n_particles > 0 and state.n_noncontacts == 2


@pytest.mark.parametrize("bad", [
    [Contact([0, 0, 0], [0, 0, 1]), "not an observation"],
    np.zeros(3),
    None,
])
def test_bad_observations_change_nothing(known_library, bad):
    particle_filter = ParticleFilter(known_library, rng=0)
    particle_filter.update(Contact([0, 0, 3.0], [0, 0, 1.0]))
    before = particle_filter.particles
    with pytest.raises(ObservationError):
        particle_filter.update(bad)
    assert particle_filter.particles is before and len(particle_filter.contact_positions) == 1


@pytest.mark.parametrize("position, normal", [
    ([np.nan, 0, 0], [0, 0, 1]), ([0, 0, 0], [0, 0, 0]), ([0, 0], [0, 0, 1]),
    ([0, 0, 0], [np.inf, 0, 1]),
])
def test_observation_validation(position, normal):
    with pytest.raises(ObservationError):
        Contact(position, normal)


def test_contact_normal_is_renormalised():
    np.testing.assert_allclose(Contact([0, 0, 0], [0, 0, 5.0]).normal, [0, 0, 1.0])


def test_presets_and_parameter_validation():
    assert PRESETS["paper"] == FilterParams(contenders=0, sdf_max_resolution=0,
                                            learned_noise=False)
    assert preset("fast").n_features < FilterParams().n_features
    assert preset("accurate").refine_map
    with pytest.raises(ValueError, match="unknown preset"):
        preset("fastest")
    for bad in [dict(sigma_d=-1.0), dict(sigma_n=0.0), dict(n_s=0), dict(lam=1.5),
                dict(sigma_d=float("nan")), dict(neighbour_bins=3), dict(contenders=-1),
                dict(contender_mass=1.5)]:
        with pytest.raises(ValueError):
            FilterParams(**bad)
    with pytest.raises(ValueError, match="unknown"):
        FilterParams.from_dict({"sigmad": 1.0})


def test_refinement_switch_does_not_hurt(known_library):
    """Over five seeds (one seed alone can go either way: seed 6 ends 0.19 refined, 0.06
    not), the median pose error with refinement is no worse."""
    truth = GroundTruth(known_library["guitar_1"], *random_pose(rng=11, max_translation=1.0))
    errors = {False: [], True: []}
    for seed in range(3, 8):
        for refine in (False, True):
            _, state = _run(known_library, truth, 20, seed=seed,
                            params=FilterParams(refine_map=refine))
            errors[refine].append(pose_error(known_library[state.map_class],
                                             state.map_rotation, state.map_translation, truth))
    assert np.median(errors[True]) <= np.median(errors[False]) + 0.02


vectors = st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3)


@settings(max_examples=25, deadline=None)
@given(steps=st.lists(st.tuples(vectors, vectors, st.booleans()), min_size=1, max_size=6),
       seed=st.integers(0, 1000))
def test_weights_stay_finite_for_arbitrary_observations(bundled, steps, seed):
    """Contacts anywhere (far outside every grid, at odd normals): never NaN or inf."""
    library = PriorLibrary(bundled[name] for name in ["mug_1", "sofa_1"])
    particle_filter = ParticleFilter(library, FilterParams(max_new_per_class=200), rng=seed)
    for position, normal, touched in steps:
        if not np.linalg.norm(normal) > 1e-6:
            normal = [0.0, 0.0, 1.0]
        observation = Contact(position, normal) if touched else NonContact(position)
        state = particle_filter.update(observation)
        if state.particles is not None:
            assert np.all(np.isfinite(state.particles.log_weights))
            assert abs(logsumexp(state.particles.log_weights)) < 1e-9
            assert not np.isnan(state.log_evidence)


def test_particle_budget_keeps_the_heaviest_new_particles(small_library):
    from tactile_viz.engine import ContactSimulator, GroundTruth, ParticleFilter
    from tactile_viz.engine.errors import ParameterError
    from tactile_viz.engine.explore.simulator import random_touch
    from tactile_viz.engine.params import FilterParams

    library, _ = small_library
    truth = GroundTruth(library["box"], np.eye(3), np.zeros(3))
    counts = {}
    for budget in (0, 50):
        simulator = ContactSimulator(truth, rng=0)
        belief = ParticleFilter(library, FilterParams(max_new_particles=budget), rng=0)
        rng = np.random.default_rng(1)
        sizes = []
        for _ in range(12):
            state = belief.update(simulator.probe(random_touch(truth, rng)))
            sizes.append(state.n_particles)
        counts[budget] = max(sizes)
        assert state.map_class == "box"
    assert counts[50] < counts[0]
    with pytest.raises(ParameterError, match="max_new_particles"):
        FilterParams(max_new_particles=-1)


def _learned(model, name):
    from tactile_viz.engine.shape.objects import ObjectModel

    return ObjectModel(name, model.mesh, model.params, model.cache, learned=True)


@pytest.mark.slow
def test_a_learned_prior_has_its_pose_refined_and_a_given_mesh_not(bundled):
    """With refine_learned a given mesh's poses are left as sampled (the same run), and a
    learned prior's heaviest particles are chosen for the least-squares pose, which never
    lowers their evidence. (The final MAP evidence of two runs is no test: refining changes
    the rest of the run, and over seeds 3-8 it came out higher in four of six.)"""
    truth = GroundTruth(bundled["guitar_1"], *random_pose(rng=11, max_translation=1.0))
    evidence = {}
    for refine in (False, True):
        _, state = _run(PriorLibrary([bundled["guitar_1"], bundled["mug_1"]]), truth, 12,
                        seed=3, params=FilterParams(refine_learned=3 if refine else 0))
        evidence[refine] = state.log_evidence
    assert evidence[True] == evidence[False]
    library = PriorLibrary([_learned(bundled["guitar_1"], "guitar"), bundled["mug_1"]])
    particle_filter, state = _run(library, truth, 12, seed=3,
                                  params=FilterParams(refine_learned=3))
    chosen = particle_filter._to_refine(int(np.argmax(state.particles.log_weights)))
    assert chosen and all(particle_filter.particles.classes[i] == 0 for i in chosen)
    for index in chosen:
        before = particle_filter.log_evidence_of(particle_filter.particles.take([index]))[0]
        particle_filter._refine(index)
        after = particle_filter.log_evidence_of(particle_filter.particles.take([index]))[0]
        assert after >= before
    # The refinement does move a pose: knocked 0.2 units off, the heaviest comes back.
    from tactile_viz.engine.belief.particle_filter import Particles

    index, particles = chosen[0], particle_filter.particles
    translations = particles.translations.copy()
    translations[index] += [0.2, 0.0, 0.0]
    particle_filter.particles = Particles(particles.classes, particles.rotations, translations,
                                          particles.log_weights)
    knocked = particle_filter.log_evidence_of(particle_filter.particles.take([index]))[0]
    particle_filter._refine(index)
    assert particle_filter.log_evidence_of(particle_filter.particles.take([index]))[0] > knocked


def test_merging_sums_the_weights_of_one_pose_and_keeps_classes_apart():
    from tactile_viz.engine.belief.particle_filter import Particles, merge_close_poses

    rotations = np.repeat(np.eye(3)[None], 4, axis=0)
    translations = np.array([[0.0, 0, 0], [0.01, 0, 0], [0.01, 0, 0], [2.0, 0, 0]])
    log_weights = np.log([0.4, 0.3, 0.2, 0.1])
    particles = Particles(np.array([0, 0, 1, 0]), rotations, translations, log_weights)
    merged = merge_close_poses(particles, 0.05, np.radians(1.0))
    assert len(merged) == 3
    weights = dict(zip(map(tuple, np.c_[merged.classes, merged.translations[:, 0]]),
                       np.exp(merged.log_weights)))
    assert weights[(0, 0.0)] == pytest.approx(0.7) and weights[(1, 0.01)] == pytest.approx(0.2)


def test_merging_stays_finite_with_negligible_weights():
    from tactile_viz.engine.belief.particle_filter import Particles, merge_close_poses

    count = 50
    rotations = np.repeat(np.eye(3)[None], count, axis=0)
    log_weights = np.r_[0.0, np.full(count - 1, -5000.0)]
    particles = Particles(np.zeros(count, int), rotations, np.zeros((count, 3)), log_weights)
    merged = merge_close_poses(particles, 0.05, np.radians(1.0))
    assert len(merged) == 1 and merged.log_weights[0] == pytest.approx(0.0)


def test_the_particle_caps_bound_the_count(bundled):
    library = PriorLibrary(bundled[name] for name in ["mug_1", "sofa_1", "vase_1"])
    truth = GroundTruth(bundled["mug_1"], *random_pose(rng=2, max_translation=1.0))
    params = FilterParams(max_particles=300, max_new_particles=150, merge_distance=0.05)
    particle_filter, state = _run(library, truth, 15, seed=4, params=params)
    assert len(state.particles) <= max(300 + 150, 3 * 200)


def test_under_noise_the_particles_stay_within_max_particles(bundled):
    """The noise-matched filter samples at nearly every step (noisy contacts never fit as
    well as the gate asks) from the nearest-bin look-up; new particles must not carry the
    count past ``max_particles``."""
    library = PriorLibrary(bundled[name] for name in ["mug_1", "sofa_1", "vase_1"])
    truth = GroundTruth(bundled["mug_1"], *random_pose(rng=5, max_translation=1.0))
    params = noise_matched(FilterParams(max_particles=300), 0.06, 2.0)
    assert params.neighbour_bins == 1  # the 24 nearest bins, not all 81
    simulator = ContactSimulator(truth, position_noise=0.06, normal_noise_deg=2.0, rng=6)
    particle_filter = ParticleFilter(library, params, rng=6)
    touches, sampled = np.random.default_rng(6), 0
    for _ in range(12):
        state = particle_filter.update(simulator.probe(random_touch(truth, touches)))
        sampled += state.sampled
        assert len(state.particles) <= 300
        assert abs(logsumexp(state.particles.log_weights)) < 1e-9
    assert sampled > 300  # the new particles alone would have passed the cap
