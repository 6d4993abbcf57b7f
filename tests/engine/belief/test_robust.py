"""Noise and outliers through the loop: the robust contact likelihood, the trimmed novelty
test, the simulated sensor's wrong contacts and the model's noise."""

import numpy as np
import pytest

from tactile_viz.engine import ContactSimulator, ParticleFilter, PriorLibrary
from tactile_viz.engine.belief.likelihood import (
    OUTLIER_NATS,
    log_contact_likelihood,
    log_normaliser,
)
from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.explore.simulator import random_touch
from tactile_viz.engine.params import FilterParams
from tactile_viz.engine.session import Session, make_truth


@pytest.fixture(scope="module")
def known():
    return PriorLibrary.bundled("known")


def test_the_mixture_caps_what_one_contact_can_cost():
    up = np.array([[0.0, 0.0, 1.0]])
    far = log_contact_likelihood(np.array([50.0]), up, up, 0.5, 1.5, 0.05)[0]
    peak = -log_normaliser(0.5, 1.5)
    assert far == pytest.approx(np.log(0.05) - OUTLIER_NATS + peak, abs=1e-6)
    gaussian = log_contact_likelihood(np.array([0.1]), up, up, 0.5, 1.5)[0]
    assert log_contact_likelihood(np.array([0.1]), up, up, 0.5, 1.5, 0.0)[0] == gaussian
    assert log_contact_likelihood(np.array([0.1]), up, up, 0.5, 1.5, 0.05)[0] == pytest.approx(
        gaussian + np.log(0.95), abs=1e-3)


@pytest.mark.parametrize("probability, novel_after_outlier", [(0.0, True), (0.05, False)])
def test_one_wrong_contact_does_not_make_a_known_object_novel(known, probability,
                                                            novel_after_outlier):
    truth = make_truth(known["mug_1"], rng=[0, 0])
    particle_filter = ParticleFilter(known, FilterParams(outlier_probability=probability), rng=0)
    simulator, rng = ContactSimulator(truth), np.random.default_rng(0)
    for index in range(21):
        observation = simulator.probe(random_touch(truth, rng))
        if index == 20:  # two units (a third of the mug) off, with a wrong normal
            observation = Contact(observation.position + [1.2, 0.0, 1.6], [0.0, 1.0, 0.0])
        state = particle_filter.update(observation)
    assert state.map_class == "mug_1"
    assert state.novel == novel_after_outlier


def test_the_simulated_sensor_makes_wrong_contacts(known):
    truth = make_truth(known["bottle_1"], rng=[1, 0])
    simulator = ContactSimulator(truth, outlier_fraction=0.5, rng=1)
    rng = np.random.default_rng(1)
    touches = [simulator.probe(random_touch(truth, rng)) for _ in range(40)]
    assert all(abs(truth.signed_distance(t.position[None])[0]) < 0.02 for t in touches)
    recorded = simulator.finish_step(touches)
    distances = np.abs([truth.signed_distance(t.position[None])[0] for t in recorded])
    assert 5 < np.sum(distances > 0.5) < 35 and np.sum(distances < 0.02) > 5


@pytest.mark.slow
def test_a_noisy_sensor_widens_the_model(known):
    session = Session.simulated(make_truth(known["mug_1"], rng=0), known, seed=0,
                      sensor_noise=(0.3, 5.0), sensor_outliers=0.05)
    assert session.filter.params.sigma_d == pytest.approx(np.hypot(0.5, 0.3))
    assert session.filter.params.neighbour_bins == 1
    assert session.simulator.outlier_fraction == 0.05
    snapshot = session.run(max_steps=15)
    assert snapshot.map_class == "mug_1"
