"""Telling near twins apart: the batched pose refinement and the discrimination step."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import ObjectModel, PriorLibrary
from tactile_viz.engine.belief.discrimination import contenders, discriminate
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.belief.particles import Particles
from tactile_viz.engine.belief.pose_refinement import refine_poses
from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.params import FilterParams
from tactile_viz.engine.presets import preset

HALF = np.array([1.0, 2.0, 3.0])  # half-extents of the test box


def box_sdf(classes, points, scale=1.0):
    """Exact signed distance of an axis-aligned box (half-extents ``HALF * scale``), and
    its gradient by central differences: the ``evaluate`` that :func:`refine_poses` takes."""
    def value(x):
        q = np.abs(x) - HALF * scale
        return (np.linalg.norm(np.maximum(q, 0), axis=-1)
                + np.minimum(q.max(axis=-1), 0))

    step = 1e-6 * scale
    gradients = np.stack([(value(points + step * e) - value(points - step * e)) / (2 * step)
                          for e in np.eye(3)], axis=-1)
    return value(points), gradients


def box_points(rng, count):
    """Points on every face of the box."""
    points = rng.uniform(-HALF, HALF, size=(count, 3))
    axis = np.arange(count) % 3
    points[np.arange(count), axis] = HALF[axis] * rng.choice([-1, 1], size=count)
    return points


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e3])
def test_refinement_recovers_perturbed_poses(rng, scale):
    """From 4 degrees and 2% of the size off, at any size."""
    contacts = box_points(rng, 60) * scale
    turns = Rotation.from_rotvec(rng.normal(scale=np.radians(4), size=(3, 3))).as_matrix()
    shifts = rng.normal(scale=0.1, size=(3, 3)) * scale
    rotations, translations, _ = refine_poses(lambda c, x: box_sdf(c, x, scale),
                                              np.zeros(3, int), turns, shifts, contacts,
                                              iterations=20)
    np.testing.assert_allclose(rotations, np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-5)
    np.testing.assert_allclose(translations / scale, 0, atol=1e-5)


def test_refinement_keeps_a_fitting_pose_and_survives_one_contact(rng):
    contacts = box_points(rng, 30)
    rotations, translations, misfit = refine_poses(box_sdf, [0], np.eye(3)[None], np.zeros((1, 3)),
                                           contacts)
    np.testing.assert_allclose(rotations[0], np.eye(3), atol=1e-9)
    assert misfit[0] < 1e-12
    # One contact constrains one direction: the pose stays finite and on the surface.
    rotations, translations, misfit = refine_poses(box_sdf, [0], np.eye(3)[None], [[0.0, 0.0, 0.2]],
                                           contacts[:1])
    assert np.isfinite(rotations).all() and np.isfinite(translations).all()
    local = (contacts[:1] - translations[0]) @ rotations[0]
    assert abs(box_sdf([0], local[None])[0][0, 0]) < 1e-6


def test_noncontacts_push_only_from_inside(rng):
    contacts = box_points(rng, 40)
    outside = np.array([[0.0, 0.0, 3.5], [0.0, 2.6, 0.0]])
    fitted, _, _ = refine_poses(box_sdf, [0], np.eye(3)[None], np.zeros((1, 3)), contacts, outside)
    np.testing.assert_allclose(fitted[0], np.eye(3), atol=1e-9)
    inside = np.array([[0.0, 0.0, 2.7]])  # the box's top must drop below it: it cannot
    _, moved, _ = refine_poses(box_sdf, [0], np.eye(3)[None], np.zeros((1, 3)),
                            contacts[:3], inside, iterations=20)
    assert box_sdf([0], (inside - moved[0])[None])[0][0, 0] > -0.3


def test_contenders_are_each_heavy_class_heaviest_particle():
    classes = np.array([0, 0, 1, 1, 1, 2, 3])
    weights = np.array([0.10, 0.25, 0.05, 0.30, 0.05, 0.24, 0.01])
    particles = Particles(classes, np.zeros((7, 3, 3)), np.zeros((7, 3)), np.log(weights))
    np.testing.assert_array_equal(contenders(particles, 4, 0.05), [3, 1, 5])
    np.testing.assert_array_equal(contenders(particles, 2, 0.05), [3, 1])
    np.testing.assert_array_equal(contenders(particles, 4, 0.36), [3])


@pytest.fixture(scope="module")
def twins(bundled):
    """mug_1 and a copy stretched by 6% along x about its centre (a shared frame)."""
    mug = bundled["mug_1"]
    stretch = np.array([1.06, 1.0, 1.0])
    wide = ObjectModel("mug_wide", trimesh.Trimesh(mug.mesh.vertices * stretch, mug.mesh.faces,
                                                   process=False), mug.params, mug.cache)
    return PriorLibrary([mug, wide])


def _touched(library, name, count):
    points, face = trimesh.sample.sample_surface_even(library[name].mesh, count, seed=1)
    return points, library[name].mesh.face_normals[face]


@pytest.mark.parametrize("contending", [0, 4])
def test_a_better_fitting_lookalike_joins_and_becomes_the_map(twins, contending):
    """The belief holds only the plain mug, at the pose the truth shares; the touched object
    is the stretched one. The lookalike step brings it in and makes it the MAP; switched
    off, nothing changes."""
    pf = ParticleFilter(twins, FilterParams(contenders=contending), rng=0)
    pf.contact_positions, pf.contact_normals = _touched(twins, "mug_wide", 40)
    only_plain = Particles(np.zeros(3, int), np.repeat(np.eye(3)[None], 3, axis=0),
                           np.array([[0.0, 0, 0], [0.05, 0, 0], [0, 0.05, 0]]),
                           np.log([0.5, 0.3, 0.2]))
    belief, chosen, _ = discriminate(pf, only_plain)
    if not contending:
        assert chosen is None and belief is only_plain
        return
    assert belief.classes[chosen] == 1
    assert np.argmax(belief.log_weights) == chosen
    assert np.exp(belief.log_weights).sum() == pytest.approx(1.0)
    evidence = pf.log_evidence_of(belief)
    assert evidence[chosen] == evidence.max()


def test_the_best_fit_wins_over_the_heavier_twin(twins):
    """Both twins hold mass, the wrong one more: the MAP is the one that fits once refined,
    and the belief itself is left as it was (no lookalike is left to join)."""
    pf = ParticleFilter(twins, FilterParams(), rng=0)
    pf.contact_positions, pf.contact_normals = _touched(twins, "mug_1", 40)
    turn = Rotation.from_rotvec([0.0, 0.0, np.radians(3)]).as_matrix()
    both = Particles(np.array([1, 0]), np.stack([np.eye(3), turn]),
                     np.array([[0.05, 0.0, 0.0], [0.0, 0.1, 0.0]]), np.log([0.7, 0.3]))
    belief, chosen, _ = discriminate(pf, both)
    assert belief is both and chosen == 1


def test_one_class_and_no_better_lookalike_changes_nothing(twins):
    pf = ParticleFilter(twins, FilterParams(), rng=0)
    pf.contact_positions, pf.contact_normals = _touched(twins, "mug_1", 40)
    alone = Particles(np.zeros(2, int), np.repeat(np.eye(3)[None], 2, axis=0),
                      np.zeros((2, 3)), np.log([0.6, 0.4]))
    belief, chosen, _ = discriminate(pf, alone)
    assert chosen is None and belief is alone


def test_the_filter_tells_twins_apart_over_seeds(twins):
    """40 random touches of the stretched mug, six seeds: the MAP is the stretched mug every
    time (measured with the discrimination off: 3 of 6)."""
    wide = twins["mug_wide"]
    for seed in range(6):
        points, faces = trimesh.sample.sample_surface(wide.mesh, 40, seed=seed)
        pf = ParticleFilter(twins, FilterParams(), rng=seed)
        for point, normal in zip(points, wide.mesh.face_normals[faces]):
            state = pf.update(Contact(point, normal))
        assert state.map_class == "mug_wide", seed
        assert state.map_index is not None and not state.novel


def test_the_paper_preset_does_not_discriminate():
    assert preset("paper").contenders == 0 and FilterParams().contenders > 0


def test_trimming_leaves_a_wrong_reading_out(rng):
    contacts = box_points(rng, 40)
    contacts[0] += [0.0, 0.0, 1.5]  # one reading far off the surface
    turn = Rotation.from_rotvec([0.0, np.radians(3), 0.0]).as_matrix()
    plain, shift, _ = refine_poses(box_sdf, [0], turn[None], [[0.05, 0, 0]], contacts,
                                   iterations=20)
    trimmed, trimmed_shift, misfit = refine_poses(box_sdf, [0], turn[None], [[0.05, 0, 0]],
                                                  contacts, iterations=20, trim=0.02)
    np.testing.assert_allclose(trimmed[0], np.eye(3), atol=1e-5)
    np.testing.assert_allclose(trimmed_shift[0], 0, atol=1e-5)
    assert misfit[0] < 1e-9
    assert np.abs(shift[0]).max() > 1e-3  # the untrimmed fit is pulled off
