"""A learned shape's own errors: how far its learning contacts lie off it."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.session.learning import learned_model_from_surface, own_errors


def _box_faces_touched():
    """A turned, moved 2 x 3 x 4 box and a contact at the middle of each side, with the
    side's outward normal (world frame)."""
    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    outward = np.vstack([np.eye(3), -np.eye(3)])
    contacts = outward * [1.0, 1.5, 2.0]
    moved = trimesh.transformations.rotation_matrix(0.7, [1, 1, 0])
    moved[:3, 3] = [5.0, -2.0, 1.0]
    box.apply_transform(moved)
    return box, contacts @ moved[:3, :3].T + moved[:3, 3], outward @ moved[:3, :3].T


def test_contacts_on_the_surface_have_no_error_and_turned_normals_their_chord():
    box, contacts, normals = _box_faces_touched()
    np.testing.assert_allclose(own_errors(box.vertices, box.faces, contacts, normals),
                               [0.0, 0.0], atol=1e-9)
    # Each normal turned a right angle (to the next side's): a chord of sqrt(2).
    turned = np.roll(normals, 1, axis=0)
    assert own_errors(box.vertices, box.faces, contacts, turned)[1] == pytest.approx(
        np.sqrt(2), rel=1e-9)
    assert own_errors(box.vertices, box.faces, np.empty((0, 3))) == (0.0, 0.0)


def test_the_shape_error_is_the_held_out_and_the_surfaces_beyond_the_noise():
    """Contacts 0.3 out along their normals: the surface misses them by 0.3, in
    quadrature with the fit's held-out errors, and by nothing a sensor of that noise
    explains."""
    box, contacts, normals = _box_faces_touched()
    out = contacts + 0.3 * normals
    assert own_errors(box.vertices, box.faces, out)[0] == pytest.approx(0.3, rel=1e-9)
    assert own_errors(box.vertices, box.faces, out, held_out=[0.4] * 3)[0] == pytest.approx(
        0.5, rel=1e-9)
    assert own_errors(box.vertices, box.faces, out, noise=0.3)[0] == pytest.approx(
        0.0, abs=1e-6)
    assert own_errors(box.vertices, box.faces, np.empty((0, 3)),
                      held_out=[0.4])[0] == pytest.approx(0.4)


def test_a_learned_shape_carries_its_contacts_errors():
    box, contacts, normals = _box_faces_touched()
    flipped = normals.copy()
    flipped[0] *= -1  # one of six reversed: a chord of 2
    model = learned_model_from_surface(box.vertices, box.faces, "learned_box",
                                       contacts=contacts + 0.1 * normals, normals=flipped,
                                       held_out=[0.2])
    assert model.normal_error == pytest.approx(np.sqrt(4.0 / 6.0), rel=1e-9)
    assert model.shape_error == pytest.approx(np.hypot(0.1, 0.2), rel=1e-9)
    alone = learned_model_from_surface(box.vertices, box.faces, "box")
    assert (alone.shape_error, alone.normal_error) == (0.0, 0.0)


def test_the_shape_error_takes_in_the_fits_spread_on_its_surface():
    """Touches met again land anywhere on a learned surface, not only at its contacts: the
    fit's posterior spread there joins the shape error in quadrature."""
    box, contacts, normals = _box_faces_touched()
    out = contacts + 0.3 * normals
    assert own_errors(box.vertices, box.faces, out, surface=0.4)[0] == pytest.approx(
        0.5, rel=1e-9)
    assert own_errors(box.vertices, box.faces, np.empty((0, 3)),
                      surface=0.4)[0] == pytest.approx(0.4)


def test_a_fits_spread_on_its_surface_is_its_posterior_std_there():
    from tactile_viz.engine.session.learning import surface_spread

    class Fit:
        def variance(self, points):
            return np.full(len(points), 0.04)

    vertices = np.random.default_rng(0).normal(size=(5000, 3))
    assert surface_spread(Fit(), vertices) == pytest.approx(0.2)
    assert surface_spread(Fit(), np.empty((0, 3))) == 0.0

    class Varied:  # the variance x^2 at N(0, 1) points: an RMS std of 1, a mean std of 0.8
        def variance(self, points):
            return points[:, 0] ** 2

    assert surface_spread(Varied(), vertices) == pytest.approx(1.0, rel=0.05)
