"""The estimator on its own (a part built from a context, the contacts and an exploration
state; no session): the GPIS reconstruction of a novel object from its MAP prior, at any
scale, and what the reported surface drops."""

import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import ObjectModel
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.context import StepContext
from tactile_viz.engine.session.estimate import Estimator
from tactile_viz.engine.session.lengths import session_lengths
from tactile_viz.engine.session.state import ExplorationState, GpisState


def _estimator(scale, contacts, normals, tmp_path):
    """An estimator of a ball of radius ``scale`` touched at ``contacts``, with a box of
    ``2 x 1 x 1`` its size as the MAP prior (a sixth of the box's longest side is the
    size unit)."""
    from tactile_viz.engine.io.cache import ArrayCache

    box = trimesh.creation.box((2.0 * scale, scale, scale))
    model = ObjectModel.from_arrays(box.vertices, box.faces, "box", cache=ArrayCache(tmp_path),
                                    longest_side=None)
    unit = model.size_unit
    p = session_lengths(session_preset("recommended", gpis_resolution=24), unit)
    belief = types.SimpleNamespace(contact_positions=contacts, contact_normals=normals,
                                   noncontact_positions=np.zeros((0, 3)))
    state = ExplorationState(gpis=GpisState(scale=p.gpis_scale))
    estimator = Estimator(StepContext(p, unit, unit), belief, state, np.random.default_rng(0))
    return estimator, model


@pytest.mark.parametrize("scale", [1e-2, 1.0, 1e2])
def test_an_estimator_reconstructs_a_ball_from_a_box_prior(scale, tmp_path):
    directions = trimesh.creation.icosphere(1).vertices
    contacts, normals = scale * directions, directions
    estimator, model = _estimator(scale, contacts, normals, tmp_path)
    pose = np.eye(3), np.zeros(3)
    map_vertices = model.mesh.vertices
    timings = {}
    before = estimator.state.copy()
    recon, gpis = estimator.reconstruct(model, *pose, map_vertices, timings)
    assert not recon.empty and {"gpis", "surface"} <= set(timings)
    radii = np.linalg.norm(recon.vertices, axis=1)
    # The surface passes through the contacts: a ball within a fifth of its radius.
    assert np.median(np.abs(radii - scale)) < 0.2 * scale
    assert (recon.candidate_variance >= 0).all()
    # The fit's scale and factor are what the next step goes on from: returned, and the
    # state is left as it was.
    assert gpis.scale == recon.fit.scale and gpis is not before.gpis
    assert estimator.state.gpis is before.gpis
    # Reported, the surface keeps only parts a contact comes within eps of.
    reported = estimator.reported(recon, contacts, {})
    assert len(reported.vertices) <= len(recon.vertices)
