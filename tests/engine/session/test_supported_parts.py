"""A stopping novel session's surface keeps only the parts a contact supports: the mask
of :func:`supported_parts` and :meth:`Reconstruction.restricted` on their own."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.session.estimate import supported_parts
from tactile_viz.engine.session.snapshot import Reconstruction


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
