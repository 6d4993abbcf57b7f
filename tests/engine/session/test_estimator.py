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


@pytest.mark.parametrize("scale", [1e-2, 1.0, 1e2])
def test_thin_walls_raise_the_final_resolution_up_to_its_cap(scale, tmp_path):
    # Both faces of a plate touched: the final surface takes final_wall_cells cells across
    # it, at most WALL_MOST times final_resolution; a ball's contacts raise nothing.
    from dataclasses import replace

    from tactile_viz.engine.session.final import WALL_MOST, WALL_VERTICES

    rng = np.random.default_rng(0)
    xy = rng.uniform(-scale, scale, size=(40, 2))
    side = np.where(np.arange(40) % 2 == 0, 1.0, -1.0)
    box = (np.full(3, -scale), np.full(3, scale))  # longest side 2 scale
    for thickness, wanted in ((0.01, None), (0.05, 80), (0.2, 64)):
        contacts = np.column_stack([xy, side * thickness * scale / 2])
        normals = np.column_stack([np.zeros((40, 2)), side])
        estimator, _ = _estimator(scale, contacts, normals, tmp_path)
        base = estimator.p.final_resolution
        assert base == 64
        got = estimator.wall_resolution(box, base, contacts)
        assert got == (int(WALL_MOST * base) if wanted is None else wanted)
        # A surface of many vertices at the base resolution is refined less (its cost).
        assert estimator.wall_resolution(box, base, contacts, vertices=WALL_VERTICES) == base
        budget = estimator.wall_resolution(box, base, contacts, vertices=WALL_VERTICES / 4)
        assert budget == min(2 * base, got)
        # Cells no finer than the sensor's position noise (the noise would be drawn).
        estimator.sensor_noise = (0.025 * scale, 0.0)
        assert estimator.wall_resolution(box, base, contacts) == max(base, min(got, 80))
        estimator.p = replace(estimator.p, final_wall_cells=0.0)
        assert estimator.wall_resolution(box, base, contacts) == base
    directions = trimesh.creation.icosphere(1).vertices
    estimator, _ = _estimator(scale, scale * directions, directions, tmp_path)
    assert estimator.wall_resolution(box, 64, scale * directions) == 64


@pytest.mark.parametrize("scale", [1e-2, 1.0, 1e2])
def test_a_final_surface_small_in_its_box_is_extracted_again_in_its_own(scale, tmp_path):
    # A ball a tenth of the box across (the MAP prior's box, with a far corner): its
    # surface is extracted again in its own box, on cells as many times finer, nearer the
    # ball; a surface that fills its box is left as it is.
    directions = trimesh.creation.icosphere(2).vertices
    radius = 0.1 * scale
    contacts, normals = radius * directions, directions
    estimator, _ = _estimator(scale, contacts, normals, tmp_path)
    ball = trimesh.creation.icosphere(3, radius)
    from tactile_viz.engine.io.cache import ArrayCache

    model = ObjectModel.from_arrays(ball.vertices, ball.faces, "ball",
                                    cache=ArrayCache(tmp_path), longest_side=None)
    far = np.vstack([ball.vertices, [[-scale, -scale, -scale], [scale, scale, scale]]])
    recon, _ = estimator.reconstruct(model, np.eye(3), np.zeros(3), far, {})
    final = estimator._surface(recon.fit, recon.bounds, 32)[0]
    own = estimator._own_box(final)
    box = np.ptp(np.asarray(final.bounds), axis=0).max()
    own_box = np.ptp(np.asarray(own.bounds), axis=0).max()
    assert own.resolution == final.resolution and own_box < 0.5 * box
    assert (own.vertices.min(axis=0) >= np.asarray(own.bounds[0]) - 1e-9 * scale).all()

    def error(surface):
        return np.median(np.abs(np.linalg.norm(surface.vertices, axis=1) - radius))

    assert error(own) < error(final)
    assert estimator._own_box(own) is own  # it fills its own box


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_own_box_is_a_small_surfaces_box_with_two_cells_of_margin(scale):
    from tactile_viz.engine.session.final import OWN_BOX_CELLS, own_box

    bounds = (np.zeros(3), np.full(3, 10.0 * scale))
    cell = 10.0 * scale / 20
    small = np.array([[1.0, 1.0, 1.0], [3.0, 2.0, 2.5]]) * scale
    low, high = own_box(small, bounds, 20)
    np.testing.assert_allclose(low, small[0] - OWN_BOX_CELLS * cell)
    np.testing.assert_allclose(high, small[1] + OWN_BOX_CELLS * cell)
    # Clipped to the box; a surface over half the box across, or none, keeps it.
    corner = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]) * scale
    np.testing.assert_allclose(own_box(corner, bounds, 20)[0], np.zeros(3))
    assert own_box(np.array([[1.0, 1, 1], [6.5, 1, 1]]) * scale, bounds, 20) is None
    assert own_box(np.zeros((0, 3)), bounds, 20) is None


def test_no_own_box_without_the_final_surfaces_refinements(tmp_path):
    # final_wall_cells 0 (the paper preset) turns the own box off with the thin walls.
    from dataclasses import replace

    directions = trimesh.creation.icosphere(2).vertices
    estimator, _ = _estimator(1.0, 0.1 * directions, directions, tmp_path)
    estimator.p = replace(estimator.p, final_wall_cells=0.0)
    ball = trimesh.creation.icosphere(2, 0.1)
    from tactile_viz.engine.session.snapshot import Reconstruction

    final = Reconstruction(np.asarray(ball.vertices), np.asarray(ball.faces), None,
                           np.zeros(0), fit=None, resolution=32,
                           bounds=(np.full(3, -1.0), np.full(3, 1.0)))
    assert estimator._own_box(final) is final


def _box_touched(scale, tmp_path, hold):
    """An estimator (``gpis_prior_hold`` as ``hold``) whose contacts lie on its
    ``2 x 1 x 1`` box prior at the identity; that pose and a quarter turn about z moved by
    its size along x."""
    from dataclasses import replace

    box = trimesh.creation.box((2.0 * scale, scale, scale))
    points, faces = trimesh.sample.sample_surface_even(box, 60, seed=0)
    estimator, model = _estimator(scale, points, box.face_normals[faces], tmp_path)
    estimator.p = replace(estimator.p, gpis_agnostic=False,
                          gpis_prior_hold="always" if hold else "never")
    quarter = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])[:3, :3]
    return estimator, model, (np.eye(3), np.zeros(3)), (quarter, np.array([scale, 0, 0]))


@pytest.mark.parametrize("scale", [1e-2, 1.0, 1e2])
def test_a_held_prior_pose_gives_way_only_to_a_pose_the_contacts_favour(scale, tmp_path,
                                                                        monkeypatch):
    from dataclasses import replace

    from tactile_viz.engine.session import estimate
    from tactile_viz.engine.transforms import transform_points

    def prior_in_force(estimator, model, held, particle):
        estimator.state.gpis = replace(estimator.state.gpis, pose=(model.name, *held))
        vertices = transform_points(model.mesh.vertices, *particle)
        _, estimator.state.gpis = estimator.reconstruct(model, *particle, vertices, {})
        pose, map_vertices = estimator.prior_pose(model, particle, vertices)
        np.testing.assert_allclose(estimator.state.gpis.pose[1], pose[0], atol=1e-12)
        np.testing.assert_allclose(
            map_vertices, transform_points(model.mesh.vertices, *pose), atol=1e-9 * scale)
        return pose

    # The contacts favour the pose they lie on by about 2 nats here: within the margin a
    # turned pose held stays in force (the hysteresis), beyond it gives way.
    estimator, model, fitting, turned = _box_touched(scale, tmp_path, hold=True)
    np.testing.assert_allclose(prior_in_force(estimator, model, turned, fitting)[0],
                               turned[0], atol=1e-12)
    monkeypatch.setattr(estimate, "AGNOSTIC_MARGIN", 1.0)
    monkeypatch.setattr(estimate, "AGNOSTIC_SHARE", 0.0)
    for hold in (True, False):
        estimator, model, fitting, turned = _box_touched(scale, tmp_path, hold)
        for held, particle in ((fitting, turned), (turned, fitting)):
            # Held, the pose the contacts lie on stays in force against a turned MAP
            # particle, and a turned pose held gives way to the particle on them; without
            # the hold the prior is the MAP particle's.
            expected = fitting if hold else particle
            np.testing.assert_allclose(prior_in_force(estimator, model, held, particle)[0],
                                       expected[0], atol=1e-12)
