"""Contacts measured to the nearest surface facing their way: thin walls do not fold the
noise, a face turned away does not explain a contact, and nested twins are told apart."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import ObjectModel, PriorLibrary
from tactile_viz.engine.belief.decision import decide
from tactile_viz.engine.belief.oriented import OrientedSurface, normal_weight
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.belief.particles import Particles
from tactile_viz.engine.belief.pose_refinement import refine_poses
from tactile_viz.engine.params import FilterParams

WALL = 0.002  # a 2 mm plate, 10 cm square, its top face at z = 1 mm


@pytest.fixture(scope="module")
def plate():
    return trimesh.creation.box(extents=(0.1, 0.1, WALL))


def _up(count):
    return np.tile([0.0, 0.0, 1.0], (count, 1))


def test_noise_through_a_thin_wall_is_not_folded(plate):
    """Touches of the top face pushed up to 1.5 mm into a 2 mm plate: the nearest surface
    (the bottom face, past the middle) would halve them; matched to the face turned their
    way they are the offsets themselves."""
    offsets = np.linspace(-0.0015, 0.0015, 13)
    points = np.column_stack([np.zeros(13), np.linspace(-0.03, 0.03, 13), WALL / 2 + offsets])
    surface = OrientedSurface(plate, normal_weight(0.002, 2.0))
    residuals, matched = surface.residuals(points, _up(13))
    np.testing.assert_allclose(residuals, offsets, atol=1e-4)
    np.testing.assert_allclose(matched, _up(13))
    nearest = np.abs(trimesh.proximity.signed_distance(plate, points))
    assert nearest[offsets < 0].max() < 0.0011  # what the nearest face leaves of 1.5 mm


def test_a_face_turned_away_does_not_explain_a_contact(plate):
    """A touch on the top face whose normal points down lies on no face that faces its
    way nearer than the bottom face, a wall's thickness off."""
    surface = OrientedSurface(plate, normal_weight(0.002, 2.0))
    residuals, matched = surface.residuals(np.array([[0.0, 0.0, WALL / 2]]), -_up(1))
    np.testing.assert_allclose(np.abs(residuals), WALL, atol=1e-9)
    np.testing.assert_allclose(matched, -_up(1))


def test_a_tangent_plane_counts_only_near_its_sample(plate):
    """A touch 5 cm beyond the plate's edge, in the plane of its top face: the top face's
    tangent plane passes through it, but the plate does not."""
    surface = OrientedSurface(plate, normal_weight(0.002, 2.0))
    residuals, _ = surface.residuals(np.array([[0.1, 0.0, WALL / 2]]), _up(1))
    assert abs(residuals[0]) > 0.04


def test_huge_normal_noise_leaves_the_nearest_point(plate):
    """With normals worth nothing the match is the nearest sample, whichever way it
    faces: a 1.5 mm push into the plate is measured to the bottom face."""
    surface = OrientedSurface(plate, normal_weight(0.002, 1e6))
    residuals, _ = surface.residuals(np.array([[0.0, 0.0, WALL / 2 - 0.0015]]), _up(1))
    assert abs(residuals[0]) < 0.0006


def _tube(outer, inner, height):
    return trimesh.creation.annulus(r_min=inner, r_max=outer, height=height, sections=96)


@pytest.fixture(scope="module")
def nested(tmp_path_factory):
    """Two tubes 10% apart in size, walls 10% of the radius: the smaller one's outside is
    the larger one's inside."""
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    large = _tube(1.0, 0.9, 2.0)
    small = _tube(0.9, 0.81, 1.8)
    return PriorLibrary([ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
                         for m, name in ((large, "large"), (small, "small"))])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_smaller_of_nested_tubes_is_told_from_the_larger(nested, seed):
    """Noisy touches of the small tube's outside: the large tube's inner wall lies where
    they do, but faces the other way; the decision's fit gives the small tube the
    posterior."""
    rng = np.random.default_rng(seed)
    angles = rng.uniform(0, 2 * np.pi, 40)
    normals = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(40)])
    heights = rng.uniform(-0.7, 0.7, 40)
    points = 0.9 * normals + np.column_stack([np.zeros((40, 2)), heights])
    points += rng.normal(0.0, 0.03, points.shape)
    chance = _fit_posterior(nested, points, normals, noise=0.03, same_mode=0.1)
    assert chance["small"] > 0.99 and chance["large"] < 0.01


def _fit_posterior(library, points, normals, noise, same_mode):
    """The decision's fit posterior of each class of a two-class library, both weighed at
    the identity: ``{name: probability}``."""
    pf = ParticleFilter(library, FilterParams(), rng=0)
    pf.contact_positions, pf.contact_normals = points, normals
    pf.particles = Particles(np.array([0, 1]), np.repeat(np.eye(3)[None], 2, axis=0),
                             np.zeros((2, 3)), np.log([0.5, 0.5]))
    decision = decide(pf, pf._record(0), 0.99, floor=noise, same_mode=same_mode,
                      normal_noise_deg=2.0)
    chance = {name: 0.0 for name in library.names}
    for h in decision.hypotheses:
        chance[library.names[h.class_index]] += h.probability
    return chance


def test_refinement_on_a_thin_plate_finds_the_face_the_touches_face(plate, tmp_path):
    """Touches of the top face and a start 1.5 mm high, the touches inside the plate
    nearer its bottom face, which faces away from them: on the grid alone the plate
    stays up; with the faces turned their way it sinks to them."""
    from tactile_viz.engine.belief.oriented import oriented_evaluator
    from tactile_viz.engine.io.cache import ArrayCache

    model = ObjectModel.from_arrays(plate.vertices, plate.faces, "plate",
                                    cache=ArrayCache(tmp_path))
    pf = ParticleFilter(PriorLibrary([model]), FilterParams(), rng=0)
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-0.04, 0.04, (30, 2)), np.full(30, WALL / 2)])
    start = np.array([[0.0, 0.0, 0.0015]])
    heights = {}
    for name, oriented in (("grid", None),
                           ("oriented", oriented_evaluator(pf.bank, pf.models, 0.001, 2.0))):
        _, translations, _ = refine_poses(pf.bank.evaluate, [0], np.eye(3)[None], start,
                                          points, normals=_up(30), oriented=oriented)
        heights[name] = translations[0, 2]
    assert abs(heights["oriented"]) < 2e-4  # along the plate it is free
    assert heights["grid"] > 0.001  # held by the bottom face


def test_a_bank_keeps_the_samples_of_a_bounded_number_of_classes():
    """Classes weighed once in a long session of a large library: the least recently
    used samples are dropped, and a class sampled again gives the same residuals."""
    from types import SimpleNamespace

    from tactile_viz.engine.belief import oriented

    models = [SimpleNamespace(mesh=trimesh.creation.box(extents=(1.0, 1.0, 0.1 + 0.01 * k)))
              for k in range(oriented._KEEP + 4)]
    evaluate = oriented.OrientedEvaluator(models, 0.05)
    points, normals = np.array([[0.1, 0.2, 0.3]]), np.array([[0.0, 0.0, 1.0]])
    first, _ = evaluate([0], points, normals)
    for k in range(len(models)):
        evaluate([k], points, normals)
    assert len(evaluate.cache) == oriented._KEEP
    again, _ = evaluate([0], points, normals)
    np.testing.assert_allclose(again, first)


def test_a_class_is_sampled_once_for_every_weight():
    """The weight follows the MAP's size from touch to touch: a class asked at another
    weight builds a tree on the samples it has, and its residuals are those of a surface
    sampled afresh at that weight."""
    from types import SimpleNamespace

    from tactile_viz.engine.belief import oriented

    models = [SimpleNamespace(mesh=trimesh.creation.box(extents=(1.0, 0.6, 0.2)))]
    samples = {}
    points = np.array([[0.1, 0.2, 0.12], [0.45, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    for weight in (0.01, 0.05, 0.2):
        evaluate = oriented.OrientedEvaluator(models, weight, samples=samples)
        got, _ = evaluate([0, 0], points, normals)
        fresh, _ = oriented.OrientedSurface(models[0].mesh, weight).residuals(points, normals)
        np.testing.assert_array_equal(got, fresh)
        assert len(evaluate.cache) == 1
    assert len(samples) == 1


def test_oriented_residuals_without_normals_are_refused(plate):
    """A caller that asks for oriented residuals must give the normals they need."""
    from tactile_viz.engine.belief.oriented import OrientedEvaluator

    with pytest.raises(ValueError, match="normals"):
        refine_poses(lambda c, x: (np.zeros(x.shape[:2]), np.zeros(x.shape)), [0],
                     np.eye(3)[None], np.zeros((1, 3)), np.zeros((3, 3)),
                     oriented=OrientedEvaluator([], 1.0))


ROD, BLADE = 0.0035, 0.004  # a 7 mm pencil and a knife's 4 mm blade, both 18 cm long


@pytest.fixture(scope="module")
def rod_and_blade(tmp_path_factory):
    """A round rod and a flat blade that a few noisy touches of the rod fit alike."""
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    rod = trimesh.creation.cylinder(radius=ROD, height=0.18, sections=48)
    blade = trimesh.creation.box(extents=(BLADE, 0.02, 0.18))
    return PriorLibrary([ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
                         for m, name in ((rod, "rod"), (blade, "blade"))])


def _touches_of_the_rod(rng, count, noise, normal_noise_deg):
    angles = rng.uniform(0, 2 * np.pi, count)
    normals = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(count)])
    points = ROD * normals + np.column_stack([np.zeros((count, 2)),
                                              rng.uniform(-0.08, 0.08, count)])
    tilt = rng.normal(0.0, np.radians(normal_noise_deg), (count, 3))
    normals = normals + tilt - np.einsum("ij,ij->i", tilt, normals)[:, None] * normals
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return points + rng.normal(0.0, noise, points.shape), normals


def test_normals_cost_the_blade_and_not_the_rod(rod_and_blade):
    """Exact touches all round the rod: their normals fit the rod's surface and cost the
    blade's (which faces only four ways) up to the cap, never beyond it."""
    from tactile_viz.engine.belief.oriented import NORMAL_CAP, OrientedEvaluator, turned_cost

    points, normals = _touches_of_the_rod(np.random.default_rng(0), 30, 0.0, 0.0)
    evaluate = OrientedEvaluator(list(rod_and_blade), normal_weight(0.002, 2.0))
    cost = turned_cost(evaluate, np.array([0, 1]), np.repeat(np.eye(3)[None], 2, axis=0),
                       np.zeros((2, 3)), points, normals, 2.0)
    assert cost[0] < 0.5 * 30  # within one std of the samples' roughness a contact
    assert cost[1] > 5 * cost[0]
    assert cost[1] <= 0.5 * NORMAL_CAP**2 * 30


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_noisy_rod_is_decided_a_rod_not_a_blade(rod_and_blade, seed):
    """A dozen touches of a 7 mm rod at 2 mm / 2 degrees: a 4 mm blade turned to them
    fits their positions about as well, but not their normals, which turn all the way
    round."""
    points, normals = _touches_of_the_rod(np.random.default_rng(seed), 12, 0.002, 2.0)
    chance = _fit_posterior(rod_and_blade, points, normals, noise=0.002, same_mode=0.004)
    assert chance["rod"] > 0.99


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_under_noise_the_filter_takes_the_rod_not_the_blade(rod_and_blade, seed):
    """The filter's discrimination between classes weighs the normals under noise too:
    the rod is its MAP, and the novelty test that follows is taken on the rod."""
    from tactile_viz.engine.belief.discrimination import discriminate

    points, normals = _touches_of_the_rod(np.random.default_rng(seed), 12, 0.002, 2.0)
    pf = ParticleFilter(rod_and_blade, FilterParams(position_noise=0.002), rng=0)
    pf.contact_positions, pf.contact_normals = points, normals
    particles = Particles(np.array([1, 0]), np.repeat(np.eye(3)[None], 2, axis=0),
                          np.zeros((2, 3)), np.log([0.6, 0.4]))
    particles, chosen, _ = discriminate(pf, particles)
    assert rod_and_blade.names[particles.classes[chosen]] == "rod"


def _refinements(monkeypatch):
    """Record each refine_poses call of the discrimination: (iterations, start rotations)."""
    from tactile_viz.engine.belief import discrimination, pose_refinement

    calls, refine = [], discrimination.refine_poses

    def spy(evaluate, classes, rotations, translations, contacts, noncontacts, iterations,
            **options):
        calls.append((iterations, np.array(rotations)))
        return refine(evaluate, classes, rotations, translations, contacts, noncontacts,
                      iterations, **options)

    monkeypatch.setattr(discrimination, "refine_poses", spy)
    monkeypatch.setattr(pose_refinement, "refine_poses", spy)
    return calls


def _rod_filter(library, noise, warm_iterations=3):
    points, normals = _touches_of_the_rod(np.random.default_rng(3), 13, noise, 2.0)
    pf = ParticleFilter(library, FilterParams(position_noise=noise,
                                              refine_warm_iterations=warm_iterations), rng=0)
    pf.contact_positions, pf.contact_normals = points[:12], normals[:12]
    turned = Rotation.from_rotvec([0.0, 0.0, 0.3]).as_matrix()
    particles = Particles(np.array([1, 0]), np.stack([turned, np.eye(3)]), np.zeros((2, 3)),
                          np.log([0.6, 0.4]))
    return pf, particles, points, normals


def test_under_noise_the_next_refinement_starts_where_the_last_ended(rod_and_blade,
                                                                    monkeypatch):
    """A contender refined at the last step starts from that pose and takes
    ``refine_warm_iterations`` steps; the rod stays the MAP."""
    from tactile_viz.engine.belief.discrimination import discriminate

    pf, particles, points, normals = _rod_filter(rod_and_blade, 0.002)
    calls = _refinements(monkeypatch)
    particles, chosen, refined = discriminate(pf, particles)
    assert [c[0] for c in calls] == [pf.params.refine_iterations]
    assert len(refined) == 2 and {key[0] for key in refined} == {0, 1}
    pf.contact_positions, pf.contact_normals = points, normals  # one contact more
    calls.clear()
    particles, chosen, again = discriminate(pf, particles, refined)
    assert [c[0] for c in calls] == [pf.params.refine_warm_iterations]
    starts = np.stack([refined[key][0] for key in again])  # in the candidates' order
    np.testing.assert_array_equal(calls[0][1], starts)
    assert rod_and_blade.names[particles.classes[chosen]] == "rod"


@pytest.mark.parametrize("noise, warm_iterations", [(0.0, 3), (0.002, 0)])
def test_without_noise_or_warm_steps_every_refinement_starts_afresh(rod_and_blade, monkeypatch,
                                                                   noise, warm_iterations):
    from tactile_viz.engine.belief.discrimination import discriminate

    pf, particles, _, _ = _rod_filter(rod_and_blade, noise, warm_iterations)
    _, chosen, refined = discriminate(pf, particles)
    calls = _refinements(monkeypatch)
    _, chosen_again, _ = discriminate(pf, particles, refined)
    assert [c[0] for c in calls] == [pf.params.refine_iterations]
    np.testing.assert_array_equal(calls[0][1][:2], particles.rotations[[0, 1]])
    assert chosen_again == chosen


def test_points_in_several_poses_frames_agree_with_one_pose_at_a_time():
    """The batched world-to-object transform of the refinement and the normals' cost is
    the single-pose one, pose by pose; without translations it only turns."""
    from scipy.spatial.transform import Rotation

    from tactile_viz.engine.transforms import (
        inverse_transform_points,
        inverse_transform_points_batch,
    )

    rng = np.random.default_rng(5)
    rotations = Rotation.random(4, random_state=5).as_matrix()
    translations, points = rng.normal(size=(4, 3)), rng.normal(size=(7, 3))
    batch = inverse_transform_points_batch(points, rotations, translations)
    for k in range(4):
        np.testing.assert_allclose(batch[k], inverse_transform_points(
            points, rotations[k], translations[k]))
        np.testing.assert_allclose(inverse_transform_points_batch(points, rotations)[k],
                                   points @ rotations[k])
