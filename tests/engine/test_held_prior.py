"""The prior a novel object's exploration holds (``cover_prior_hold``): kept until the
filter's MAP explains the observations better by the margin."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tactile_viz.engine import Contact
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.estimate import held_prior


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
