"""The prior a novel object's exploration holds (``cover_prior_hold``): kept until the
filter's MAP explains the observations better by the margin."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import Contact, PriorLibrary
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session import Session, make_truth
from tactile_viz.engine.session.estimate import held_prior
from tactile_viz.engine.shape.objects import ObjectModel


@pytest.fixture
def touched_box(small_library):
    """A filter over the box and the cylinder, given touches on the box (6 x 3 x 2) at the
    identity pose: its top and its two long sides."""
    library, _ = small_library
    touches = [Contact([x, 0.0, 1.0], [0, 0, 1.0]) for x in (-2.0, 0.0, 2.0)]
    touches += [Contact([x, side * 1.5, 0.0], [0, side, 0.0])
                for x in (-2.0, 2.0) for side in (-1, 1)]
    belief_filter = ParticleFilter(library, rng=0)
    belief_filter.update(touches)
    return belief_filter, library.names.index("box")


def test_a_pose_that_explains_the_touches_is_held_against_a_worse_one(touched_box):
    belief_filter, box = touched_box
    right = (box, np.eye(3), np.zeros(3))
    turned = (box, Rotation.from_euler("z", 45, degrees=True).as_matrix(), np.zeros(3))
    assert held_prior(belief_filter, right, turned, 1.0) is right
    assert held_prior(belief_filter, turned, right, 1.0) is right


def test_the_margin_holds_a_prior_the_map_beats_by_less(touched_box):
    belief_filter, box = touched_box
    right = (box, np.eye(3), np.zeros(3))
    near = (box, np.eye(3), np.array([0.0, 0.0, 0.05]))
    assert held_prior(belief_filter, near, right, np.inf) is near
    assert held_prior(belief_filter, near, right, 0.0) is right
    assert held_prior(belief_filter, None, near, 5.0) is near


def test_a_candidate_equal_to_the_held_prior_is_the_candidate(touched_box):
    belief_filter, box = touched_box
    held = (box, np.eye(3), np.zeros(3))
    same = (box, np.eye(3), np.zeros(3))
    assert held_prior(belief_filter, held, same, 5.0) is same


def test_the_presets_follow_the_map():
    assert session_preset("paper").cover_prior_hold == 0.0


def test_a_novel_sessions_covered_prior_is_held_while_the_map_moves(sphere_model):
    box = trimesh.creation.box((6.0, 3.0, 3.0))
    library = PriorLibrary([ObjectModel.from_arrays(box.vertices, box.faces, "box",
                                                    cache=sphere_model.cache)])
    params = session_preset("recommended", cover_prior_hold=1e6)
    session = Session(make_truth(sphere_model, rng=0), library, seed=0, params=params)
    held = []
    for _ in range(12):
        session.step()
        held.append(session.state.covered_prior if session.latest.novel else None)
    pairs = [(a, b) for a, b in zip(held, held[1:]) if a is not None and b is not None]
    assert len(pairs) >= 3  # a sphere against a box: novel from its first touches on
    for before, after in pairs:  # a known step in between lets go of it
        assert after[0] == before[0]
        np.testing.assert_array_equal(after[1], before[1])
        np.testing.assert_array_equal(after[2], before[2])
