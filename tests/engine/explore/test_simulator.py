import numpy as np
import pytest

from tactile_viz.engine import Contact, ContactSimulator, GroundTruth, NonContact, random_pose
from tactile_viz.engine.explore.simulator import sample_path
from tactile_viz.engine.scene import Scene


@pytest.fixture(params=["mug_1", "armadillo", "office_chair"])
def truth(request, bundled):
    rotation, translation = random_pose(rng=3, max_translation=2.0)
    return GroundTruth(bundled[request.param], rotation, translation)


def _inward_probe(truth, rng):
    """A path from 1.5 units outside a random surface point to 1.5 units inside."""
    point = truth.surface_points(1, rng)[0]
    _, _, normal = truth.closest(point[None])
    return np.stack([point + 1.5 * normal[0], point - 1.5 * normal[0]])


def test_contacts_lie_within_tolerance_of_true_surface(truth, rng):
    simulator = ContactSimulator(truth)
    assert simulator.step == pytest.approx(truth.model.length / 300)
    for _ in range(40):
        observation = simulator.probe(_inward_probe(truth, rng))
        assert isinstance(observation, Contact)
        distance, _, normal = truth.closest(observation.position[None])
        assert abs(distance[0]) <= 0.01
        np.testing.assert_allclose(observation.normal, normal[0], atol=1e-9)


def test_path_that_misses_reports_non_contact_at_its_end(truth):
    start = truth.translation + [20.0, 0.0, 0.0]
    end = truth.translation + [20.0, 10.0, 0.0]
    observation = ContactSimulator(truth).probe([start, end])
    assert isinstance(observation, NonContact)
    np.testing.assert_allclose(observation.position, end)


def test_start_inside_follows_gradient_to_surface(truth, rng):
    point = truth.surface_points(1, rng)[0]
    _, _, normal = truth.closest(point[None])
    inside = point - 0.05 * normal[0]
    assert truth.signed_distance(inside[None])[0] < 0
    observation = ContactSimulator(truth).probe([inside, inside + [5.0, 0, 0]])
    assert isinstance(observation, Contact)
    assert abs(truth.signed_distance(observation.position[None])[0]) <= 0.01
    assert np.linalg.norm(observation.position - inside) <= 0.05 + 1e-6


def test_first_crossing_wins(bundled):
    truth = GroundTruth(bundled["bottle_1"], np.eye(3), np.zeros(3))
    observation = ContactSimulator(truth).probe([[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    assert isinstance(observation, Contact)
    assert observation.position[0] < 0 and observation.normal[0] < -0.9


def test_a_path_is_evaluated_in_batches_as_it_would_be_whole(truth, rng):
    """The first sample inside, wherever it falls among the doubling batches (a batch's
    first sample included), gives the contact the whole path's distances give."""
    simulator = ContactSimulator(truth)
    for crossing in (1, 31, 32, 33, 95, 96, 97, 500):
        point = truth.surface_points(1, rng)[0]
        _, _, normal = truth.closest(point[None])
        start = point + (crossing - 0.5) * simulator.step * normal[0]
        samples = sample_path([start, point - 0.2 * normal[0]], simulator.step)
        distance = truth.signed_distance(samples)
        hit = np.flatnonzero(distance <= 0)[0]
        expected = simulator._bisect(samples[hit - 1], samples[hit], distance[hit - 1])
        observation = simulator.probe([start, point - 0.2 * normal[0]])
        np.testing.assert_array_equal(observation.position, expected)


def _every_sample(field, samples):
    """The first sample inside and the distance before it, from every sample's distance."""
    distance = field(samples)
    if distance[0] < 0:
        return 0, None
    inside = np.flatnonzero(distance <= 0)
    if not len(inside):
        return None, None
    return inside[0], (distance[inside[0] - 1] if inside[0] else None)


@pytest.mark.parametrize("scene", [None, Scene.on_table(height=-2.5, tip_radius=0.3)])
def test_skipped_samples_change_no_first_contact(truth, rng, scene):
    """The samples skipped by their distance (1-Lipschitz) leave the first sample inside,
    and the distance before it, as every sample's distance gives them: polylines passing
    far, grazing and through the object, with and without a table and a tip."""
    simulator = ContactSimulator(truth, scene=scene)
    field = simulator._gap if scene is not None else truth.signed_distance
    found = 0
    for _ in range(40):
        ends = truth.translation + rng.normal(scale=rng.choice([1.0, 4.0, 12.0]), size=(3, 3))
        samples = sample_path(ends, simulator.step)
        hit, before = simulator._first_inside(samples, field)
        expected_hit, expected_before = _every_sample(field, samples)
        assert hit == expected_hit
        # A distance asked alone can differ from the batch's in its last bit.
        assert (before is None) == (expected_before is None)
        assert before is None or before == pytest.approx(expected_before, rel=1e-12)
        found += hit is not None
    assert 0 < found < 40  # both kinds of path were drawn


def test_a_path_from_the_surface_touches_at_its_start(truth, rng):
    simulator = ContactSimulator(truth)
    point = truth.surface_points(1, rng)[0]
    samples = sample_path([point, point + [5.0, 0.0, 0.0]], simulator.step)

    def on_surface(points):  # exactly 0 at the path's start
        return np.where(np.all(points == point, axis=1), 0.0, truth.signed_distance(points))

    assert simulator._first_inside(samples, on_surface) == (0, None)


def test_a_far_small_object_is_missed_without_asking_every_sample(bundled):
    """A line 20 units long past a 0.1 unit sphere: under 2,000 of its 60,000 samples are
    asked."""
    import trimesh

    from tactile_viz.engine import ObjectModel

    ball = trimesh.creation.icosphere(3, radius=0.05)
    truth = GroundTruth(ObjectModel.from_arrays(ball.vertices, ball.faces, "ball"), np.eye(3),
                        np.zeros(3))
    simulator = ContactSimulator(truth)
    asked = []
    field = truth.signed_distance

    def counted(points):
        asked.append(len(points))
        return field(points)

    samples = sample_path([[-10.0, 0.5, 0.0], [10.0, 0.5, 0.0]], simulator.step)
    assert len(samples) > 50_000
    assert simulator._first_inside(samples, counted) == (None, None)
    assert sum(asked) < 2_000


def test_same_seed_same_noisy_observations(truth):
    paths = [_inward_probe(truth, np.random.default_rng(i)) for i in range(10)]

    def run(seed):
        simulator = ContactSimulator(truth, position_noise=0.02, normal_noise_deg=10.0, rng=seed)
        return np.array([np.r_[o.position, o.normal] for o in map(simulator.probe, paths)])

    np.testing.assert_array_equal(run(5), run(5))
    assert not np.allclose(run(5), run(6))


@pytest.mark.slow
def test_noise_levels_are_as_asked(bundled, rng):
    truth = GroundTruth(bundled["vase_1"], np.eye(3), np.zeros(3))
    clean = ContactSimulator(truth)
    noisy = ContactSimulator(truth, position_noise=0.05, normal_noise_deg=15.0, rng=1)
    paths = [_inward_probe(truth, rng) for _ in range(300)]
    pairs = [(clean.probe(p), noisy.probe(p)) for p in paths]
    offsets = np.array([n.position - c.position for c, n in pairs])
    angles = np.degrees([np.arccos(np.clip(c.normal @ n.normal, -1, 1)) for c, n in pairs])
    assert np.std(offsets) == pytest.approx(0.05, rel=0.2)
    assert np.sqrt(np.mean(angles**2)) == pytest.approx(15.0, rel=0.2)


def test_sample_path_steps():
    samples = sample_path([[0, 0, 0], [1, 0, 0], [1, 1, 0]], 0.3)
    assert np.all(np.linalg.norm(np.diff(samples, axis=0), axis=1) <= 0.3 + 1e-12)
    np.testing.assert_allclose(samples[[0, -1]], [[0, 0, 0], [1, 1, 0]])
    with pytest.raises(ValueError):
        sample_path([[0, 0, np.nan]], 0.1)


def test_bad_simulator_parameters(truth):
    with pytest.raises(ValueError):
        ContactSimulator(truth, step=0)
    with pytest.raises(ValueError):
        ContactSimulator(truth, position_noise=-1)
