"""The table and the tip in the decision's pose fits: a missed tip's centre stays a radius
off the surface (``clearance``), and a hypothesis rests on its stable face (support.py)."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import ObjectModel, PriorLibrary, Session
from tactile_viz.engine.belief.pose_refinement import refine_poses, surface_uncertainty
from tactile_viz.engine.belief.support import (
    Support,
    resting_faces,
    support_residuals,
    table_support,
)
from tactile_viz.engine.io.cache import ArrayCache
from tactile_viz.engine.scene import Scene

UP = np.array([0.0, 0.0, 1.0])


@pytest.fixture
def box(tmp_path):
    mesh = trimesh.creation.box(extents=(6.0, 3.0, 2.0))
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, "box",
                                   cache=ArrayCache(tmp_path), longest_side=6.0)


def _filter(box, scene):
    return Session(PriorLibrary([box]), scene=scene).filter


def _resting(box):
    """The box flat on the table at z = 0: its 2-unit side up."""
    return np.eye(3), np.array([0.0, 0.0, 1.0])


def test_a_box_rests_on_its_faces_and_its_resting_vertices_lie_on_the_table(box):
    hull, downs, faces = resting_faces(box)
    assert len(downs) >= 2 and all(len(face) == 4 for face in faces)
    support = Support(UP, np.zeros(3), (box,))
    rotation, translation = _resting(box)
    values, jacobian = support_residuals(support, np.array([0]), rotation[None],
                                         translation[None], np.zeros(3))
    np.testing.assert_allclose(values, 0.0, atol=1e-9)
    # Raised by h, every resting vertex is h high, and d/dz of each is 1.
    values, jacobian = support_residuals(support, np.array([0]), rotation[None],
                                         (translation + [0, 0, 0.3])[None], np.zeros(3))
    np.testing.assert_allclose(values[0], 0.3, atol=1e-9)
    np.testing.assert_allclose(jacobian[0, :, 5], 1.0)


def test_a_hypothesis_far_from_every_stable_pose_rests_on_its_lowest_vertex(box):
    support = Support(UP, np.zeros(3), (box,))
    tilted = Rotation.from_rotvec([0.6, 0.5, 0.0]).as_matrix()
    points, mask = support.points(np.array([0]), tilted[None])
    assert mask.sum() == 1
    lowest = (box.mesh.vertices @ tilted.T)[:, 2].min()
    assert (points[0, 0] @ tilted.T)[2] == pytest.approx(lowest)


def test_the_table_pins_the_tilt_that_contacts_on_the_top_leave_loose(box):
    """Two contacts on the top face leave the turn about the line through them loose;
    resting on the table pins it, and the height."""
    rotation, translation = _resting(box)
    top = np.array([[-2.0, 0.0, 2.0], [2.0, 0.0, 2.0]])
    pf = _filter(box, Scene.on_table(0.0))
    off = Rotation.from_rotvec([0.05, 0.0, 0.0]).as_matrix()  # about the line, 2.9 deg
    tilts = []
    for support in (None, table_support(pf)):
        refined, moved, _ = refine_poses(pf.bank.evaluate, np.array([0]), off[None],
                                         (translation + [0, 0, 0.2])[None], top,
                                         iterations=20, support=support)
        tilts.append(np.degrees(np.arccos(np.clip(refined[0][2, 2], -1, 1))))
    assert tilts[0] > 1.0 and tilts[1] < 0.05
    assert moved[0, 2] == pytest.approx(1.0, abs=1e-3)
    spread = [surface_uncertainty(pf.bank.evaluate, 0, rotation, translation, top,
                                  pf.bank.points[0], pf.bank.normals[0], 0.01,
                                  support=support).max()
              for support in (None, table_support(pf))]
    assert spread[1] < spread[0]


def test_a_missed_tip_refutes_a_pose_that_leaves_it_less_than_a_radius_clear(box):
    """A tip centre 0.05 above the top face missed: a box posed there fits with a point
    probe, and misfits once the tip has a radius of 0.1."""
    rotation, translation = _resting(box)
    pf = _filter(box, Scene.on_table(0.0, tip_radius=0.1))
    contacts = np.array([[2.0, 1.0, 2.0], [-2.0, 1.0, 2.0], [0.0, -1.0, 2.0],
                         [3.0, 0.0, 1.0]])
    missed = np.array([[0.0, 0.0, 2.05]])
    cost = [refine_poses(pf.bank.evaluate, np.array([0]), rotation[None], translation[None],
                         contacts, missed, iterations=0, clearance=clearance)[2][0]
            for clearance in (0.0, 0.1)]
    assert cost[0] == pytest.approx(0.0, abs=1e-6)
    assert cost[1] == pytest.approx(0.05**2, rel=0.2)


def test_without_a_table_there_is_no_support(box):
    assert table_support(_filter(box, Scene())) is None


def test_on_a_table_the_first_known_targets_stay_near_the_contacts(tmp_path):
    """Aimed far from a first touch, a probe lands on the table beside an object lying
    flat: until three contacts the known targets lie near them."""
    from tactile_viz.engine import Contact
    from tactile_viz.engine.session.planner import FIRST_SEARCH

    mesh = trimesh.creation.box(extents=(6.0, 3.0, 2.0))
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, 0.2)
    box = ObjectModel.from_arrays(vertices, faces, "fine box", cache=ArrayCache(tmp_path),
                                  longest_side=6.0)
    session = Session(PriorLibrary([box]), seed=0, scene=Scene.on_table(0.0, 60.0, 0.05))
    touch = np.array([1.0, 0.5, 2.0])
    snapshot = session.observe([Contact(touch, [0.0, 0.0, 1.0])])
    assert not snapshot.novel and session.state.target is not None
    distance = np.linalg.norm(session.state.target.position - touch)
    assert distance <= FIRST_SEARCH * session._unit + 1e-9
    free = Session(PriorLibrary([box]), seed=0)
    free.observe([Contact(touch, [0.0, 0.0, 1.0])])
    assert np.linalg.norm(free.state.target.position - touch) > FIRST_SEARCH * free._unit


def test_a_far_pose_mode_that_fits_too_holds_the_decision_and_is_aimed_at(box):
    """`_open_modes`: another mode of the lead's class within the fit's limit and farther
    than the tolerance is open; a near one, or one that misfits, is not."""
    from tactile_viz.engine.belief.decision import Decision, Hypothesis, _open_modes

    pf = _filter(box, Scene())
    lead = Hypothesis(0, np.eye(3), np.zeros(3), 1.0, 0.999)
    far = Hypothesis(0, np.eye(3), np.array([0.0, 0.0, 1.0]), 2.0, 1e-6)
    near = Hypothesis(0, np.eye(3), np.array([0.0, 0.0, 0.01]), 2.0, 1e-6)
    misfit = Hypothesis(0, np.eye(3), np.array([0.0, 0.0, 1.0]), 50.0, 1e-9)
    modes = _open_modes(pf.bank, (lead, far, near, misfit), lead, limit=10.0, tolerance=0.3)
    assert modes == (far,)
    assert _open_modes(pf.bank, (lead, far), lead, 10.0, np.inf) == ()
    decision = Decision(False, 0.999, (lead, far, near), True, None, 0.1, modes)
    assert far in decision.rivals and near not in decision.rivals


def _points_one_by_one(support, classes, rotations):
    """Support.points as it was written first: one hypothesis at a time."""
    cos_limit = np.cos(np.radians(20.0))
    rows = []
    for c, rotation in zip(classes, rotations):
        hull, downs, faces = resting_faces(support.models[int(c)])
        down = -(rotation.T @ support.up)
        dots = downs @ down
        best = int(np.argmax(dots))
        rows.append(hull[faces[best]] if dots[best] >= cos_limit
                    else hull[[int(np.argmax(hull @ down))]])
    width = max(max(len(face) for face in resting_faces(support.models[int(c)])[2])
                for c in np.unique(classes))
    points = np.stack([np.vstack([row, np.repeat(row[:1], width - len(row), 0)])
                       for row in rows])
    mask = np.arange(width)[None] < np.array([len(row) for row in rows])[:, None]
    return points, mask


def test_the_resting_vertices_of_many_hypotheses_are_each_ones_own(box, tmp_path):
    """Hypotheses of several classes at once, near and far from their stable poses, get
    the vertices each would get alone, padded alike."""
    wedge = trimesh.creation.cone(radius=2.0, height=3.0, sections=5)
    cone = ObjectModel.from_arrays(wedge.vertices, wedge.faces, "cone",
                                   cache=ArrayCache(tmp_path), longest_side=4.0)
    support = Support(UP, np.zeros(3), (box, cone))
    rng = np.random.default_rng(8)
    near = Rotation.from_rotvec(rng.normal(scale=0.1, size=(20, 3))).as_matrix()
    rotations = np.concatenate([Rotation.random(40, random_state=9).as_matrix(), near])
    classes = rng.integers(0, 2, len(rotations))
    points, mask = support.points(classes, rotations)
    expected, expected_mask = _points_one_by_one(support, classes, rotations)
    np.testing.assert_array_equal(points, expected)
    np.testing.assert_array_equal(mask, expected_mask)
    assert mask.sum(axis=1).max() > 1 and mask.sum(axis=1).min() == 1
