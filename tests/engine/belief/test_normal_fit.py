"""The decision's pose fits weigh the contacts' normals (beyond the paper)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tactile_viz.engine.belief.decision import Hypothesis, _open_modes
from tactile_viz.engine.belief.pose_refinement import (
    normal_residuals,
    normal_weights,
    refine_poses,
    surface_uncertainty,
)

HALF = np.array([1.0, 1.0, 1.0])  # a cube of side 2


def box(classes, local):
    """A cube's exact signed distance and outward gradient, ``local (k, m, 3)``."""
    q = np.abs(local) - HALF
    outside = np.maximum(q, 0.0)
    length = np.linalg.norm(outside, axis=2)
    inside = np.minimum(q.max(axis=2), 0.0)
    axis = np.eye(3)[np.argmax(q, axis=2)] * np.sign(local)
    gradient = np.where(length[..., None] > 0,
                        outside * np.sign(local) / np.maximum(length, 1e-300)[..., None], axis)
    return length + inside, gradient


def ball(classes, local):
    """A unit ball's signed distance and gradient."""
    length = np.linalg.norm(local, axis=2)
    return length - 1.0, local / np.maximum(length, 1e-300)[..., None]


def _box_touches(rng, count, noise, normal_noise_deg):
    """Touches of the cube's five faces but its bottom, exact points moved by ``noise`` and
    normals tilted by ``normal_noise_deg`` (std)."""
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    which = rng.integers(len(faces), size=count)
    normal = faces[which]
    points = rng.uniform(-0.9, 0.9, (count, 3))
    points = np.where(normal != 0, normal, points)
    tilt = Rotation.from_rotvec(rng.normal(0, np.radians(normal_noise_deg), (count, 3)))
    return points + rng.normal(0, noise, (count, 3)), tilt.apply(normal)


def _turn_deg(rotation):
    return np.degrees(Rotation.from_matrix(rotation).magnitude())


def test_a_normal_weighs_as_much_as_the_surface_is_flat_about_it():
    scale, sigma = 0.05, np.radians(2.0)
    on_face = np.array([[[0.2, -0.3, 1.0], [1.0, 0.1, 0.4]]])
    flat = normal_weights(box, np.array([0]), on_face, scale, sigma)
    np.testing.assert_allclose(flat, scale / sigma, rtol=1e-6)
    on_ball = Rotation.random(20, random_state=1).apply([1.0, 0.0, 0.0])[None]
    curved = normal_weights(ball, np.array([0]), on_ball, scale, sigma)
    # The normal turns by s / rho across the noise: rho = 1.
    np.testing.assert_allclose(curved, scale / np.hypot(sigma, scale), rtol=0.02)
    near_edge = np.array([[[1.0, 0.99, 0.0]]])  # the gradient turns 90 degrees within s
    assert normal_weights(box, np.array([0]), near_edge, scale, sigma)[0, 0] < 0.1 * scale / sigma


def test_the_normal_rows_are_the_derivative_of_a_small_turn():
    rng = np.random.default_rng(3)
    posed = Rotation.random(6, random_state=4).apply([0.0, 0.0, 1.0])[None]
    measured = Rotation.from_rotvec(rng.normal(0, 0.05, (6, 3))).apply(posed[0])
    weight = rng.uniform(0.5, 2.0, (1, 6))
    values, jacobian = normal_residuals(posed, measured, weight)
    turn = rng.normal(0, 1e-6, 3)
    moved, _ = normal_residuals(Rotation.from_rotvec(turn).apply(posed[0])[None], measured,
                                weight)
    np.testing.assert_allclose((moved - values)[0], jacobian[0] @ np.r_[turn, np.zeros(3)],
                               rtol=1e-4, atol=1e-10)
    # A shift moves no normal; a normal turned past the gate says nothing.
    assert not jacobian[..., 3:].any()
    away, rows = normal_residuals(-measured[None], measured, weight)
    assert not away.any() and not rows.any()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_normals_pin_the_turn_of_a_small_box_under_large_noise(seed):
    """Positions with noise 10% of the size leave a cube's turn several degrees loose;
    their 2-degree normals pin it within about a degree."""
    rng = np.random.default_rng(seed)
    points, normals = _box_touches(rng, 60, 0.2, 2.0)
    start = Rotation.from_rotvec(np.radians([4.0, -3.0, 5.0])).as_matrix()[None]
    options = dict(iterations=30, normals=normals)
    positions, _, _ = refine_poses(box, np.array([0]), start, np.zeros((1, 3)), points,
                                   **options)
    both, _, _ = refine_poses(box, np.array([0]), start, np.zeros((1, 3)), points,
                              normal_noise=(0.2, np.radians(2.0)), **options)
    assert _turn_deg(both[0]) < 1.5
    assert _turn_deg(both[0]) < _turn_deg(positions[0])


def test_the_misfit_counts_the_positions_not_the_normals():
    rng = np.random.default_rng(5)
    points, normals = _box_touches(rng, 30, 0.05, 5.0)
    rotations, translations, misfit = refine_poses(
        box, np.array([0]), np.eye(3)[None], np.zeros((1, 3)), points, normals=normals,
        normal_noise=(0.05, np.radians(5.0)))
    local = (points - translations[0]) @ rotations[0]
    values, _ = box(None, local[None])
    np.testing.assert_allclose(misfit, np.square(values).sum(), rtol=1e-9)


def test_normals_narrow_the_uncertainty_of_the_turn():
    rng = np.random.default_rng(6)
    points, normals = _box_touches(rng, 40, 0.2, 2.0)
    surface = np.array([[1.0, 0.9, 0.9], [-0.9, 1.0, -0.9], [0.9, -0.9, 1.0]])
    directions = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    args = (box, 0, np.eye(3), np.zeros(3), points, surface, directions, 0.2**2)
    alone = surface_uncertainty(*args)
    both = surface_uncertainty(*args, measured=normals, normal_noise=(0.2, np.radians(2.0)))
    assert np.all(both < alone) and np.all(both > 0)


class _Bank:
    """A bank of one cube for :func:`_open_modes` (its surface points and distance)."""

    points = [np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0],
                        [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]] * 3)]
    evaluate = staticmethod(box)


def test_a_mode_whose_normals_misfit_is_no_open_mode():
    """A mode that fits the positions within the noise stays open unless its normals cost
    it more than the confidence's margin over the lead's."""
    lead = Hypothesis(0, np.eye(3), np.zeros(3), 1.0, 0.9, turned=2.0)
    tilted = Rotation.from_rotvec([0.0, 0.3, 0.0]).as_matrix()
    near = Hypothesis(0, tilted, np.zeros(3), 1.2, 0.1, turned=4.0)
    far = Hypothesis(0, tilted, np.zeros(3), 1.2, 0.0, turned=60.0)
    margin = np.log(100.0)
    assert _open_modes(_Bank(), (lead, near), lead, 2.0, 0.01, margin) == (near,)
    assert _open_modes(_Bank(), (lead, far), lead, 2.0, 0.01, margin) == ()
    assert _open_modes(_Bank(), (lead, far), lead, 2.0, 0.01) == (far,)  # positions alone


@pytest.fixture(scope="module")
def box_library(tmp_path_factory):
    """A box 6 x 3 x 2 and a cylinder, as a library."""
    import trimesh

    from tactile_viz.engine import ObjectModel, PriorLibrary
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    meshes = ((trimesh.creation.box(extents=(6, 3, 2)), "box"),
              (trimesh.creation.cylinder(radius=1.5, height=6, sections=48), "cylinder"))
    return PriorLibrary([ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
                         for m, name in meshes])


def test_the_lead_is_posed_by_its_normals_only_when_asked(box_library):
    """A lead 4 degrees off, refitted to noisy touches (5% of the box's length) with their
    normals, turns back within a degree; without ``fit_noise`` it is returned as it is."""
    from tactile_viz.engine.belief.oriented import oriented_evaluator
    from tactile_viz.engine.belief.particle_filter import ParticleFilter
    from tactile_viz.engine.belief.posed import posed_by_normals
    from tactile_viz.engine.explore.observations import Contact
    from tactile_viz.engine.params import FilterParams

    rng = np.random.default_rng(7)
    mesh = box_library["box"].mesh
    points, faces = mesh.sample(60, return_index=True, seed=7)
    tilt = Rotation.from_rotvec(rng.normal(0, np.radians(2.0), (60, 3)))
    pf = ParticleFilter(box_library, FilterParams(), rng=0)
    for point, normal in zip(points + rng.normal(0, 0.3, points.shape),
                             tilt.apply(mesh.face_normals[faces])):
        pf.update(Contact(point, normal))
    start = Rotation.from_rotvec(np.radians([3.0, -2.0, 2.0])).as_matrix()
    lead = Hypothesis(0, start, np.zeros(3), 1.0, 1.0)
    alone = oriented_evaluator(pf.bank, pf.models, 0.3, 2.0)
    assert posed_by_normals(pf, lead, np.zeros((0, 3)), alone) is lead
    both = oriented_evaluator(pf.bank, pf.models, 0.3, 2.0, in_fits=True)
    posed = posed_by_normals(pf, lead, np.zeros((0, 3)), both)
    assert _turn_deg(posed.rotation) < 1.0
    local = (pf.contact_positions - posed.translation) @ posed.rotation
    values, _ = pf.bank.evaluate(np.array([0]), local[None])
    # The positions' misfit (a few contacts are measured to the face turned their way),
    # not the joint cost, which the normals would more than double.
    np.testing.assert_allclose(posed.misfit, np.square(values).sum(), rtol=0.02)
