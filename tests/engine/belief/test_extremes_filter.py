"""The likelihood and the particle filter at the extremes.

Widths of the likelihood from 1e-6 to 1e6, one to 1,000 contacts, duplicate contacts,
contacts on a plane or a line or far outside every prior, point pairs with parallel,
antiparallel or zero-length geometry, and a likelihood that underflows for every particle
in linear space. Every case must give finite, normalised weights and a sensible belief, or
one of the project's own errors.
"""

import numpy as np
import pytest
import trimesh
from scipy.special import logsumexp

from tactile_viz.engine import (
    Contact,
    ContactSimulator,
    GroundTruth,
    NonContact,
    ObjectModel,
    ObservationError,
    ParameterError,
    PriorLibrary,
    TactileVizError,
    random_pose,
)
from tactile_viz.engine.belief.likelihood import (
    log_contact_likelihood,
    log_noncontact_likelihood,
    log_normaliser,
    normalise_log_weights,
)
from tactile_viz.engine.belief.particle_filter import ParticleFilter, Particles
from tactile_viz.engine.belief.ppf import align_pairs, is_degenerate, local_frames, pair_features
from tactile_viz.engine.explore.simulator import random_touch
from tactile_viz.engine.params import FilterParams
from tactile_viz.engine.presets import noise_matched, preset
from tactile_viz.engine.shape.metrics import pose_error

WIDTHS = [1e-6, 1e-3, 1.0, 1e3, 1e6]


@pytest.fixture(scope="module")
def library(bundled):
    return PriorLibrary(bundled[name] for name in ["mug_1", "vase_1", "bottle_1"])


@pytest.fixture(scope="module")
def mug_touches(library):
    """Twelve clean contacts on mug_1 at a random pose."""
    truth = GroundTruth(library["mug_1"], *random_pose(rng=1, max_translation=1.0))
    simulator = ContactSimulator(truth)
    rng = np.random.default_rng(0)
    return truth, [simulator.probe(random_touch(truth, rng)) for _ in range(12)]


def _assert_sound(state):
    """Finite normalised weights, a class posterior summing to one, no NaN evidence."""
    weights = state.particles.log_weights
    assert len(weights) > 0
    assert np.all(np.isfinite(weights)) and abs(logsumexp(weights)) < 1e-9
    assert not np.isnan(state.log_evidence) and np.isfinite(state.log_threshold)
    assert sum(state.class_posterior.values()) == pytest.approx(1.0)
    assert np.all(np.isfinite(state.map_rotation)) and np.all(np.isfinite(state.map_translation))


def _run(library, observations, params=None, seed=0):
    particle_filter = ParticleFilter(library, params or FilterParams(max_new_per_class=300),
                                     rng=seed)
    for observation in observations:
        state = particle_filter.update(observation)
        if state.particles is not None:
            _assert_sound(state)
    return particle_filter, state


# ----------------------------------------------------------------- likelihood widths
@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("which", ["sigma_d", "sigma_n", "both"])
def test_likelihood_widths_from_1e_minus6_to_1e6(library, mug_touches, width, which):
    truth, touches = mug_touches
    names = ["sigma_d", "sigma_n"] if which == "both" else [which]
    params = FilterParams(max_new_per_class=300, **{name: width for name in names})
    _, state = _run(library, touches, params)
    assert state.map_class == "mug_1"
    if width >= 1e3:
        # So wide that every contact scores nearly its maximum 1/Z: known, whatever the pose.
        assert not state.novel
        assert state.log_evidence == pytest.approx(
            -len(touches) * log_normaliser(params.sigma_d, params.sigma_n), abs=1.0)
    if which != "sigma_n" and width <= 1e-3:
        # Narrower than the 0.01 contact tolerance and the grid's error: nothing fits, novel.
        assert state.novel


@pytest.mark.parametrize("sigma", [1e-6, 1e6])
def test_likelihood_terms_stay_finite_far_away(sigma):
    distance = np.array([0.0, 1e-3, 10.0, 1e6 * np.sqrt(3) * 2])
    normals = np.array([[0, 0, 1.0]] * 4)
    flipped = -normals
    contact = log_contact_likelihood(distance, normals, flipped, sigma, sigma)
    outside = log_noncontact_likelihood(np.concatenate([-distance, distance]), sigma)
    assert np.all(np.isfinite(contact)) and np.all(np.isfinite(outside))
    assert np.all(np.diff(contact) <= 0)  # farther is never more likely
    assert np.all(outside <= 0)


def test_weights_that_are_all_zero_become_uniform_not_nan():
    """All -inf (nothing explains the data) used to give -inf - (-inf) = NaN."""
    weights = normalise_log_weights(np.full(4, -np.inf))
    np.testing.assert_allclose(weights, np.log(0.25))
    mixed = normalise_log_weights([-np.inf, -1e4, -1e4])
    assert mixed[0] == -np.inf and np.allclose(mixed[1:], np.log(0.5))


# ----------------------------------------------------------------- how many contacts
def test_one_contact_ties_every_feature_alignment(library, mug_touches):
    _, touches = mug_touches
    particle_filter, state = _run(library, touches[:1])
    _assert_sound(state)
    # Every feature point of every class on the contact, all equally likely.
    weights = state.particles.log_weights
    np.testing.assert_allclose(weights, weights[0])
    assert state.n_contacts == 1 and state.sampled == 0
    assert len(particle_filter.contact_positions) == 1


def test_two_contacts_break_the_tie(library, mug_touches):
    _, touches = mug_touches
    _, state = _run(library, touches[:2])
    assert state.n_contacts == 2
    assert np.ptp(state.particles.log_weights) > 0 or state.n_particles == 1


@pytest.mark.slow
def test_a_thousand_contacts(library):
    """1,000 contacts in 40 batches of 25: right class and pose, known, finite (~6 s)."""
    truth = GroundTruth(library["bottle_1"], *random_pose(rng=5, max_translation=1.0))
    points = truth.surface_points(1000, rng=1)
    _, _, normals = truth.closest(points)
    contacts = [Contact(p, n) for p, n in zip(points, normals)]
    particle_filter = ParticleFilter(library, FilterParams(), rng=1)
    for start in range(0, 1000, 25):
        state = particle_filter.update(contacts[start:start + 25])
        _assert_sound(state)
    assert state.n_contacts == 1000 and np.isfinite(state.log_evidence)
    assert state.map_class == "bottle_1" and not state.novel
    assert pose_error(library["bottle_1"], state.map_rotation, state.map_translation,
                      truth) < 0.6


# ----------------------------------------------------------------- duplicates
def test_exact_duplicate_contacts_add_no_point_pairs(library, mug_touches):
    _, touches = mug_touches
    particle_filter, state = _run(library, touches[:1])
    for _ in range(4):
        state = particle_filter.update(touches[0])
        _assert_sound(state)
        assert state.sampled == 0  # every pair with a copy of itself is degenerate
    state = particle_filter.update([touches[0]] * 5)  # and five copies in one step
    _assert_sound(state)
    assert state.n_contacts == 10


@pytest.mark.parametrize("offset", [1e-12, 1e-9, 1e-7, 1e-4])
def test_near_duplicate_contacts(library, mug_touches, offset):
    _, touches = mug_touches
    base = touches[:4]
    twins = [Contact(c.position + offset, c.normal) for c in base]
    _, state = _run(library, base + twins + touches[4:8])
    assert state.map_class == "mug_1"


# ----------------------------------------------------------------- degenerate layouts
@pytest.fixture(scope="module")
def box_library(tmp_path_factory):
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    return PriorLibrary([ObjectModel.from_arrays(box.vertices, box.faces, "box", cache=cache),
                         ObjectModel.from_arrays(cylinder.vertices, cylinder.faces, "cylinder",
                                                 cache=cache)])


@pytest.mark.slow
def test_all_contacts_on_one_plane(box_library):
    """The top face of the box: the belief must put a flat face of some prior there."""
    rng = np.random.default_rng(2)
    points = np.column_stack([rng.uniform(-2.5, 2.5, 30), rng.uniform(-1.2, 1.2, 30),
                              np.ones(30)])
    particle_filter, state = _run(box_library, [Contact(p, [0, 0, 1.0]) for p in points])
    best = state.particles.take([int(np.argmax(state.particles.log_weights))])
    local = (points - best.translations[0]) @ best.rotations[0]
    values, gradients = particle_filter.models[best.classes[0]].sdf.evaluate(local)
    assert not state.novel
    assert np.median(np.abs(values)) < 0.05 and np.abs(values).max() < 0.5
    normals = gradients @ best.rotations[0].T
    assert np.median(normals[:, 2]) > 0.99


@pytest.mark.slow
def test_all_contacts_on_one_line(box_library):
    """Contacts along a line with one normal: pose about the line is undetermined, but the
    weights stay finite and the contacts lie on the MAP surface."""
    points = np.column_stack([np.linspace(-2.5, 2.5, 20), np.zeros(20), np.ones(20)])
    particle_filter, state = _run(box_library, [Contact(p, [0, 0, 1.0]) for p in points])
    best = state.particles.take([int(np.argmax(state.particles.log_weights))])
    local = (points - best.translations[0]) @ best.rotations[0]
    values = particle_filter.models[best.classes[0]].sdf.distance(local)
    assert not state.novel
    assert np.median(np.abs(values)) < 0.1 and np.abs(values).max() < 0.5


@pytest.mark.parametrize("distance", [1e3, 1e6 / 2])
def test_contacts_far_outside_every_prior_grid(library, mug_touches, distance):
    """Far contacts that no prior can explain: finite weights and the object is novel."""
    _, touches = mug_touches
    far = [Contact([distance, 0, 0], [0, 0, 1.0]), NonContact([-distance, distance, 0]),
           Contact([distance, distance, -distance], [1.0, 0, 0])]
    _, state = _run(library, touches[:5] + far)
    assert state.novel and state.log_evidence < state.log_threshold
    # Far non-contacts alone are simply outside every shape: no evidence against it.
    _, state = _run(library, touches[:5] + [NonContact([distance, 0, 0])])
    assert state.n_noncontacts == 1


def test_out_of_range_observation_is_refused_and_changes_nothing(library, mug_touches):
    _, touches = mug_touches
    particle_filter, state = _run(library, touches[:3])
    before = particle_filter.particles
    with pytest.raises(ObservationError, match="out of range"):
        particle_filter.update(Contact([1e200, 0, 0], [0, 0, 1.0]))
    with pytest.raises(ObservationError, match="non-contact position is out of range"):
        NonContact([0, -2e6, 0])
    assert particle_filter.particles is before and len(particle_filter.contact_positions) == 3


def test_huge_normal_is_renormalised_not_zeroed():
    """The length of (1e300, 1e300, 0) overflows; it used to become a zero normal."""
    np.testing.assert_allclose(Contact([0, 0, 0], [1e300, 1e300, 0]).normal,
                               [np.sqrt(0.5), np.sqrt(0.5), 0])
    np.testing.assert_allclose(Contact([0, 0, 0], [0, -1e-8, 0]).normal, [0, -1.0, 0])


# ----------------------------------------------------------------- point pairs
def _pair_cases():
    z, x = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    p1, p2 = np.zeros(3), np.array([2.0, 0.5, 0])
    return {
        # name: (p1, n1, p2, n2, degenerate)
        "parallel normals": (p1, z, p2, z, False),
        "antiparallel normals": (p1, z, p2, -z, False),
        "normals along -x (rotation by pi)": (p1, -x, np.array([0.5, 2.0, 0]), -x, False),
        "antiparallel along x": (p1, x, np.array([0.5, 2.0, 1.0]), -x, False),
        "zero distance": (p1, z, p1, x, True),
        "zero distance, same normal": (p1, z, p1, z, True),
        "difference along the first normal": (p1, z, np.array([0, 0, 2.0]), x, True),
        "difference along the second normal": (p1, x, np.array([0, 0, -2.0]), z, True),
    }


@pytest.mark.parametrize("case", sorted(_pair_cases()))
def test_pair_geometry_extremes(case):
    p1, n1, p2, n2, degenerate = _pair_cases()[case]
    features = pair_features(p1, n1, p2, n2)
    assert np.all(np.isfinite(features))
    assert np.all((features[1:] >= 0) & (features[1:] <= np.pi))
    assert bool(is_degenerate(p1, n1, p2, n2)) == degenerate
    rotation, translation, alpha = local_frames(p1[None], n1[None], p2[None])
    assert np.all(np.isfinite(rotation)) and np.isfinite(alpha).all()
    np.testing.assert_allclose(rotation[0] @ n1, [1, 0, 0], atol=1e-12)
    if degenerate:
        return
    # A rigid motion of a good pair is recovered exactly by the alignment.
    turn, shift = random_pose(rng=3, max_translation=2.0)
    world = (p1 @ turn.T + shift, n1 @ turn.T, p2 @ turn.T + shift)
    rotations, translations = align_pairs(tuple(v[None] for v in (p1, n1, p2)),
                                          tuple(v[None] for v in world))
    np.testing.assert_allclose(rotations[0], turn, atol=1e-9)
    np.testing.assert_allclose(translations[0], shift, atol=1e-9)


def test_degenerate_pairs_only_give_no_particles(library):
    """Contacts whose every pair is degenerate (all stacked along their common normal)."""
    contacts = [Contact([0, 0, z], [0, 0, 1.0]) for z in (0.0, 0.5, 1.0, 1.5)]
    _, state = _run(library, contacts)
    assert state.sampled == 0


# ----------------------------------------------------------------- underflow and recovery
def test_recovery_when_every_particle_underflows(library):
    """All hypotheses far off the data: every particle's likelihood of the next contact is
    below the smallest double (exp underflows to 0), so a linear-space filter would divide
    0 by 0. The filter must keep finite weights and recover by point-pair sampling."""
    truth = GroundTruth(library["vase_1"], *random_pose(rng=2, max_translation=1.0))
    simulator = ContactSimulator(truth)
    rng = np.random.default_rng(0)
    particle_filter = ParticleFilter(library, rng=0)
    particle_filter.update(simulator.probe(random_touch(truth, rng)))
    moved = particle_filter.particles
    particle_filter.particles = Particles(moved.classes, moved.rotations,
                                          moved.translations + [40.0, 0, 0], moved.log_weights)
    contact = simulator.probe(random_touch(truth, rng))
    log_likelihood = particle_filter.log_likelihood(particle_filter.particles,
                                                    contact.position[None], contact.normal[None])
    assert np.all(np.exp(log_likelihood) == 0.0)
    state = particle_filter.update(contact)
    _assert_sound(state)
    assert state.sampled > 0
    for _ in range(15):
        state = particle_filter.update(simulator.probe(random_touch(truth, rng)))
        _assert_sound(state)
    assert state.map_class == "vase_1" and not state.novel
    assert pose_error(library["vase_1"], state.map_rotation, state.map_translation, truth) < 0.6


def test_contact_from_another_object_first_makes_it_novel(library):
    """A first contact from a decoy 30 units away, then 15 from the truth: no hypothesis
    explains both, every particle underflows in linear space, weights stay finite and the
    data are judged novel (no known object at one pose fits them all)."""
    truth = GroundTruth(library["vase_1"], *random_pose(rng=2, max_translation=1.0))
    decoy = GroundTruth(library["mug_1"], random_pose(rng=3)[0], truth.translation + [30.0, 0, 0])
    rng = np.random.default_rng(1)
    first = ContactSimulator(decoy).probe(random_touch(decoy, rng))
    simulator = ContactSimulator(truth)
    _, state = _run(library, [first] + [simulator.probe(random_touch(truth, rng))
                                        for _ in range(15)])
    assert np.exp(state.log_evidence) == 0.0
    assert state.novel


# ----------------------------------------------------------------- parameters
@pytest.mark.parametrize("changes, field", [
    (dict(sigma_d=-0.5), "sigma_d"), (dict(sigma_n=float("inf")), "sigma_n"),
    (dict(sigma_d="0.5"), "sigma_d"), (dict(sigma_n=None), "sigma_n"),
    (dict(n_s=0), "n_s"), (dict(n_s=2.5), "n_s"), (dict(n_s=True), "n_s"),
    (dict(lam=0.0), "lam"), (dict(known_fraction=-0.1), "known_fraction"),
    (dict(distance_step=0.0), "distance_step"), (dict(angle_step_deg=-12), "angle_step_deg"),
    (dict(max_particles=0), "max_particles"), (dict(refine_map="yes"), "refine_map"),
    (dict(refine_learned=-1), "refine_learned"),
    (dict(sdf_resolution=4), "sdf_resolution"), (dict(n_features=2), "n_features"),
])
def test_out_of_range_filter_parameters_name_the_parameter(changes, field):
    with pytest.raises(ParameterError, match=field) as raised:
        FilterParams(**changes)
    assert isinstance(raised.value, (TactileVizError, ValueError))


def test_empty_library_is_a_parameter_error():
    with pytest.raises(ParameterError, match="empty"):
        ParticleFilter(PriorLibrary())


def test_filter_parameters_from_bad_dicts():
    assert FilterParams(n_s=30.0).n_s == 30 and isinstance(FilterParams(n_s=30.0).n_s, int)
    for bad in (["sigma_d", 0.5], "sigma_d=0.5", None):
        with pytest.raises(ParameterError, match="must be a dict"):
            FilterParams.from_dict(bad)
    with pytest.raises(ParameterError, match="unknown preset"):
        preset("fastest")


def test_noise_matched_parameters():
    paper = preset("paper")
    assert noise_matched(paper, 0.0, 0.0) == paper
    matched = noise_matched(paper, 0.05, 15.0)
    assert matched.neighbour_bins == 1
    assert matched.sigma_d == pytest.approx(np.hypot(0.5, 0.05))
    assert matched.sigma_n == pytest.approx(np.hypot(1.5, np.radians(15.0)))
    assert noise_matched(paper, 0.001, 1.0).neighbour_bins == 0  # below a quarter bin
    for bad in ((-0.1, 0.0), (0.0, float("nan")), ("0.05", 15.0)):
        with pytest.raises(ParameterError):
            noise_matched(paper, *bad)


@pytest.mark.parametrize("changes, field", [
    (dict(position_noise=-0.01), "position_noise"), (dict(normal_noise_deg=float("nan")),
                                                     "normal_noise_deg"),
    (dict(step=float("inf")), "step"), (dict(tolerance=-1.0), "tolerance"),
])
def test_out_of_range_simulator_parameters(library, changes, field):
    truth = GroundTruth(library["mug_1"], np.eye(3), np.zeros(3))
    with pytest.raises(ParameterError, match=field):
        ContactSimulator(truth, **changes)


@pytest.mark.slow
@pytest.mark.parametrize("noise", [(0.05, 0.0), (0.0, 15.0), (0.05, 15.0)])
def test_noisy_sensing_at_the_largest_noise_stays_sound(library, noise):
    """Position noise 0.05 and normal noise 15 degrees: still finite, still the mug."""
    truth = GroundTruth(library["mug_1"], *random_pose(rng=4, max_translation=1.0))
    simulator = ContactSimulator(truth, position_noise=noise[0], normal_noise_deg=noise[1],
                                 rng=3)
    rng = np.random.default_rng(3)
    params = noise_matched(FilterParams(max_new_per_class=500), *noise)
    _, state = _run(library, [simulator.probe(random_touch(truth, rng)) for _ in range(20)],
                    params, seed=3)
    assert state.map_class == "mug_1"
    assert pose_error(library["mug_1"], state.map_rotation, state.map_translation, truth) < 0.6


@pytest.mark.slow
def test_noise_benchmark_command(tmp_path, capsys):
    """``python -m tactile_viz bench noise`` on a tiny grid: table, rows and plot written."""
    import json

    from tactile_viz.__main__ import main

    out = tmp_path / "noise"
    assert main(["bench", "noise", "--levels", "0:0", "0.05:15", "--seeds", "1",
                 "--contacts", "4", "--objects", "mug_1", "--out", str(out),
                 "--no-progress"]) == 0
    rows = json.loads((out / "noise.json").read_text())
    assert {(r["position_noise"], r["config"]) for r in rows} == {
        (0.0, "paper"), (0.0, "matched"), (0.05, "paper"), (0.05, "matched")}
    assert all(r["trials"] == 1 and 0 <= r["recognised"] <= 1 for r in rows)
    assert (out / "noise.png").stat().st_size > 10_000
    assert "| 0.05 | 15 | matched | 1 |" in (out / "noise.md").read_text()
    assert "noise.md" in capsys.readouterr().out
