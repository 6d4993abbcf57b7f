"""The non-contacts' share of a pose fit, summed over the pairs that count, and the
prior bank's near boxes that find them."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tactile_viz.engine.belief.outside import dense_below, outside_terms
from tactile_viz.engine.belief.prior_bank import PriorBank

from .conftest import box_distance

HALF = np.array([[3.0, 1.5, 1.0], [1.0, 1.0, 2.5]])  # two boxes, one a class


def boxes_evaluate(classes, points):
    """Each class's box's exact signed distance and outward gradient: (k, m), (k, m, 3)."""
    return box_distance(points, HALF[np.asarray(classes)][:, None])


def dense_terms(classes, rotations, translations, points, centre, clearance):
    """The same sums over every pair, as :func:`refine_poses` formed them before."""
    local = (points[None] - translations[:, None]) @ rotations  # R^T (p - t)
    values, gradients = boxes_evaluate(classes, local)
    values = np.minimum(values - clearance, 0.0)
    normals = np.einsum("kij,kmj->kmi", rotations, gradients) * (values < 0)[..., None]
    rows = -np.concatenate([np.cross(points - centre, normals), normals], axis=2)
    return (
        (values**2).sum(axis=1),
        np.einsum("kmi,kmj->kij", rows, rows),
        np.einsum("kmi,km->ki", rows, values),
    )


@pytest.mark.parametrize("clearance", [0.0, 0.3])
def test_the_sums_over_the_pairs_inside_are_those_over_every_pair(clearance, rng):
    classes = np.array([0, 1, 0, 1, 1])
    rotations = Rotation.random(5, random_state=3).as_matrix()
    translations = rng.uniform(-1, 1, (5, 3))
    points = rng.uniform(-6, 6, (800, 3))  # a few hundred inside some pose's box
    centre = np.array([0.2, -0.1, 0.3])
    cost, normal, gradient = outside_terms(
        dense_below(boxes_evaluate), classes, rotations, translations, points, centre, clearance
    )
    expected = dense_terms(classes, rotations, translations, points, centre, clearance)
    assert (cost > 0).all()  # every pose has points inside
    for got, want in zip((cost, normal, gradient), expected):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_no_non_contacts_or_none_inside_cost_nothing():
    rotations, translations = np.eye(3)[None], np.zeros((1, 3))
    for points in (np.zeros((0, 3)), np.full((4, 3), 50.0)):
        cost, normal, gradient = outside_terms(
            dense_below(boxes_evaluate), [1], rotations, translations, points, np.zeros(3), 0.1
        )
        assert cost.shape == (1,) and normal.shape == (1, 6, 6) and gradient.shape == (1, 6)
        assert not cost.any() and not normal.any() and not gradient.any()


@pytest.mark.parametrize("level", [0.0, 0.3])
def test_the_banks_look_up_finds_the_pairs_every_pair_finds(bundled, level, rng):
    bank = PriorBank([bundled[name] for name in ("mug_1", "bottle_1")], 0.1, 12.0)
    classes = np.array([0, 1, 1, 0])
    rotations = Rotation.random(4, random_state=7).as_matrix()
    translations = rng.uniform(-0.5, 0.5, (4, 3))
    points = rng.uniform(-5, 5, (3000, 3))
    found = bank.below(classes, rotations, translations, points, level)
    every = dense_below(bank.evaluate)(classes, rotations, translations, points, level)
    assert 100 < len(found[0]) < len(points)  # some inside, most not
    for got, want in zip(found[:2], every[:2]):
        np.testing.assert_array_equal(got, want)
    for got, want in zip(found[2:], every[2:]):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("level", [0.0, 0.25, 1.5])
def test_outside_a_near_box_every_value_exceeds_its_level(bundled, level, rng):
    models = [bundled[name] for name in ("mug_1", "bottle_1")]
    bank = PriorBank(models, 0.1, 12.0)
    low, high = bank.near_boxes(level)
    grid_low, grid_high = bank.boxes
    if level == 0.0:  # well inside the grid; a level reaching its faces, beyond them
        assert (low > grid_low).all() and (high < grid_high).all()
    for c in range(len(models)):
        points = rng.uniform(low[c] - 2.0, high[c] + 2.0, (20000, 3))
        values, _ = bank.evaluate(np.array([c]), points[None])
        beyond = ((points < low[c]) | (points > high[c])).any(axis=1)
        assert beyond.sum() > 1000 and (values[0][beyond] > level).all()
        # The box is tight: a point just inside each face is within a cell of the level.
        assert (values[0][~beyond] <= level).any()
    assert bank.near_boxes(level) is bank.near_boxes(level)  # cached


def test_the_banks_look_up_in_chunks_finds_the_same_pairs(bundled, monkeypatch, rng):
    from tactile_viz.engine.belief import prior_bank

    bank = PriorBank([bundled[name] for name in ("mug_1", "bottle_1")], 0.1, 12.0)
    classes = rng.integers(0, 2, 7)
    rotations = Rotation.random(7, random_state=2).as_matrix()
    translations = rng.uniform(-0.5, 0.5, (7, 3))
    points = rng.uniform(-4, 4, (500, 3))
    whole = bank.below(classes, rotations, translations, points, 0.1)
    monkeypatch.setattr(prior_bank, "BELOW_PAIRS", 1100)  # two hypotheses a chunk
    chunked = bank.below(classes, rotations, translations, points, 0.1)
    assert len(whole[0]) > 50
    for a, b in zip(whole, chunked):
        np.testing.assert_array_equal(a, b)
