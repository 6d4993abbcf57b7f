"""A novel object's prior cover (``cover_prior``, beyond the paper): the part of the MAP
prior that the stop still asks to touch, on its own (a planner with no session)."""

import dataclasses
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.scene import FREE
from tactile_viz.engine.session.context import StepContext
from tactile_viz.engine.session.planner import Planner
from tactile_viz.engine.session.state import ExplorationState


def _ball(radius, subdivisions=3):
    return trimesh.creation.icosphere(subdivisions, radius).vertices


def _planner(scale):
    """A planner with what its coverage reads: parameters in scene units, the exploration
    state and the scene (the paper's free space); no filter."""
    p = session_preset("recommended")
    p = dataclasses.replace(p, eps=0.1 * scale, contact_spacing=0.05 * scale,
                            gpis_carve_radius=0.1 * scale)
    return Planner(StepContext(p, scale, scale, scene=FREE), None, ExplorationState())


def _estimate(radius):
    """A reconstruction whose surface is a ball of ``radius`` about the origin."""
    vertices = _ball(radius)
    fit = types.SimpleNamespace(mean_value=lambda q: np.linalg.norm(q, axis=1) - radius)
    return types.SimpleNamespace(vertices=vertices, empty=False, fit=fit)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_missed_probes_refute_the_prior_where_they_passed(scale):
    # The prior stands 0.3 off the object: no contact comes within eps of it; missed
    # probes through it refute it where they passed, and only there.
    planner, recon = _planner(scale), _estimate(scale)
    contacts = _ball(scale, 2)
    prior = _ball(1.3 * scale)
    assert planner.coverage(recon, prior, contacts).prior_dhd > 0.25 * scale
    directions = prior / np.linalg.norm(prior, axis=1, keepdims=True)
    upper = directions[:, 2] >= 0  # probes missed through the upper half only
    way = np.concatenate([d * scale * np.linspace(1.0, 2.0, 21)[:, None]
                          for d in directions[upper]])
    planner.state.free_space = way
    coverage = planner.coverage(recon, prior, contacts)
    assert coverage.prior_open is not None
    assert not coverage.prior_open[upper].any()
    assert coverage.prior_open[directions[:, 2] < -0.2].all()
    assert coverage.prior_dhd > 0.25 * scale  # the lower half is still open


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_refuted_everywhere_has_nothing_left_to_cover(scale):
    # Probes missed through all of the prior: none of it is left to touch, and the stop
    # does not wait for it (a 2 mm fork's held prior, refuted everywhere, held its stop
    # 28 mm off for 80 touches). The estimate's own DHD keeps every vertex then.
    planner, recon = _planner(scale), _estimate(scale)
    contacts = _ball(scale, 2)
    prior = _ball(1.3 * scale)
    directions = prior / np.linalg.norm(prior, axis=1, keepdims=True)
    planner.state.free_space = np.concatenate(
        [d * scale * np.linspace(1.0, 2.0, 21)[:, None] for d in directions])
    coverage = planner.coverage(recon, prior, contacts)
    assert not coverage.prior_open.any() and coverage.prior_dhd == 0.0
    assert coverage.reachable.all()  # every estimate vertex lies near a refuted point


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_prior_many_times_the_objects_size_is_not_covered(scale):
    # A 2 cm block's 25 cm knife prior held its stop 15-23 cm off the block: explored at
    # its own size, the object's coverage is its reconstruction's alone.
    planner, recon = _planner(scale), _estimate(0.1 * scale)
    contacts = _ball(0.1 * scale, 2)
    prior = _ball(1.3 * scale)
    assert planner.coverage(recon, prior, contacts).prior_dhd > scale
    own = dataclasses.replace(planner.context, own_size=True)
    coverage = Planner(own, None, planner.state).coverage(recon, prior, contacts)
    assert coverage.prior_open is None
    assert coverage.prior_dhd == 0.0
    assert coverage.value == pytest.approx(coverage.dhd)
