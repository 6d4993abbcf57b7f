"""Target selection and contact enforcement on a sphere of radius 3 (exact answers)."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import Contact, ContactSimulator, GroundTruth, NonContact
from tactile_viz.engine.explore.exploration import (
    RASTER_HALF,
    clearest_direction,
    enforce_contact,
    farthest_vertex,
    first_contact,
    follow_surface,
    grows_away,
    inward,
    next_sweep_direction,
    path_until,
    raster_path,
    rrt_step,
    sweep_directions,
    sweep_line,
    variance_target,
    weakest_support,
    widest_gap,
)
from tactile_viz.engine.session import deepest_inside, free_approach


@pytest.fixture
def simulator(sphere_model):
    return ContactSimulator(GroundTruth(sphere_model, np.eye(3), np.zeros(3)))


def _on_sphere(observation):
    return isinstance(observation, Contact) and abs(np.linalg.norm(observation.position) - 3) < 0.02


def test_first_contact_touches(simulator, rng):
    paths, observations = first_contact(simulator, np.zeros(3), rng)
    assert _on_sphere(observations[-1]) and len(paths) == len(observations)


@pytest.mark.parametrize("unit", [1e-3, 1.0, 1e3])
def test_the_first_lines_widen_after_fifty_misses_and_keep_them(unit):
    """Fifty lines pass within half a unit of the centre (each axis), drawn as they always
    were; if all miss, fifty more reach up to WIDE_OFFSET units; every miss is kept."""
    from tactile_viz.engine.explore.exploration import WIDE_OFFSET, first_contact_moves
    from tactile_viz.engine.explore.observations import NonContact

    centre = np.array([1.0, -2.0, 0.5]) * unit
    moves = first_contact_moves(centre, np.random.default_rng(4), radius=10 * unit, unit=unit)
    paths, path = [], next(moves)
    while len(paths) < 70:
        paths.append(path)
        path = moves.send(NonContact(path[-1]))
    done = None
    try:
        moves.send(Contact(path[0], np.array([0.0, 0.0, 1.0])))
    except StopIteration as stop:
        done = stop.value
    assert done is not None and len(done[0]) == len(done[1]) == 71
    assert all(isinstance(o, NonContact) for o in done[1][:-1])
    offsets = np.array([p.mean(axis=0) - centre for p in done[0]]) / unit
    assert np.abs(offsets[:50]).max() <= 0.5 and np.abs(offsets[50:]).max() > 0.5
    assert np.abs(offsets[50:]).max() <= WIDE_OFFSET
    again = np.random.default_rng(4)  # the first round's draws, as before
    again.normal(size=(1, 3))  # the first line's direction
    np.testing.assert_allclose(offsets[0], again.uniform(-0.5, 0.5, size=3), rtol=1e-9,
                               atol=1e-12)


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


@pytest.mark.parametrize("anchors", [1, 2])
def test_a_way_back_that_touches_nothing_tries_the_next_contact(simulator, anchors):
    # The nearest contact is a reading 0.5 off the sphere (noise, or a wrong one): the way
    # back to it ends in free space; the next nearest is on the sphere.
    target, normal = np.array([3.5, 0.0, 0.5]), np.array([1.0, 0.0, 0.0])
    contacts = np.array([[3.4, 0.3, 0.6], [3.0, 0, 0]])
    normals = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    paths, observations, reached = enforce_contact(simulator, target, normal, contacts,
                                                   normals, depth=0.4, anchors=anchors)
    assert isinstance(observations[0], NonContact)
    if anchors == 1:  # the paper's: only the miss is recorded
        assert len(observations) == 1 and not reached and len(paths) == 2
    else:
        assert reached and len(observations) == 2 and _on_sphere(observations[1])
        np.testing.assert_allclose(paths[2][1], contacts[1])


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


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_weakest_support_moves_on_from_places_tried(scale):
    # A line of vertices touched at both ends and at x = 6: the weakest support is the
    # middle of the longer span; that one tried, the sweep's cube about it (half-size
    # RASTER_HALF of 3) is left out, and the next lies just beyond it.
    vertices = scale * np.c_[np.linspace(0.0, 8.0, 81), np.zeros(81), np.zeros(81)]
    contacts = scale * np.array([[0.0, 0, 0], [6.0, 0, 0], [8.0, 0, 0]])
    vertex, distance = weakest_support(vertices, contacts, least=0.5 * scale)
    np.testing.assert_allclose(vertex, [3.0 * scale, 0, 0], atol=1e-9 * scale)
    assert distance == pytest.approx(3.0 * scale)
    tried = [vertex]
    vertex, distance = weakest_support(vertices, contacts, tried, least=0.5 * scale)
    assert abs(vertex[0] - 3.0 * scale) > RASTER_HALF * 3.0 * scale
    assert distance == pytest.approx(1.3 * scale)
    # At most `largest` is left out.
    vertex, _ = weakest_support(vertices, contacts, tried, 0.5 * scale, largest=0.5 * scale)
    assert abs(vertex[0] - 3.0 * scale) == pytest.approx(0.3 * scale)
    # The least distance is what is returned when the support is close.
    assert weakest_support(vertices, contacts, least=5.0 * scale)[1] == pytest.approx(
        5.0 * scale)
    # A place tried leaves out only as far as its own distance to the contacts now.
    near = weakest_support(vertices, np.vstack([contacts, [[3.0 * scale, 0, 0.1 * scale]]]),
                           [[3.0 * scale, 0, 0]])
    assert 1.4 * scale < near[0][0] < 1.6 * scale or 4.4 * scale < near[0][0] < 4.6 * scale


def test_the_weakest_support_of_nothing_or_all_tried():
    vertices = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    contacts = np.array([[3.0, 0, 0]])
    assert weakest_support(np.zeros((0, 3)), contacts) == (None, 0.0)
    assert weakest_support(vertices, np.zeros((0, 3))) == (None, 0.0)
    assert weakest_support(vertices, contacts, [[0.0, 0, 0]]) == (None, 0.0)


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


def test_a_long_approach_stops_short_of_what_the_estimate_predicts():
    # Estimate: two slabs, z in [-1, 0] and z in [1.2, 2]; from the top of the lower one the
    # approach may start at most just below the upper one.
    estimate = lambda points: np.maximum(np.minimum(  # noqa: E731
        np.abs(points[:, 2] + 0.5) - 0.5, np.abs(points[:, 2] - 1.6) - 0.4), -10.0)
    target, normal = np.zeros(3), np.array([0.0, 0.0, 1.0])
    clearance = free_approach(estimate, target, normal, 3.0)
    assert 1.0 <= clearance < 1.2
    assert free_approach(lambda p: np.ones(len(p)), target, normal, 3.0) == 3.0
    assert free_approach(estimate, target, normal, 0.5) == 0.5  # never longer than asked
    assert free_approach(lambda p: -np.ones(len(p)), target, normal, 3.0) == 0.5


def test_a_long_approach_meets_a_part_the_estimate_does_not_predict(simulator):
    # The estimate has a surface facing up at (2.9, 0, -1.5); the sphere (radius 3) crosses
    # the vertical line x = 2.9 at |z| < 0.77, above the target. An approach from 0.5 above
    # misses everything; one from 2.5 above starts outside the sphere, passes through it on
    # the way down and touches it there: a part nothing predicted.
    target, normal = np.array([2.9, 0.0, -1.5]), np.array([0.0, 0.0, 1.0])
    contacts, normals = np.array([[3.0, 0, 0]]), np.array([[1.0, 0, 0]])
    _, short, _ = enforce_contact(simulator, target, normal, contacts, normals, depth=0.2,
                                  clearance=0.5, max_follow=0.05)
    assert isinstance(short[0], NonContact)
    _, long, reached = enforce_contact(simulator, target, normal, contacts, normals, depth=0.2,
                                       clearance=2.5)
    assert reached and len(long) == 1 and _on_sphere(long[0])
    assert long[0].position[2] == pytest.approx(0.77, abs=0.03)


def _cube_contacts(half=2.0, count=6):
    """Contacts on the faces of a cube of half-size ``half`` (the estimate's surface)."""
    axis = np.linspace(-half, half, count)
    a, b = np.meshgrid(axis, axis)
    faces = []
    for dim in range(3):
        for sign in (-1.0, 1.0):
            face = np.zeros((a.size, 3))
            face[:, dim] = sign * half
            face[:, (dim + 1) % 3], face[:, (dim + 2) % 3] = a.ravel(), b.ravel()
            faces.append(face)
    return np.unique(np.vstack(faces), axis=0)


def test_the_widest_gap_is_where_nothing_was_observed():
    # A hollow cube of contacts, nothing estimated inside: every inside point is a candidate
    # and the one farthest from the observed points is chosen; with the corner (1, 1, 1)
    # region observed, the gap moves away from it.
    contacts = _cube_contacts()
    outside = lambda points: np.ones(len(points))  # noqa: E731 (nothing predicted inside)
    point, gap = widest_gap(contacts, contacts, np.zeros((0, 3)), outside)
    assert np.linalg.norm(point) < 0.3 and gap == pytest.approx(2.0, abs=0.2)
    observed = np.vstack([contacts, np.zeros((1, 3))])
    point, gap = widest_gap(contacts, observed, np.zeros((0, 3)), outside)
    assert 0.6 < gap < 1.6 and np.linalg.norm(point) > 0.6
    # Inside the estimate nothing is a candidate.
    assert widest_gap(contacts, contacts, contacts, lambda p: -np.ones(len(p)))[0] is None


def test_a_shell_gap_observed_only_is_not_bounded_by_the_estimate():
    # A flat estimate at z = 0 (outside above it), touched at one corner only: the space
    # just above the far corner is unobserved. Measured from the estimate too, no shell
    # point is wider than the shell; measured from the observations alone, one is.
    grid = np.linspace(-1.0, 1.0, 21)
    surface = np.array([[x, y, 0.0] for x in grid for y in grid])
    contacts = np.array([[-1.0, -1.0, 0.0], [-0.9, -1.0, 0.0], [-1.0, -0.9, 0.0],
                         [-0.95, -0.95, -0.1]])
    outside = lambda points: points[:, 2]  # noqa: E731
    _, bounded = widest_gap(contacts, contacts, surface, outside, shell=0.6)
    point, gap = widest_gap(contacts, contacts, surface, outside, shell=0.6, observed_only=True)
    assert bounded <= 0.6 + 1e-9 < gap
    assert point[0] > 0.5 and point[1] > 0.5 and 0.0 < point[2] <= 0.6 + 0.1


def test_a_gap_beyond_the_end_of_a_part_is_found_in_the_shell():
    # A rod's estimate along z ends at z = 2 (its contacts stop there): the shell reaches
    # beyond the end, the widest gap lies there.
    z = np.linspace(-2.0, 2.0, 21)
    ring = np.array([[np.cos(t), np.sin(t)] for t in np.linspace(0, 2 * np.pi, 8, endpoint=False)])
    surface = np.array([[0.2 * c, 0.2 * s, h] for h in z for c, s in ring])
    outside = lambda points: np.linalg.norm(points[:, :2], axis=1) - 0.2  # noqa: E731
    # The sides were approached along their normals, from 2 away: that space is swept.
    radial = np.column_stack([surface[:, :2] / 0.2, np.zeros(len(surface))])
    swept = np.vstack([surface + t * radial for t in np.arange(0.0, 2.01, 0.25)])
    point, gap = widest_gap(surface, swept, surface, outside, shell=0.6)
    assert point is not None and abs(point[2]) > 2.0 and gap >= 0.3


def test_a_gap_far_from_the_estimate_is_measured_in_full():
    # Contacts on a sphere of radius 2 around a small estimated ball of radius 0.5: the
    # widest gap lies halfway between, 0.75 from both, beyond the near distances the
    # estimate's vertices are first asked for; deep inside the ball nothing is a gap.
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5).vertices
    contacts = 2.0 * trimesh.creation.icosphere(subdivisions=3).vertices
    outside = lambda points: np.linalg.norm(points, axis=1) - 0.5  # noqa: E731
    for observed_only in (False, True):
        point, gap = widest_gap(contacts, contacts, ball, outside, shell=0.0,
                                observed_only=observed_only)
        assert abs(np.linalg.norm(point) - 1.25) < 0.15 and 0.6 < gap < 0.85


def test_inward_moves_a_rim_gap_until_its_lattice_reaches_the_band():
    # A flat estimate at z = 0: a gap 1.2 above it with a lattice of radius 0.5 (a cube
    # of half-size 0.275) moves straight down to 0.3 + 0.275; a gap already that near
    # stays, and so does any gap without an estimate.
    grid = np.linspace(-1.0, 1.0, 21)
    surface = np.array([[x, y, 0.0] for x in grid for y in grid])
    moved = inward([0.0, 0.0, 1.2], surface, 0.5)
    np.testing.assert_allclose(moved, [0.0, 0.0, 0.3 + RASTER_HALF * 0.5])
    np.testing.assert_allclose(inward([0.0, 0.0, 0.5], surface, 0.5), [0.0, 0.0, 0.5])
    np.testing.assert_allclose(inward([0.0, 0.0, 1.2], np.zeros((0, 3)), 0.5), [0, 0, 1.2])
    # In scene units: a 6 cm object's unit is 0.01.
    np.testing.assert_allclose(inward([0.0, 0.0, 0.012], surface * 0.01, 0.005, unit=0.01),
                               [0.0, 0.0, 0.003 + RASTER_HALF * 0.005])


def test_a_clear_direction_avoids_the_estimate():
    # The estimate is a wall at x = 1 in front of the point: the line must not come in
    # through it.
    y, z = np.meshgrid(np.linspace(-5, 5, 41), np.linspace(-5, 5, 41))
    wall = np.column_stack([np.ones(y.size), y.ravel(), z.ravel()])
    direction = clearest_direction(np.zeros(3), wall)
    assert direction[0] < 0.2


def test_a_raster_sweeps_a_cube_and_finds_a_thin_bar(sphere_model):
    path = raster_path(np.zeros(3), 1.0, np.array([0.0, 0.0, 1.0]), spacing=0.2, reach=5.0)
    np.testing.assert_allclose(path[0], [0, 0, 5.0])
    assert np.abs(path[1:]).max() <= 0.7 + 1e-9 and len(path) > 30
    # Any point of the cube lies within half a row spacing (and a bit) of the path.
    samples = path_until(path, np.full(3, 99.0), 0.05)
    probe = np.random.default_rng(0).uniform(-0.6, 0.6, size=(200, 3))
    from scipy.spatial import cKDTree
    assert cKDTree(samples).query(probe)[0].max() < 0.16
    # A sweep stops at its first touch: the samples end there.
    touched = path[5]
    until = path_until(path, touched, 0.25)
    assert np.linalg.norm(until[-1] - touched) < 0.3 and len(until) < len(samples) / 4


def test_the_variance_target_looks_beyond_a_distance_first():
    # Four vertices on a line, contacts at 0; the variance is largest beside the contact
    # (as under noise, where it is nearly flat), so only the distance moves the target.
    vertices = np.array([[0.1, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    subset, contacts = np.arange(4), np.zeros((1, 3))
    variance, reachable = np.array([1.0, 0.9, 0.8, 0.7]), np.ones(4, bool)
    assert variance_target(vertices, subset, variance, reachable, contacts) == 0
    assert variance_target(vertices, subset, variance, reachable, contacts, 0.5) == 1
    assert variance_target(vertices, subset, variance, reachable, contacts, 2.5) == 3
    # Nothing beyond it: the paper's target among all.
    assert variance_target(vertices, subset, variance, reachable, contacts, 5.0) == 0


def test_a_variance_that_does_not_grow_away_from_the_contacts_gives_the_farthest_target():
    # The same line: beside the contact the variance is largest (as once the fitted scale
    # falls to the noise's order); with the flag the farthest candidate is the target.
    vertices = np.array([[0.1, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    subset, contacts = np.arange(4), np.zeros((1, 3))
    falling, reachable = np.array([1.0, 0.9, 0.8, 0.7]), np.ones(4, bool)
    assert not grows_away(falling, np.arange(4.0))
    assert variance_target(vertices, subset, falling, reachable, contacts) == 0
    assert variance_target(vertices, subset, falling, reachable, contacts,
                           farthest_when_flat=True) == 3
    # A candidate out of reach still comes after the rest.
    reachable[3] = False
    assert variance_target(vertices, subset, falling, reachable, contacts,
                           farthest_when_flat=True) == 2
    # A variance that grows away from the contacts keeps the paper's target, the largest.
    rising = np.array([0.1, 0.5, 0.9, 0.7])
    assert grows_away(rising, np.arange(4.0))
    assert variance_target(vertices, subset, rising, np.ones(4, bool), contacts,
                           farthest_when_flat=True) == 2
    # A flat variance (a compact kernel's prior everywhere), or too few candidates to tell.
    assert not grows_away(np.ones(4), np.arange(4.0))
    assert grows_away(np.ones(2), np.arange(2.0))
