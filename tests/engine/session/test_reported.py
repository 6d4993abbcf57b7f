"""A novel session's surface keeps only the parts a contact supports and drops what the
misses refute: :mod:`tactile_viz.engine.session.reported` and
:meth:`Reconstruction.restricted` on their own."""

import dataclasses

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.reported import (
    refuted_vertices,
    support_reach,
    supported_parts,
    without_refuted,
)
from tactile_viz.engine.session.snapshot import Reconstruction
from tactile_viz.engine.session.state import ExplorationState
from tactile_viz.engine.shape.mesh_repair import closed_faces


def _two_balls(scale):
    """A ball at the origin and a smaller one 3 radii off, one surface of two parts."""
    body = trimesh.creation.icosphere(2, scale)
    blob = trimesh.creation.icosphere(1, 0.3 * scale)
    blob.apply_translation([3.0 * scale, 0.0, 0.0])
    both = trimesh.util.concatenate([body, blob])
    return np.asarray(both.vertices), np.asarray(both.faces), len(body.vertices)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_only_the_parts_a_contact_comes_near_are_kept(scale):
    vertices, faces, body = _two_balls(scale)
    contacts = vertices[:body][::7] + 0.01 * scale  # touches of the body only
    keep = supported_parts(vertices, faces, contacts, 0.1 * scale)
    assert keep[:body].all() and not keep[body:].any()
    # A contact near the blob supports it too; one nearly within reach does not.
    beside = np.array([[3.3 * scale + 0.09 * scale, 0.0, 0.0]])
    assert supported_parts(vertices, faces, np.vstack([contacts, beside]), 0.1 * scale).all()
    assert not supported_parts(vertices, faces, beside, 0.05 * scale).any()


def _ball_with_void(scale, winding=1):
    """A ball's surface and, 5% of its radius inside it, a void's facing into the void (as
    a fit's level set winds them; ``winding`` -1 turns every face)."""
    outer = trimesh.creation.icosphere(3, scale)
    void = trimesh.creation.icosphere(2, 0.95 * scale)
    void.invert()
    both = trimesh.util.concatenate([outer, void])
    faces = np.asarray(both.faces)
    return np.asarray(both.vertices), faces if winding > 0 else faces[:, ::-1], len(outer.vertices)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("winding", [1, -1])
def test_a_void_inside_the_solid_is_not_supported_by_the_contacts_outside(scale, winding):
    vertices, faces, outer = _ball_with_void(scale, winding)
    contacts = vertices[:outer][::9]
    normals = contacts / np.linalg.norm(contacts, axis=1)[:, None]
    reach = 0.1 * scale  # the void lies within it of the contacts
    assert supported_parts(vertices, faces, contacts, reach).all()
    keep = supported_parts(vertices, faces, contacts, reach, normals)
    assert keep[:outer].all() and not keep[outer:].any()
    # Touched from inside (a cup's inner wall), the same surface is supported.
    inside = vertices[outer:][::9]
    both = supported_parts(vertices, faces, np.vstack([contacts, inside]), reach,
                           np.vstack([normals, -inside / np.linalg.norm(inside, axis=1)[:, None]]))
    assert both.all()


def test_no_contacts_or_no_surface_support_nothing():
    vertices, faces, _ = _two_balls(1.0)
    assert not supported_parts(vertices, faces, np.zeros((0, 3)), 1.0).any()
    assert supported_parts(np.zeros((0, 3)), np.zeros((0, 3), int), vertices, 1.0).shape == (0,)


def test_a_restricted_estimate_keeps_its_faces_and_variance_on_the_kept_part():
    vertices, faces, body = _two_balls(1.0)
    subset = np.array([0, 5, body + 1, body + 2, 40])
    variance = np.arange(len(subset), dtype=float)
    recon = Reconstruction(vertices, faces, subset, variance, fit=None, resolution=32,
                           vertex_variance=np.linspace(0.0, 1.0, len(vertices)))
    keep = np.arange(len(vertices)) < body
    part = recon.restricted(keep)
    np.testing.assert_array_equal(part.vertices, vertices[:body])
    assert part.faces.min() >= 0 and part.faces.max() < body
    assert len(part.faces) == len(trimesh.creation.icosphere(2, 1.0).faces)
    np.testing.assert_array_equal(part.vertices[part.subset], vertices[[0, 5, 40]])
    np.testing.assert_array_equal(part.candidate_variance, [0.0, 1.0, 4.0])
    np.testing.assert_array_equal(part.variance, recon.vertex_variance[:body])


def test_a_restricted_estimate_without_a_variance_sample_has_none():
    vertices, faces, body = _two_balls(1.0)
    recon = Reconstruction(vertices, faces, np.array([body, body + 3]), np.ones(2),
                           fit=None, resolution=32)
    part = recon.restricted(np.arange(len(vertices)) < body)
    assert part.subset is None
    np.testing.assert_array_equal(part.variance, np.zeros(body))


def _ball_with_misses(scale):
    """A ball of radius ``scale`` touched on its lower half, with misses beside its top:
    ``(recon, refuted, contacts)``."""
    ball = trimesh.creation.icosphere(3, scale)
    vertices, faces = np.asarray(ball.vertices), np.asarray(ball.faces)
    contacts = vertices[vertices[:, 2] < -0.2 * scale][::5]
    top = vertices[vertices[:, 2] > 0.8 * scale]
    refuted = top * 1.05  # just outside: the probes passed there and touched nothing
    recon = Reconstruction(vertices, faces, None, np.zeros(0), fit=None, resolution=32)
    return recon, refuted, contacts


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_only_vertices_near_a_miss_and_far_from_every_contact_are_refuted(scale):
    recon, refuted, contacts = _ball_with_misses(scale)
    marked = refuted_vertices(recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale)
    z = recon.vertices[:, 2]
    assert marked.any() and (z[marked] > 0.6 * scale).all()
    assert marked[z > 0.85 * scale].all()
    # A contact within reach of the top covers it; a miss farther than spacing refutes none.
    assert not refuted_vertices(recon.vertices, refuted, np.vstack([contacts, refuted]),
                                0.2 * scale, 0.3 * scale).any()
    assert not refuted_vertices(recon.vertices, refuted + [0, 0, scale], contacts,
                                0.2 * scale, 0.3 * scale).any()


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_cap_at_the_box_is_refuted_as_far_as_the_carve_reaches(scale):
    # The top closes the surface at its box: a miss refutes it within cap_reach there,
    # the rest of the ball within spacing only, as the stop sees it (refuted.open_estimate).
    recon, refuted, contacts = _ball_with_misses(scale)
    z = recon.vertices[:, 2]
    cap = z > 0.3 * scale
    narrow = refuted_vertices(recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale)
    wide = refuted_vertices(recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale,
                            cap, 0.5 * scale)
    assert not (wide & ~narrow & ~cap).any() and (wide & ~narrow & cap).any()
    assert (narrow <= wide).all()
    # No wider than spacing, or no closure: the narrow mask.
    np.testing.assert_array_equal(refuted_vertices(
        recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale, cap, 0.1 * scale), narrow)
    np.testing.assert_array_equal(refuted_vertices(
        recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale, None, 0.5 * scale), narrow)


def test_without_misses_or_vertices_nothing_is_refuted():
    recon, refuted, contacts = _ball_with_misses(1.0)
    assert not refuted_vertices(recon.vertices, np.zeros((0, 3)), contacts, 1.0, 0.1).any()
    assert refuted_vertices(np.zeros((0, 3)), refuted, contacts, 1.0, 0.1).shape == (0,)
    # Without contacts, every vertex near a miss is refuted.
    assert refuted_vertices(recon.vertices, refuted, np.zeros((0, 3)), 0.2, 0.3).any()


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_refuted_part_is_dropped_and_its_hole_closed_on_request(scale):
    recon, refuted, contacts = _ball_with_misses(scale)
    marked = refuted_vertices(recon.vertices, refuted, contacts, 0.2 * scale, 0.3 * scale)
    opened = without_refuted(recon, refuted, contacts, 0.2 * scale, 0.3 * scale)
    closed = without_refuted(recon, refuted, contacts, 0.2 * scale, 0.3 * scale, close=True)
    for part in (opened, closed):
        assert len(part.vertices) <= np.count_nonzero(~marked)
        assert np.array_equal(np.unique(part.faces), np.arange(len(part.vertices)))
        assert part.vertices[:, 2].max() < 0.95 * scale
    assert not trimesh.Trimesh(opened.vertices, opened.faces, process=False).is_watertight
    mesh = trimesh.Trimesh(closed.vertices, closed.faces, process=False)
    assert mesh.is_watertight
    np.testing.assert_array_equal(closed.faces[:len(opened.faces)], opened.faces)
    assert 0.8 * (4 / 3 * np.pi * scale**3) < mesh.volume < 4 / 3 * np.pi * scale**3


def test_nothing_is_dropped_when_every_vertex_is_refuted():
    recon, _, _ = _ball_with_misses(1.0)
    everywhere = recon.vertices * 1.05
    assert without_refuted(recon, everywhere, np.zeros((0, 3)), 0.5, 0.1) is recon


def test_a_closed_surface_stays_as_it_is():
    ball = trimesh.creation.icosphere(2)
    np.testing.assert_array_equal(closed_faces(ball.vertices, ball.faces), ball.faces)
    assert closed_faces(ball.vertices, np.zeros((0, 3), int)) is None


def test_the_refuted_points_are_the_given_up_targets_and_the_free_space():
    state = ExplorationState()
    assert state.refuted.shape == (0, 3)
    state.given_up.append(np.ones(3))
    state.free_space = np.zeros((2, 3))
    np.testing.assert_array_equal(state.refuted, [[1, 1, 1], [0, 0, 0], [0, 0, 0]])


def test_a_surface_pymeshlab_refuses_is_not_closed(monkeypatch):
    import pymeshlab

    def refuse(self, **_):
        raise pymeshlab.PyMeshLabException("Failed to apply filter")

    monkeypatch.setattr(pymeshlab.MeshSet, "meshing_close_holes", refuse)
    recon, refuted, contacts = _ball_with_misses(1.0)
    assert closed_faces(recon.vertices, recon.faces[:-10]) is None
    assert without_refuted(recon, refuted, contacts, 0.2, 0.3, close=True) is recon
    # Given one, the surface is cut instead (the session extracts it again without what
    # the misses refute), and only then.
    cut = []
    assert without_refuted(recon, refuted, contacts, 0.2, 0.3, close=True,
                           cut=lambda r: cut.append(r) or "cut") == "cut"
    assert cut == [recon]
    assert without_refuted(recon, refuted, contacts, 0.2, 0.3,
                           cut=lambda r: cut.append(r) or "cut") is not recon
    assert len(cut) == 1


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("noise", [1e-9, 0.01, 1.0])
def test_a_surface_is_supported_nearer_a_contact_than_eps_where_misses_refute_it(scale,
                                                                                 noise):
    p = dataclasses.replace(session_preset("recommended"), eps=0.6 * scale,
                            contact_spacing=0.3 * scale)
    reach = support_reach(p, noise * scale)
    assert reach == pytest.approx(min(p.eps, max(p.contact_spacing,
                                                 p.target_noise_stds * noise * scale)))
    assert p.contact_spacing <= reach <= p.eps
    assert support_reach(dataclasses.replace(p, final_support_near=False), noise) == p.eps
    assert support_reach(p, 0.0) == p.eps  # noiseless: eps
    # A blob 0.45 units inside a shell of contacts, misses about it: within eps of them,
    # beyond the spacing. Its vertices are refuted only with a reach under 0.45.
    vertices, faces, body = _two_balls(scale)
    centre = np.array([3.0 * scale, 0.0, 0.0])
    contacts = centre + (vertices[body:] - centre) * 0.75 / 0.3
    misses = vertices[body:] + [0.0, 0.1 * scale, 0.0]
    for support, dropped in ((p.eps, False), (reach, reach < 0.45 * scale)):
        refuted = refuted_vertices(vertices, misses, contacts, p.contact_spacing, support)
        assert refuted[body:].any() == dropped
