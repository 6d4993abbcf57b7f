"""The decision made incremental (issue 63): starts carried from touch to touch, the
hypotheses an incremental touch leaves out, full searches, and the refinement's spared
work (free space outside a pose's box, fits that stop once converged)."""

import dataclasses

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import ObjectModel, PriorLibrary
from tactile_viz.engine.belief import decision as decision_module
from tactile_viz.engine.belief.decision import decide
from tactile_viz.engine.belief.incremental import (
    NOTHING,
    Refined,
    full_search_due,
    in_mode,
    remembered,
    starts,
)
from tactile_viz.engine.belief.particle_filter import ParticleFilter
from tactile_viz.engine.belief.pose_refinement import refine_poses
from tactile_viz.engine.explore.observations import Contact
from tactile_viz.engine.params import PAPER_SIZE, FilterParams, scaled_lengths


def _turn(degrees, axis=(0.0, 0.0, 1.0)):
    return Rotation.from_rotvec(np.radians(degrees) * np.asarray(axis)).as_matrix()


def _memory(classes, rotations, translations, searched=3):
    rotations, translations = np.asarray(rotations, float), np.asarray(translations, float)
    return Refined(np.asarray(classes), (rotations, translations), rotations + 0.0,
                   translations + 0.0, searched)


def test_poses_of_one_mode_are_within_its_turn_and_distance():
    rotations = np.stack([_turn(0), _turn(9), _turn(11), _turn(0)])
    translations = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0.2, 0, 0]], float)
    np.testing.assert_array_equal(in_mode(np.eye(3), np.zeros(3), rotations, translations, 0.1),
                                  [True, True, False, False])


def test_a_candidate_the_last_touch_refined_starts_there_and_waits_for_a_full_search():
    """But the MAP's, which is refined from the filter's pose."""
    memory = _memory([0, 1], [_turn(30), _turn(90)], [[1.0, 0, 0], [0, 1.0, 0]])
    classes = np.array([0, 1, 1, 2])
    rotations = np.stack([_turn(33), _turn(92), _turn(200), np.eye(3)])
    translations = np.array([[1.01, 0, 0], [0, 1.0, 0], [0, 1.0, 0], [0, 0, 0]])
    start_r, start_t, source, kept = starts(classes, rotations, translations, memory, 0.05,
                                            full=False)
    np.testing.assert_array_equal(source, [-1, 1, -1, -1])
    np.testing.assert_array_equal(kept, [True, False, True, True])  # the MAP always
    np.testing.assert_array_equal(start_r[0], rotations[0])  # from the filter's pose
    np.testing.assert_array_equal(start_r[1], memory.rotations[1])
    np.testing.assert_array_equal(start_r[2], rotations[2])  # afresh
    *_, source_full, kept_full = starts(classes, rotations, translations, memory, 0.05, True)
    np.testing.assert_array_equal(source_full, source)
    assert kept_full.all()


def test_between_full_searches_only_the_budget_starts_afresh():
    classes = np.array([0, 1, 2, 3, 4])
    rotations, translations = np.repeat(np.eye(3)[None], 5, 0), np.zeros((5, 3))
    *_, source, kept = starts(classes, rotations, translations, NOTHING, 0.1, False, budget=2)
    np.testing.assert_array_equal(kept, [True, True, True, False, False])
    assert (source == -1).all()
    assert starts(classes, rotations, translations, NOTHING, 0.1, True, budget=2)[3].all()


def test_a_left_out_hypothesis_is_handed_on_and_one_never_refined_is_not():
    memory = _memory([0, 1], [_turn(30), _turn(90)], [[1.0, 0, 0], [0, 1.0, 0]])
    begun = (np.stack([_turn(31), _turn(91), np.eye(3)]), np.zeros((3, 3)))
    source, kept = np.array([0, 1, -1]), np.array([True, False, False])
    ended = (np.stack([_turn(32), _turn(5)]), np.array([[1.0, 0, 0], [0, 0, 2.0]]))
    handed = remembered(memory, source, kept, begun, np.array([0, 7]), ended, searched=9)
    np.testing.assert_array_equal(handed.classes, [0, 7, 1])
    np.testing.assert_array_equal(handed.starts[0][0], begun[0][0])  # its own start
    np.testing.assert_array_equal(handed.starts[0][1], ended[0][1])  # carried: where it was
    np.testing.assert_array_equal(handed.rotations[2], memory.rotations[1])
    np.testing.assert_array_equal(handed.starts[0][2], begun[0][1])
    assert handed.searched == 9 and not handed.decided


@pytest.mark.parametrize("searched, decided, contacts, every, due", [
    (-1, False, 10, 4, True), (8, False, 11, 4, False), (8, False, 12, 4, True),
    (8, True, 9, 4, True), (8, False, 9, 1, True)])
def test_a_full_search_comes_every_so_many_contacts_and_after_a_decision(
        searched, decided, contacts, every, due):
    refined = Refined(searched=searched, decided=decided)
    assert full_search_due(refined, contacts, every) is due


@pytest.fixture(scope="module")
def shapes(tmp_path_factory):
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    wedge = trimesh.creation.box(extents=(5, 4, 1))
    models = [ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
              for m, name in ((box, "box"), (cylinder, "cylinder"), (wedge, "slab"))]
    return PriorLibrary(models)


def _touched(library, name, count, seed):
    model = library[name]
    points, faces = trimesh.sample.sample_surface_even(model.mesh, count, seed=seed)
    params = scaled_lengths(FilterParams(), library.reference_size / PAPER_SIZE)
    pf = ParticleFilter(library, params, rng=seed)
    for p, n in zip(points, model.mesh.face_normals[faces]):
        state = pf.update(Contact(p, n))
    return pf, state


def test_free_space_far_off_is_spared_and_the_fit_is_the_same(shapes):
    """The bank's look-up of the free points inside a pose (:meth:`PriorBank.below`) fits
    as every point evaluated does, and leaves ``evaluate`` only the contacts."""
    pf, state = _touched(shapes, "box", 20, seed=3)
    rng = np.random.default_rng(0)
    outside = np.vstack([rng.uniform(-30, 30, (300, 3)), rng.uniform(-4, 4, (60, 3))])
    rotations = np.stack([_turn(a, (1, 1, 0)) for a in (0, 20, 150)])
    translations = rng.normal(0, 0.3, (3, 3))
    asked = []

    def evaluate(classes, points):
        asked.append(points.shape[1])
        return pf.bank.evaluate(classes, points)

    plain = refine_poses(evaluate, np.array([0, 0, 1]), rotations, translations,
                         pf.contact_positions, outside, 6, clearance=0.1)
    assert max(asked) == len(outside)
    asked[:] = []
    spared = refine_poses(evaluate, np.array([0, 0, 1]), rotations, translations,
                          pf.contact_positions, outside, 6, clearance=0.1,
                          below=pf.bank.below)
    for a, b in zip(plain, spared):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    assert set(asked) == {len(pf.contact_positions)}
    assert not np.allclose(plain[2], refine_poses(
        evaluate, np.array([0, 0, 1]), rotations, translations, pf.contact_positions, None,
        6)[2])  # the free points do count


def test_a_fit_with_a_tolerance_stops_once_a_step_gains_little(shapes):
    """A step taken that lowers a pose's squares by less than the tolerance ends its fit
    (fewer look-ups, a fit no worse than its start); no tolerance is the plain fit."""
    pf, state = _touched(shapes, "cylinder", 25, seed=5)
    rotations = np.stack([_turn(0.5, (1, 0, 0)), np.eye(3)])  # about where it was touched
    translations = np.array([[0.01, 0.0, 0.0], [0.0, 0.0, 0.0]])
    calls = []

    def evaluate(classes, points):
        calls.append(len(classes))
        return pf.bank.evaluate(classes, points)

    def fitted(iterations, **options):
        calls.clear()
        fit = refine_poses(evaluate, np.array([1, 1]), rotations, translations,
                           pf.contact_positions, None, iterations, **options)
        return fit, len(calls)

    (plain, _), (zero, _) = fitted(10), fitted(10, tolerance=0.0)
    for a, b in zip(plain, zero):
        np.testing.assert_array_equal(a, b)
    (_, _, stopped), stopped_calls = fitted(30, tolerance=1e-2)
    start = fitted(0)[0][2]
    assert stopped_calls < fitted(30)[1] and np.all(stopped <= start)


def test_an_incremental_touch_refines_fewer_and_only_a_full_search_decides(shapes,
                                                                           monkeypatch):
    pf, state = _touched(shapes, "cylinder", 30, seed=1)
    first = decide(pf, state, 0.99, floor=0.02, same_mode=0.1, refresh=4)
    assert first.refined.searched == len(pf.contact_positions)
    weighed, refine = [], decision_module.refine_poses

    def spy(evaluate, classes, *args, **options):
        weighed.append(len(classes))
        return refine(evaluate, classes, *args, **options)

    fulls, weigh = [], decision_module._weigh

    def spy_weigh(pf, belief, **options):
        fulls.append(options["full"])
        return weigh(pf, belief, **options)

    monkeypatch.setattr(decision_module, "refine_poses", spy)
    monkeypatch.setattr(decision_module, "_weigh", spy_weigh)
    undecided = dataclasses.replace(first.refined, decided=False)
    again = decide(pf, state, 0.99, floor=0.02, same_mode=0.1, carried=first.carried,
                   refined=undecided, refresh=4)
    assert fulls[0] is False and weighed[0] < len(first.refined.classes)
    if again.decided:
        assert fulls[-1] is True
    assert again.hypotheses[0].class_index == first.hypotheses[0].class_index
