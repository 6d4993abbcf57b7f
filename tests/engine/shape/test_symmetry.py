"""Symmetry groups found from shapes, and pose errors taken up to them."""

import itertools

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from tactile_viz.engine import ObjectModel, load_bundled
from tactile_viz.engine.io.cache import ArrayCache
from tactile_viz.engine.shape.metrics import (
    rotation_error_deg,
    same_pose_mode,
    symmetric_pose_difference,
    symmetry_group,
)
from tactile_viz.engine.shape.symmetry import find_symmetry_group, rotation

TURN = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()  # turns the meshes off the axes
GENERIC = np.array([0.48, -0.6, 0.64])  # unit; no symmetry axis of any shape here


def tetrahedron():
    return trimesh.convex.convex_hull(np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1],
                                                [-1, -1, 1.0]]))


# name: (mesh, group name, order of the discrete part, continuous axis)
SHAPES = {
    "cube": (lambda: trimesh.creation.box(extents=(2, 2, 2)), "O", 24, False),
    "box": (lambda: trimesh.creation.box(extents=(6, 3, 2)), "D2", 4, False),
    "square prism": (lambda: trimesh.creation.box(extents=(2, 2, 5)), "D4", 8, False),
    "hexagonal prism": (lambda: trimesh.creation.cylinder(radius=1, height=3, sections=6),
                        "D6", 12, False),
    "cylinder": (lambda: trimesh.creation.cylinder(radius=1, height=4, sections=64),
                 "D∞", 2, True),
    "cone": (lambda: trimesh.creation.cone(radius=1, height=3, sections=64), "C∞", 1, True),
    "sphere": (lambda: trimesh.creation.icosphere(subdivisions=3), "SO(3)", 1, False),
    "tetrahedron": (tetrahedron, "T", 12, False),
    "blob": (lambda: trimesh.convex.convex_hull(np.random.default_rng(0).normal(size=(30, 3))),
             "C1", 1, False),
}


def model_of(mesh, tmp_path, turn=np.eye(3), size=1.0, name="shape"):  # noqa: B008 (read only)
    """An ObjectModel of ``mesh`` turned by ``turn`` with its longest side scaled to ``size``
    times the mesh's."""
    vertices = mesh.vertices @ turn.T * size
    return ObjectModel.from_arrays(vertices, mesh.faces, name, cache=ArrayCache(tmp_path),
                                   scale=1.0)


@pytest.mark.parametrize("turned, size", [(False, 1.0), (True, 1e-3), (True, 1e3)])
@pytest.mark.parametrize("shape", SHAPES)
def test_the_group_found_is_the_shapes(shape, turned, size, tmp_path):
    build, name, order, continuous = SHAPES[shape]
    model = model_of(build(), tmp_path, TURN if turned else np.eye(3), size)
    group = symmetry_group(model)
    rotations, axis, is_sphere, centre = group
    assert group.name == name
    assert len(rotations) == order and is_sphere == (name == "SO(3)")
    assert (axis is not None) == continuous and centre.shape == (3,)
    assert np.allclose(group.rotations[0], np.eye(3))
    assert np.allclose(np.einsum("kji,kjl->kil", group.rotations, group.rotations), np.eye(3),
                       atol=1e-9)


def cube_turns(turn):
    """The cube's 24 rotations (signed permutation matrices of determinant 1) as they act on
    a cube turned by ``turn``."""
    turns = []
    for order in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            matrix = np.eye(3)[list(order)] * np.array(signs)[:, None]
            if np.linalg.det(matrix) > 0:
                turns.append(turn @ matrix @ turn.T)
    return np.array(turns)


def test_every_turn_of_a_cube_is_no_error_and_others_count(tmp_path):
    model = model_of(trimesh.creation.box(extents=(2, 2, 2)), tmp_path, TURN)
    truth = Rotation.from_rotvec([1.0, 0.2, -0.5]).as_matrix()
    turns = cube_turns(TURN)
    assert len(turns) == 24
    errors = [rotation_error_deg(model, truth @ turn, truth) for turn in turns]
    np.testing.assert_allclose(errors, 0.0, atol=1e-3)
    off = truth @ turns[7] @ rotation(GENERIC, np.radians(10))
    assert rotation_error_deg(model, off, truth) == pytest.approx(10.0, abs=0.5)
    # A turn halfway between two symmetries is as far from both.
    half = truth @ rotation(TURN @ [0, 0, 1], np.radians(45))
    assert rotation_error_deg(model, half, truth) == pytest.approx(45.0, abs=0.5)


def test_a_box_turns_only_half_way_about_its_axes(tmp_path):
    model = model_of(trimesh.creation.box(extents=(6, 3, 2)), tmp_path, TURN)
    for axis in TURN.T:
        assert rotation_error_deg(model, rotation(axis, np.pi), np.eye(3)) \
            == pytest.approx(0.0, abs=1e-3)
        assert rotation_error_deg(model, rotation(axis, np.pi / 2), np.eye(3)) \
            == pytest.approx(90.0, abs=0.5)


def test_only_the_tilt_of_a_cylinders_axis_counts(tmp_path):
    model = model_of(trimesh.creation.cylinder(radius=1, height=4, sections=64), tmp_path, TURN)
    axis = symmetry_group(model).axis
    assert abs(axis @ TURN[:, 2]) == pytest.approx(1.0, abs=1e-3)
    truth = Rotation.from_rotvec([0.4, 0.9, -0.2]).as_matrix()
    spun = truth @ rotation(axis, 1.3)
    flipped = spun @ rotation(TURN[:, 0], np.pi)
    for pose in (spun, flipped):
        assert rotation_error_deg(model, pose, truth) == pytest.approx(0.0, abs=0.5)
    tilt = rotation(TURN[:, 0], np.radians(10))
    assert rotation_error_deg(model, flipped @ tilt, truth) == pytest.approx(10.0, abs=0.5)


def test_a_cone_has_no_flip(tmp_path):
    model = model_of(trimesh.creation.cone(radius=1, height=3, sections=64), tmp_path, TURN)
    flipped = rotation(TURN[:, 0], np.pi)
    assert rotation_error_deg(model, flipped, np.eye(3)) == pytest.approx(180.0, abs=0.5)


def test_a_sphere_has_no_rotation_error(tmp_path):
    model = model_of(trimesh.creation.icosphere(subdivisions=3), tmp_path)
    assert symmetry_group(model).is_sphere
    turn = Rotation.random(random_state=2).as_matrix()
    assert rotation_error_deg(model, turn, np.eye(3)) == 0.0


def test_a_mug_has_no_symmetry():
    group = symmetry_group(load_bundled("mug_1"))
    assert group.name == "C1" and group.axis is None and not group.is_sphere
    assert rotation_error_deg(load_bundled("mug_1"), rotation(GENERIC, 0.5), np.eye(3)) \
        == pytest.approx(np.degrees(0.5), abs=1e-6)


def test_scan_noise_keeps_a_cubes_group():
    mesh = trimesh.creation.box(extents=(2, 2, 2))
    for _ in range(5):
        mesh = mesh.subdivide()
    noisy = mesh.vertices + np.random.default_rng(1).normal(scale=0.006, size=mesh.vertices.shape)
    group = find_symmetry_group(noisy @ TURN.T, mesh.faces)
    assert group.name == "O" and len(group.rotations) == 24


def placed(model, rotation_, translation):
    """World positions of the model's vertices at a pose."""
    return model.mesh.vertices @ rotation_.T + translation


def test_equivalent_poses_move_the_centre_with_the_symmetry(tmp_path):
    # Turned off the axes, a tetrahedron's box centre (the object origin) is not its centre.
    model = model_of(tetrahedron(), tmp_path, TURN)
    group = symmetry_group(model)
    assert np.linalg.norm(group.centre) > 0.05
    rotation_b = Rotation.from_rotvec([0.2, 1.0, 0.3]).as_matrix()
    translation_b = np.array([1.0, -2.0, 0.5])
    world = placed(model, rotation_b, translation_b)
    for symmetry in group.rotations[1:]:
        rotation_a = rotation_b @ symmetry.T
        translation_a = translation_b - rotation_a @ (group.centre - symmetry @ group.centre)
        # The same surface: each placed vertex is at some vertex of the other placement.
        moved = placed(model, rotation_a, translation_a)
        assert np.abs(moved[:, None] - world[None]).sum(axis=2).min(axis=1).max() < 1e-5
        angle, distance = symmetric_pose_difference(model, rotation_a, translation_a,
                                                    rotation_b, translation_b)
        assert angle[0] == pytest.approx(0.0, abs=1e-3)
        assert distance[0] == pytest.approx(0.0, abs=1e-6)
        assert np.linalg.norm(translation_a - translation_b) > 0.01
        pose_a, pose_b = (rotation_a, translation_a), (rotation_b, translation_b)
        assert same_pose_mode(model, pose_a, pose_b, angle_tol_deg=2.0, translation_tol=0.01)
        shifted = (rotation_a, translation_a + [0.0, 0.05, 0.0])
        assert not same_pose_mode(model, shifted, pose_b, 2.0, 0.01)
        tilted = (rotation_a @ rotation(GENERIC, np.radians(5)), translation_a)
        assert not same_pose_mode(model, tilted, pose_b, 2.0, 0.01)


def test_pose_differences_of_many_poses_at_once(tmp_path):
    model = model_of(trimesh.creation.box(extents=(6, 3, 2)), tmp_path)
    rotations = Rotation.random(50, random_state=3).as_matrix()
    translations = np.random.default_rng(3).normal(size=(50, 3))
    angles, distances = symmetric_pose_difference(model, rotations, translations, np.eye(3),
                                                  np.zeros(3))
    one_by_one = [rotation_error_deg(model, r, np.eye(3)) for r in rotations]
    np.testing.assert_allclose(angles, one_by_one)
    assert angles.shape == distances.shape == (50,)
    assert angles.max() <= 180.0 and (distances >= 0).all()


def test_roughness_is_the_detail_that_poses_a_round_shape():
    """A sphere with 1% bumps is still round, and its roughness is about the bumps; a smooth
    sphere's is far smaller, and a shape without a round axis has none."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    bumps = 0.01 * np.sin(5 * sphere.vertices[:, 0]) * np.cos(4 * sphere.vertices[:, 1])
    bumpy = find_symmetry_group(sphere.vertices * (1 + bumps)[:, None], sphere.faces)
    smooth = find_symmetry_group(sphere.vertices, sphere.faces)
    assert bumpy.is_sphere and smooth.is_sphere
    assert 0.002 < bumpy.roughness < 0.02  # bumps of at most 0.01 on a radius of 1
    assert smooth.roughness < 0.2 * bumpy.roughness
    box = trimesh.creation.box(extents=(6, 3, 2))
    assert find_symmetry_group(box.vertices, box.faces).roughness == 0.0


def test_a_group_is_found_once_per_shape(tmp_path, monkeypatch):
    import tactile_viz.engine.shape.symmetry as symmetry

    mesh = trimesh.creation.cylinder(radius=1, height=4, sections=64)
    first = symmetry_group(model_of(mesh, tmp_path))

    def refuse(*args, **kwargs):
        raise AssertionError("found again")

    monkeypatch.setattr(symmetry, "find_symmetry_group", refuse)
    again = symmetry_group(model_of(mesh, tmp_path))  # a new model of the same shape
    assert again.name == first.name == "D∞"
    np.testing.assert_allclose(again.axis, first.axis)
    np.testing.assert_allclose(again.rotations, first.rotations)
    assert again.roughness == pytest.approx(first.roughness)
