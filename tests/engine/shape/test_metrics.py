import numpy as np
import pytest
import trimesh
from scipy.spatial.distance import pdist

from tactile_viz.engine import ObjectModel
from tactile_viz.engine.shape.metrics import (
    diameter,
    directed_hausdorff,
    surface_hausdorff,
    two_way_hausdorff,
    wall_thickness,
)


def _brute(a, b):
    return float(np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min(axis=1).max())


@pytest.mark.parametrize("offset", [0.0, 1e-3, 0.5, 30.0])
def test_directed_hausdorff_is_exact_near_and_far(offset, rng):
    """Close sets go by KD-tree, far ones by the early break: the same number either way."""
    surface = rng.normal(size=(1500, 3))
    surface /= np.linalg.norm(surface, axis=1, keepdims=True)
    other = surface[rng.permutation(1500)[:900]] + offset * rng.normal(size=(900, 3))
    other[:5] += [offset * 10, 0, 0]
    for a, b in ((surface, other), (other, surface), (surface[:3], other), (other, surface[:1])):
        assert directed_hausdorff(a, b) == pytest.approx(_brute(a, b), rel=1e-12)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_diameter_is_the_farthest_pair_at_any_scale(scale, rng):
    """A box's diagonal, a flat set's and a line's farthest pair (no hull: every pair), 0
    for fewer than two points; an object's diameter is its mesh's."""
    box = trimesh.creation.box([1.0, 2.0, 3.0])
    points = np.vstack([box.vertices, trimesh.sample.sample_surface(box, 200, seed=1)[0]])
    assert diameter(points * scale) == pytest.approx(np.sqrt(14) * scale, rel=1e-12)
    flat = rng.random((50, 3)) * [scale, scale, 0.0]
    assert diameter(flat) == pytest.approx(pdist(flat).max(), rel=1e-12)
    line = np.outer(np.linspace(0.0, scale, 9), [1.0, 0.0, 0.0])
    assert diameter(line) == pytest.approx(scale)
    assert diameter(np.zeros((1, 3))) == 0.0 and diameter(np.zeros((0, 3))) == 0.0
    model = ObjectModel.from_arrays(box.vertices * scale, box.faces, "box")
    assert model.diameter == pytest.approx(diameter(model.mesh.vertices))


def test_directed_hausdorff_of_empty_sets():
    assert directed_hausdorff(np.zeros((0, 3)), np.ones((4, 3))) == 0.0
    assert directed_hausdorff(np.ones((4, 3)), np.zeros((0, 3))) == float("inf")


@pytest.mark.parametrize("scale", [0.01, 1.0, 100.0])
def test_the_surface_hausdorff_has_no_sampling_floor(scale):
    mesh = trimesh.creation.box((2.0 * scale, 2.0 * scale, 2.0 * scale))
    a, _ = trimesh.sample.sample_surface(mesh, 2000, seed=0)
    b, _ = trimesh.sample.sample_surface(mesh, 2000, seed=1)
    surface = (mesh.vertices, mesh.faces)
    assert two_way_hausdorff(a, b) > 0.05 * scale  # the samples' gaps
    assert surface_hausdorff(a, surface, b, surface) < 1e-9 * scale
    moved = mesh.copy()
    moved.apply_translation((0.1 * scale, 0.0, 0.0))
    distance = surface_hausdorff(a, surface, b + (0.1 * scale, 0.0, 0.0),
                                 (moved.vertices, moved.faces))
    assert distance == pytest.approx(0.1 * scale, rel=1e-6)
    assert surface_hausdorff(a, surface, b, (np.zeros((0, 3)), np.zeros((0, 3), int))) == np.inf


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_truth_evaluator_measures_a_step_without_a_session(scale, rng):
    """The truth's own shape at its own pose is no error; the same shape shifted is off by
    the shift; a reconstruction that is the truth's surface is off by at most the samples'
    gap and, on a final step, by about nothing; contacts on every sample cover the truth;
    another shape has no rotation error (tiny and huge)."""
    from types import SimpleNamespace

    from tactile_viz.engine.session.truth import TruthEvaluator, make_truth
    from tactile_viz.engine.shape.objects import ObjectModel
    from tactile_viz.engine.transforms import transform_points

    box = trimesh.creation.box((2.0 * scale, 1.0 * scale, 0.5 * scale))
    model = ObjectModel.from_arrays(box.vertices, box.faces, "box")
    ball = trimesh.creation.icosphere(radius=0.6 * scale)
    other = ObjectModel.from_arrays(ball.vertices, ball.faces, "ball")
    truth = make_truth(model, rng=rng)
    evaluator = TruthEvaluator(truth, 2000)
    placed = transform_points(model.mesh.vertices, truth.rotation, truth.translation)
    recon = SimpleNamespace(vertices=placed, faces=model.mesh.faces)  # what it reads
    same = evaluator.errors(model, truth.rotation, truth.translation, recon,
                            evaluator.points, final=True)
    assert same["pose_error"] == pytest.approx(0.0, abs=1e-9 * scale)
    assert same["rotation_error_deg"] == pytest.approx(0.0, abs=1e-6)
    assert same["truth_coverage"] == 0.0
    assert 0 < same["recon_error"] < 0.2 * scale
    assert same["recon_surface_error"] < 1e-6 * scale
    shift = np.array([0.1, 0.0, 0.0]) * scale
    shifted = evaluator.errors(model, truth.rotation, truth.translation + shift, None,
                               evaluator.points[:10])
    assert shifted["pose_error"] == pytest.approx(0.1 * scale, rel=1e-6)
    assert shifted["recon_error"] is None and shifted["truth_coverage"] > 0
    elsewhere = evaluator.errors(other, truth.rotation, truth.translation, None,
                                 evaluator.points)
    assert elsewhere["rotation_error_deg"] is None and elsewhere["pose_error"] > 0


def test_the_truth_evaluator_remembers_what_it_measured_without_changing_it(rng):
    """Contacts appended, dropped and replaced give each step's own coverage; a surface met
    again gives its own error, and another surface its own."""
    from types import SimpleNamespace

    from tactile_viz.engine.session.truth import TruthEvaluator, make_truth
    from tactile_viz.engine.shape.metrics import directed_hausdorff
    from tactile_viz.engine.shape.objects import ObjectModel

    box = trimesh.creation.box((2.0, 1.0, 0.5))
    truth = make_truth(ObjectModel.from_arrays(box.vertices, box.faces, "box"), rng=rng)
    evaluator = TruthEvaluator(truth, 1000)
    contacts = rng.normal(size=(40, 3))
    for count in (1, 2, 5, 30, 12, 40, 0, 3):
        given = contacts[:count] if count != 3 else rng.normal(size=(3, 3))
        found = evaluator.errors(truth.model, truth.rotation, truth.translation, None, given)
        assert found["truth_coverage"] == pytest.approx(
            directed_hausdorff(evaluator.points, given), rel=1e-12)
    ball = trimesh.creation.icosphere(radius=0.7)
    for mesh in (ball, box, ball):
        recon = SimpleNamespace(vertices=mesh.vertices + truth.translation, faces=mesh.faces)
        found = evaluator.errors(truth.model, truth.rotation, truth.translation, recon,
                                 contacts)["recon_error"]
        fresh = TruthEvaluator(truth, 1000).errors(
            truth.model, truth.rotation, truth.translation, recon, contacts)["recon_error"]
        assert found == fresh


def _plate(rng, thickness, scale, count=60):
    """Contacts on both faces of a plate ``thickness`` thick, ``scale`` across (z up)."""
    xy = rng.uniform(-scale / 2, scale / 2, size=(count, 2))
    side = np.where(np.arange(count) % 2 == 0, 1.0, -1.0)
    points = np.column_stack([xy, side * thickness / 2])
    normals = np.column_stack([np.zeros((count, 2)), side])
    return points, normals


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_the_wall_touched_on_both_sides_is_measured(scale, rng):
    points, normals = _plate(rng, 0.04 * scale, scale)
    assert wall_thickness(points, normals, 0.3 * scale) == pytest.approx(0.04 * scale)
    # Beyond reach of each other the sides are not one wall (a block, a ball).
    assert wall_thickness(points, normals, 0.02 * scale) is None
    sphere = rng.normal(size=(200, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    assert wall_thickness(scale * sphere, sphere, 0.3 * scale) is None


def test_a_wall_needs_several_contacts_on_its_far_side(rng):
    points, normals = _plate(rng, 0.04, 1.0, count=8)
    assert wall_thickness(points[:1], normals[:1], 1.0) is None
    assert wall_thickness(points[:4], normals[:4], 2.0) is None  # 4 contacts, fewer than 5
    assert wall_thickness(points, normals, 2.0) == pytest.approx(0.04)
    assert wall_thickness(np.zeros((0, 3)), np.zeros((0, 3)), 1.0) is None
