"""Target selection and contact enforcement on a sphere of radius 3 (exact answers)."""

import numpy as np
import pytest

from tactile_viz.engine import Contact, ContactSimulator, GroundTruth, NonContact
from tactile_viz.engine.exploration import (enforce_contact, farthest_vertex, first_contact,
                                            follow_surface, next_sweep_direction, rrt_step,
                                            sweep_directions, sweep_line)
from tactile_viz.engine.session import deepest_inside


@pytest.fixture
def simulator(sphere_model):
    return ContactSimulator(GroundTruth(sphere_model, np.eye(3), np.zeros(3)))


def _on_sphere(observation):
    return isinstance(observation, Contact) and abs(np.linalg.norm(observation.position) - 3) < 0.02


def test_first_contact_touches(simulator, rng):
    paths, observations = first_contact(simulator, np.zeros(3), rng)
    assert _on_sphere(observations[-1]) and len(paths) == len(observations)


def test_reaching_a_real_target_gives_one_contact(simulator):
    target, normal = np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, 1.0])
    paths, observations, reached = enforce_contact(
        simulator, target, normal, np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]]))
    assert reached and len(observations) == 1 and _on_sphere(observations[0])
    np.testing.assert_allclose(observations[0].position, target, atol=0.02)


def test_a_contact_on_the_way_to_the_nearest_contact_counts(simulator):
    # The estimate claims surface at z = 4.5; the sphere ends at 3, the probe reaches 3.6.
    # From there the way to the contact at (3, 0, 0) enters the sphere near (0.54, 0, 2.95).
    target, normal = np.array([0.0, 0.0, 4.5]), np.array([0.0, 0.0, 1.0])
    contacts, normals = np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]])
    paths, observations, reached = enforce_contact(simulator, target, normal, contacts,
                                                   normals, depth=0.9)
    assert isinstance(observations[0], NonContact)
    np.testing.assert_allclose(observations[0].position, [0, 0, 3.6])
    assert reached and len(observations) == 2 and _on_sphere(observations[1])
    np.testing.assert_allclose(observations[1].position, [0.54, 0, 2.95], atol=0.05)


def test_a_miss_beside_a_contact_follows_the_surface_to_a_new_contact(simulator):
    # The probe ends just outside the sphere next to the only contact: the sensor touches
    # that contact again and slides up toward the target until it is 0.3 from it.
    target, normal = np.array([3.5, 0.0, 0.5]), np.array([1.0, 0.0, 0.0])
    contacts, normals = np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]])
    paths, observations, reached = enforce_contact(simulator, target, normal, contacts,
                                                   normals, depth=0.4, follow_step=0.1,
                                                   spacing=0.3)
    assert isinstance(observations[0], NonContact) and reached
    touched = observations[1]
    assert _on_sphere(touched) and 0.3 <= touched.position[2] <= 0.45
    assert 0.3 <= np.linalg.norm(touched.position - contacts[0]) <= 0.45
    assert len(paths) >= 4  # probe, back to the contact, then several in-contact steps


def test_a_target_out_of_reach_is_reported(simulator):
    target, normal = np.array([3.5, 0.0, 0.5]), np.array([1.0, 0.0, 0.0])
    contacts, normals = np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]])
    _, observations, reached = enforce_contact(simulator, target, normal, contacts, normals,
                                               depth=0.4, follow_step=0.1, max_follow=0.05)
    assert not reached and _on_sphere(observations[-1])


def test_following_off_an_edge_comes_back_to_the_surface(simulator):
    contacts, normals = np.array([[0.0, 0, 3.0]]), np.array([[0.0, 0, 1.0]])
    paths, observations = follow_surface(simulator, np.array([50.0, 0, 3.0]), contacts, normals,
                                         step=2.9, depth=0.2)
    assert _on_sphere(observations[-1])


def test_rrt_steps_stay_near_the_nearest_contact(simulator, rng):
    contacts, normals = np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]])
    for _ in range(10):
        _, observations = rrt_step(simulator, contacts, normals, (-np.ones(3) * 6, np.ones(3) * 6),
                                   rng, step=0.3)
        assert _on_sphere(observations[-1])
        assert np.linalg.norm(observations[-1].position - contacts[0]) < 0.5


def test_farthest_vertex_and_deepest_inside():
    vertices = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
    assert farthest_vertex(vertices, np.array([[0.5, 0, 0]])) == 2
    estimate = lambda points: np.abs(points[:, 2] - 0.4) - 0.5  # noqa: E731 (slab, deepest at z=0.4)
    depth = deepest_inside(estimate, np.array([0.0, 0, 1.0]), np.array([0.0, 0, 1.0]), 1.0)
    assert depth == pytest.approx(0.6, abs=0.06)


def test_sweep_directions_are_spread_and_the_next_is_the_least_used(rng):
    directions = sweep_directions(64)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
    cosines = directions @ directions.T - 2 * np.eye(64)
    assert cosines.max() < np.cos(np.radians(20))  # no two within 20 degrees
    first = next_sweep_direction([], rng)
    second = next_sweep_direction([first], rng)
    assert first @ second < -0.95  # the opposite side (of the 64 directions)
    third = next_sweep_direction([first, second], rng)
    assert abs(third @ first) < 0.2  # then across


def test_a_sweep_line_records_the_first_surface_it_meets(simulator):
    paths, observations = sweep_line(simulator, np.array([0.0, 1.0, 0.0]),
                                     np.array([1.0, 0.0, 0.0]))
    touched = observations[0]
    assert _on_sphere(touched) and touched.position[0] > 0
    np.testing.assert_allclose(touched.position, [np.sqrt(8.0), 1.0, 0.0], atol=0.02)
    paths, observations = sweep_line(simulator, np.array([0.0, 4.0, 0.0]),
                                      np.array([1.0, 0.0, 0.0]))
    assert isinstance(observations[0], NonContact)
