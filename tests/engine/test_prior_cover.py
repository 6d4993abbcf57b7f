"""A novel object's prior cover (``cover_prior``, beyond the paper): the part of the MAP
prior that the stop still asks to touch, on its own (a planner with no session)."""

import dataclasses
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.scene import FREE
from tactile_viz.engine.session.fields import buried
from tactile_viz.engine.session.planner import Planner
from tactile_viz.engine.session.state import ExplorationState


def _ball(radius, subdivisions=3):
    return trimesh.creation.icosphere(subdivisions, radius).vertices


class _Planner(Planner):
    """The planner's coverage with what it reads: parameters in scene units, the
    exploration state and the scene."""

    def __init__(self, scale):
        p = session_preset("recommended")
        self._p = dataclasses.replace(p, eps=0.1 * scale, contact_spacing=0.05 * scale,
                                      gpis_carve_radius=0.1 * scale)
        self.state = ExplorationState()
        self.scene = FREE


def _estimate(radius):
    """A reconstruction whose surface is a ball of ``radius`` about the origin."""
    vertices = _ball(radius)
    fit = types.SimpleNamespace(mean_value=lambda q: np.linalg.norm(q, axis=1) - radius)
    return types.SimpleNamespace(vertices=vertices, empty=False, fit=fit)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_buried_is_what_lies_deeper_than_the_depth_and_far_from_every_contact(scale):
    def estimate(q):
        return np.linalg.norm(q, axis=1) - scale

    contacts = np.array([[scale, 0, 0]])
    vertices = scale * np.array([[0.0, 0, 0],     # deep inside, far from the contact
                                 [0.95, 0, 0],    # inside, near the contact
                                 [0, 0.95, 0],    # inside, not deeper than the depth
                                 [0, 1.5, 0],     # outside
                                 [0, 0, -0.5]])   # deep inside, not asked about
    mask = np.array([True, True, True, True, False])
    got = buried(vertices, mask, estimate, contacts, 0.1 * scale)
    np.testing.assert_array_equal(got, [True, False, False, False, False])
    assert not buried(vertices, mask, estimate, np.zeros((0, 3)), 0.1 * scale).any()
    assert not buried(vertices, np.zeros(5, bool), estimate, contacts, 0.1 * scale).any()


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_inside_the_estimate_does_not_hold_the_stop(scale):
    # A small ball's prior within a larger object: no probe can touch it.
    planner, recon = _Planner(scale), _estimate(scale)
    contacts = _ball(scale)
    prior = _ball(0.5 * scale)
    coverage = planner._coverage(recon, prior, contacts)
    assert coverage.prior_dhd == 0.0
    assert coverage.value == pytest.approx(coverage.dhd)
    assert coverage.dhd <= 0.1 * scale
    # Not deeper than eps: still to be covered.
    shallow = planner._coverage(recon, _ball(0.95 * scale), contacts[:3])
    assert shallow.prior_dhd > 0.1 * scale


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_refuted_everywhere_by_missed_probes_is_covered(scale):
    # The prior stands 0.3 off the object: no contact comes within eps of it; missed
    # probes through it refute it where they passed, and all of it once they passed
    # everywhere (it does not come back whole).
    planner, recon = _Planner(scale), _estimate(scale)
    contacts = _ball(scale, 2)
    prior = _ball(1.3 * scale)
    assert planner._coverage(recon, prior, contacts).prior_dhd > 0.25 * scale
    directions = prior / np.linalg.norm(prior, axis=1, keepdims=True)
    upper = directions[:, 2] >= 0  # probes missed through the upper half only
    way = np.concatenate([d * scale * np.linspace(1.0, 2.0, 21)[:, None]
                          for d in directions[upper]])
    planner.state.free_space = way
    coverage = planner._coverage(recon, prior, contacts)
    assert coverage.prior_open is not None
    assert not coverage.prior_open[upper].any()
    assert coverage.prior_open[directions[:, 2] < -0.2].all()
    assert coverage.prior_dhd > 0.25 * scale  # the lower half is still open
    planner.state.free_space = np.concatenate([way, -way])
    assert planner._coverage(recon, prior, contacts).prior_dhd == 0.0
