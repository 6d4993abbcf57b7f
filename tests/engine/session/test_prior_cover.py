"""A novel object's prior cover (``cover_prior``, beyond the paper): the part of the MAP
prior that the stop still asks to touch, on its own (a planner with no session)."""

import dataclasses
import functools
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.scene import FREE
from tactile_viz.engine.session.context import StepContext
from tactile_viz.engine.session.planner import Planner
from tactile_viz.engine.session.state import ExplorationState


def _ball(radius, subdivisions=3):
    return trimesh.creation.icosphere(subdivisions, radius).vertices


def _planner(scale, carve=0.1):
    """A planner with what its coverage reads: parameters in scene units, the exploration
    state and the scene (the paper's free space); no filter."""
    p = session_preset("recommended")
    p = dataclasses.replace(p, eps=0.1 * scale, contact_spacing=0.05 * scale,
                            gpis_carve_radius=carve * scale)
    return Planner(StepContext(p, scale, scale, scene=FREE), None, ExplorationState())


def _estimate(radius):
    """A reconstruction whose surface is a ball of ``radius`` about the origin."""
    ball = trimesh.creation.icosphere(3, radius)
    fit = types.SimpleNamespace(mean_value=lambda q: np.linalg.norm(q, axis=1) - radius)
    return types.SimpleNamespace(vertices=ball.vertices, faces=ball.faces, empty=False, fit=fit,
                                 closure=np.zeros(len(ball.vertices), bool))


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_missed_probes_refute_the_prior_where_they_passed(scale):
    # The prior stands 0.3 off the object: no contact comes within eps of it; missed
    # probes through it refute it where they passed, and only there.
    planner, recon = _planner(scale), _estimate(scale)
    contacts = _ball(scale, 2)
    prior = _ball(1.3 * scale)
    assert planner.coverage(recon, prior, contacts).prior_dhd > 0.25 * scale
    directions = prior / np.linalg.norm(prior, axis=1, keepdims=True)
    upper = directions[:, 2] >= 0  # probes missed through the upper half only
    way = np.concatenate([d * scale * np.linspace(1.0, 2.0, 21)[:, None]
                          for d in directions[upper]])
    planner.state.free_space = way
    coverage = planner.coverage(recon, prior, contacts)
    assert coverage.prior_open is not None
    assert not coverage.prior_open[upper].any()
    assert coverage.prior_open[directions[:, 2] < -0.2].all()
    assert coverage.prior_dhd > 0.25 * scale  # the lower half is still open


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_refuted_everywhere_has_nothing_left_to_cover(scale):
    # Probes missed through all of the prior: none of it is left to touch, and the stop
    # does not wait for it (a 2 mm fork's held prior, refuted everywhere, held its stop
    # 28 mm off for 80 touches). The estimate's own DHD keeps every vertex then.
    planner, recon = _planner(scale), _estimate(scale)
    contacts = _ball(scale, 2)
    prior = _ball(1.3 * scale)
    directions = prior / np.linalg.norm(prior, axis=1, keepdims=True)
    planner.state.free_space = np.concatenate(
        [d * scale * np.linspace(1.0, 2.0, 21)[:, None] for d in directions])
    coverage = planner.coverage(recon, prior, contacts)
    assert not coverage.prior_open.any() and coverage.prior_dhd == 0.0
    assert coverage.reachable.all()  # every estimate vertex lies near a refuted point


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_many_times_the_objects_size_is_not_covered(scale):
    # A 2 cm block's 25 cm knife prior held its stop 15-23 cm off the block: explored at
    # its own size, the object's coverage is its reconstruction's alone.
    planner, recon = _planner(scale), _estimate(0.1 * scale)
    contacts = _ball(0.1 * scale, 2)
    prior = _ball(1.3 * scale)
    assert planner.coverage(recon, prior, contacts).prior_dhd > scale
    own = dataclasses.replace(planner.context, own_size=True)
    coverage = Planner(own, None, planner.state).coverage(recon, prior, contacts)
    assert coverage.prior_open is None
    assert coverage.prior_dhd == 0.0
    assert coverage.value == pytest.approx(coverage.dhd)


@pytest.mark.parametrize("carve", [0.0, 0.1])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_miss_refutes_where_the_estimate_closes_at_its_box_as_far_as_the_carve(scale,
                                                                                  carve):
    # A disc 0.5 above a ball closes the estimate at its box (the grid ends there): one
    # probe missed down through its middle refutes it as far as the carve reaches, the
    # ball's own surface as far as the contact spacing, as before.
    planner, ball, disc, recon = _capped(scale, carve)
    reachable = planner.coverage(recon, ball, ball[ball[:, 2] < 0]).reachable
    off_axis = np.hypot(disc[:, 0], disc[:, 1])
    assert reachable[:len(ball)].all()
    assert not reachable[len(ball):][off_axis < 0.05 * scale].any()
    assert reachable[len(ball):][off_axis > 0.11 * scale].all()
    between = (off_axis > 0.06 * scale) & (off_axis < 0.09 * scale)
    assert reachable[len(ball):][between].all() == (carve == 0)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_cap_within_eps_of_a_contact_is_refuted_as_the_fit_is(scale):
    # Near a contact a cap can be the object going on past its box: a miss refutes it
    # only within the contact spacing there, as the carve keeps within eps of a contact.
    planner, ball, disc, recon = _capped(scale, 0.1)
    contact = np.array([[0.15, 0.0, 1.5]]) * scale
    reachable = planner.coverage(recon, ball, np.vstack([ball[ball[:, 2] < 0], contact]))
    reachable = reachable.reachable[len(ball):]
    off_axis = np.hypot(disc[:, 0], disc[:, 1])
    between = (off_axis > 0.06 * scale) & (off_axis < 0.09 * scale)
    near = np.linalg.norm(disc - contact, axis=1) < 0.1 * scale
    assert (between & near).any() and (between & ~near).any()
    assert reachable[between & near].all() and not reachable[between & ~near].any()


def _capped(scale, carve):
    """A planner, a ball, a disc 0.5 above it that closes the estimate at its box, the
    estimate of both, and one probe missed down through the disc's middle."""
    planner = _planner(scale, carve)
    ball = _ball(scale)
    side = np.linspace(-0.3, 0.3, 25) * scale
    disc = np.stack(np.meshgrid(side, side, [1.5 * scale]), axis=-1).reshape(-1, 3)
    recon = _estimate(scale)
    recon.vertices = np.vstack([ball, disc])
    recon.closure = np.r_[np.zeros(len(ball), bool), np.ones(len(disc), bool)]
    planner.state.free_space = np.linspace([0, 0, 3.0], [0, 0, 1.5], 31) * scale
    return planner, ball, disc, recon


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_detached_part_no_contact_supports_is_left_out_after_three_misses(scale):
    from tactile_viz.engine.session.refuted import missed_parts

    ball, blob = trimesh.creation.icosphere(2, scale), trimesh.creation.icosphere(2, scale)
    blob.apply_translation([10 * scale, 0, 0])
    vertices = np.vstack([ball.vertices, blob.vertices])
    faces = np.vstack([ball.faces, blob.faces + len(ball.vertices)])
    contacts = ball.vertices[::7]
    on_blob, on_ball = blob.vertices[:3], ball.vertices[:3]
    parts = functools.partial(missed_parts, vertices, faces, contacts, reach=0.5 * scale)
    assert not parts(on_blob[:2], misses=3).any()
    refuted = parts(on_blob, misses=3)
    assert refuted[len(ball.vertices):].all() and not refuted[:len(ball.vertices)].any()
    assert not parts(on_ball, misses=3).any()  # a part a contact supports stays
    assert not parts(on_blob, misses=0).any()
    # A target given up far from every vertex counts for no part.
    assert not parts(on_blob + [0, 0, 5 * scale], misses=3).any()


def _box_model(scale, tmp_path):
    from tactile_viz.engine import ObjectModel
    from tactile_viz.engine.io.cache import ArrayCache

    box = trimesh.creation.box((2.0 * scale, scale, scale))
    return ObjectModel.from_arrays(box.vertices, box.faces, "box", cache=ArrayCache(tmp_path),
                                   longest_side=None)


def _turned(axis, angle=np.pi / 2):
    return trimesh.transformations.rotation_matrix(angle, axis)[:3, :3]


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_part_its_poses_place_apart_is_not_asked_to_be_covered(scale, tmp_path):
    # A 2 x 1 x 1 box prior whose two heaviest particles differ by a quarter turn: about
    # its long axis they place it alike and all of it is a prediction to cover; about the
    # vertical its ends lie apart, and only its middle is.
    from tactile_viz.engine.belief.particles import Particles

    model = _box_model(scale, tmp_path)
    planner = _planner(scale)
    vertices = np.asarray(trimesh.creation.box((2.0 * scale, scale, scale)).subdivide()
                          .subdivide().vertices)
    contacts = np.array([[0.0, 0.0, 0.5 * scale]])
    recon = _estimate(0.5 * scale)
    pose = np.eye(3), np.zeros(3)
    for axis, ends_open in (([1, 0, 0], True), ([0, 0, 1], False)):
        particles = Particles(np.zeros(2, int), np.stack([np.eye(3), _turned(axis)]),
                              np.zeros((2, 3)), np.log([0.6, 0.4]))
        planner.filter = types.SimpleNamespace(particles=particles, class_names=["box"])
        coverage = planner.coverage(recon, vertices, contacts, model, pose)
        ends = np.abs(vertices[:, 0]) > 0.9 * scale
        assert coverage.prior_open[ends].all() == ends_open
        assert coverage.prior_open[np.abs(vertices[:, 0]) < 0.2 * scale].any()
        # With one pose (the paper's) the whole prior is asked for.
        planner.p = dataclasses.replace(planner.p, cover_prior_poses=1)
        assert planner.coverage(recon, vertices, contacts, model, pose).prior_open[ends].all()
        planner.p = dataclasses.replace(planner.p, cover_prior_poses=8)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_averaged_over_poses_keeps_what_they_place_alike(scale, tmp_path):
    # A box prior's SDF averaged over its poses (cover_prior_poses): turned within
    # itself (about its long axis) it is the box; turned about the vertical its ends,
    # placed apart, lie outside.
    from tactile_viz.engine.belief.particles import Particles
    from tactile_viz.engine.session.fields import MixedSDF, PosedSDF, prior_poses

    model = _box_model(scale, tmp_path)
    points = np.array([[0.5 * scale, 0.0, 0.5 * scale], [scale, 0.0, 0.0],
                       [0.0, 2.0 * scale, 0.0]])
    own = PosedSDF(model, np.eye(3), np.zeros(3))(points)
    quarter = {axis: trimesh.transformations.rotation_matrix(np.pi / 2, axis)[:3, :3]
               for axis in ((1, 0, 0), (0, 0, 1))}
    alike = MixedSDF(model, np.stack([np.eye(3), quarter[(1, 0, 0)]]), np.zeros((2, 3)),
                     [3.0, 1.0])
    np.testing.assert_allclose(alike(points)[0], own[0], atol=0.02 * scale)
    apart = MixedSDF(model, np.stack([np.eye(3), quarter[(0, 0, 1)]]), np.zeros((2, 3)),
                     [1.0, 1.0])
    values, gradients = apart(points)
    assert values[1] > 0.2 * scale  # the box's end: outside the turned box by half its size
    assert abs(values[0]) < 0.02 * scale and gradients.shape == (3, 3)
    # The poses: the given one in the place of the class's heaviest particle, then the
    # next heaviest by weight; other classes' particles are left out.
    particles = Particles(np.array([0, 1, 0, 0]), np.stack([np.eye(3)] * 4),
                          np.arange(12.0).reshape(4, 3), np.log([0.1, 0.5, 0.3, 0.1]))
    given = quarter[(0, 0, 1)], np.full(3, -1.0)
    rotations, translations, weights = prior_poses(particles, 0, *given, 2)
    np.testing.assert_allclose(rotations[0], given[0])
    np.testing.assert_allclose(translations, [[-1.0, -1.0, -1.0], [0.0, 1.0, 2.0]])
    np.testing.assert_allclose(weights, [1.0, 1.0 / 3.0])
    for count, particles_given in ((1, particles), (8, None)):
        rotations, translations, weights = prior_poses(particles_given, 0, *given, count)
        assert len(weights) == 1 and np.allclose(translations, given[1])
