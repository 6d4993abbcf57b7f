"""The frontier of a novel estimate (beyond the paper) on its own: a bookkeeper with no
session follows a frontier touch only onto ground nothing predicted."""

import dataclasses
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.bookkeeping import Bookkeeper
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
