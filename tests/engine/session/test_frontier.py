"""The frontier of a novel estimate (beyond the paper) on its own: a bookkeeper with no
session follows a frontier touch only onto ground nothing predicted."""

import dataclasses
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.bookkeeping import (
    UNHELD_AFTER,
    Bookkeeper,
    sign_kept,
    tangent_points,
    unheld_contacts,
)
from tactile_viz.engine.session.context import StepContext
from tactile_viz.engine.session.state import ExplorationState


def _keeper(scale, contacts, estimate):
    """What following the frontier reads: parameters in scene units, the contacts, the
    exploration state after a frontier target with the whole estimate the last step
    planned on (its snapshot reports only supported parts: here none, to show it is not
    read)."""
    p = session_preset("recommended")
    p = dataclasses.replace(p, eps=0.2 * scale, contact_spacing=0.1 * scale)
    return Bookkeeper(StepContext(p, scale, scale),
                      types.SimpleNamespace(contact_positions=contacts),
                      ExplorationState(frontier_target=True, estimate_vertices=estimate),
                      snapshots=[types.SimpleNamespace(gpis_vertices=None)])


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_frontier_follows_only_ground_the_estimate_did_not_predict(scale):
    # Contacts on the upper half of a ball; a frontier touch on its lower half lies far
    # from every contact. An estimate that holds the whole ball predicted it: nothing to
    # follow (the checks test it). One that holds the upper half only did not: the
    # frontier grows from the touch, as it does with no estimate at all.
    ball = trimesh.creation.icosphere(3, scale).vertices
    contacts = ball[ball[:, 2] > 0.3 * scale][::4]
    touch = Contact(np.array([0.0, 0.0, -scale]), np.array([0.0, 0.0, -1.0]))
    for estimate, grows in ((ball, False), (ball[ball[:, 2] > 0], True), (None, True)):
        keeper = _keeper(scale, contacts, estimate)
        keeper._follow_frontier(touch)
        assert bool(keeper.state.frontier) == grows
        queued = np.reshape([position for position, _ in keeper.state.frontier], (-1, 3))
        np.testing.assert_allclose(np.linalg.norm(queued - touch.position, axis=1),
                                   0.2 * scale)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_contact_the_estimate_leaves_off_queues_places_about_it_once(scale):
    # Contacts on a ball, the first 0.3 out (a thin part's lone touch the fit smoothed
    # away): only that one queues targets, contact_spacing (0.1) about it across its
    # normal, once ten contacts came after it, and only once; without follow_unheld, none.
    mesh = trimesh.creation.icosphere(3, scale)
    recon = _estimate(mesh.vertices, mesh.faces, scale)
    contacts = np.vstack([[[0.0, 0.0, 1.3 * scale]], mesh.vertices[::40]])
    assert len(contacts) > UNHELD_AFTER + 1
    normals = contacts / np.linalg.norm(contacts, axis=1, keepdims=True)
    for follow in (True, False):
        keeper = _keeper(scale, contacts[:UNHELD_AFTER], None)
        keeper.p = dataclasses.replace(keeper.p, follow_unheld=follow)
        keeper.filter.contact_normals = normals
        keeper.follow_unheld(recon)  # too soon
        assert not keeper.state.frontier
        keeper.filter.contact_positions = contacts
        keeper.follow_unheld(recon)
        queued = np.reshape([position for position, _ in keeper.state.frontier], (-1, 3))
        if not follow:
            assert len(queued) == 0
            continue
        assert keeper.state.followed == [0]
        assert len(queued) == 4
        np.testing.assert_allclose(np.linalg.norm(queued - contacts[0], axis=1), 0.1 * scale)
        np.testing.assert_allclose(queued[:, 2], 1.3 * scale)
        keeper.follow_unheld(recon)
        assert len(keeper.state.frontier) == 4
        keeper.follow_unheld(_estimate(mesh.vertices, mesh.faces[:0], scale))  # no surface
        assert len(keeper.state.frontier) == 4


def _estimate(vertices, faces, radius):
    """An estimate whose fit is a ball's signed distance (what ``follow_unheld`` reads)."""
    fit = types.SimpleNamespace(
        mean_value=lambda points: np.linalg.norm(points, axis=1) - radius)
    return types.SimpleNamespace(vertices=vertices, faces=faces, fit=fit)


def test_a_contact_on_a_face_between_far_vertices_is_held():
    # Beside a coarse estimate's vertices but on its faces: held (the surface is measured,
    # not its vertices); one off every face is not, nor any without a surface.
    mesh = trimesh.creation.box((2.0, 2.0, 2.0))
    contacts = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.5]])
    np.testing.assert_array_equal(unheld_contacts(contacts, mesh.vertices, mesh.faces, 0.2),
                                  [False, True])
    np.testing.assert_array_equal(unheld_contacts(contacts, mesh.vertices, mesh.faces[:0], 0.2),
                                  [True, True])


def test_a_contact_the_fit_holds_between_the_grids_samples_is_held():
    # A thin part between a coarse grid's samples has no triangles, yet its fit passes
    # through the contact: held; a contact where the fit is far from zero is not.
    mesh = trimesh.creation.box((2.0, 2.0, 2.0))
    contacts = np.array([[0.0, 0.0, 1.5], [0.0, 0.0, 2.0]])

    def tine(points):  # a slab 0.02 thick through the first contact, 0.49 off the second
        return np.abs(points[:, 2] - 1.5) - 0.01

    np.testing.assert_array_equal(
        unheld_contacts(contacts, mesh.vertices, mesh.faces, 0.2, tine), [False, True])


def test_tangent_points_lie_across_the_normal():
    normal = np.array([0.6, 0.0, 0.8])
    points = tangent_points(np.ones(3), normal, 0.5)
    np.testing.assert_allclose((points - 1.0) @ normal, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points - 1.0, axis=1), 0.5)
    np.testing.assert_allclose(points.mean(axis=0), np.ones(3))


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_sign_is_kept_only_where_no_zero_level_comes_within_reach(scale):
    # A ball's signed distance: 0.3 outside it, the sign holds to 0.2 and not to 0.4
    # (nor on the surface itself, where it is zero), whatever the direction.
    def ball(points):
        return np.linalg.norm(points, axis=1) - scale

    directions = trimesh.creation.icosphere(1).vertices
    points = 1.3 * scale * directions
    assert sign_kept(ball, points, 0.2 * scale).all()
    assert not sign_kept(ball, points, 0.4 * scale).any()
    assert not sign_kept(ball, scale * directions, 0.2 * scale).any()
