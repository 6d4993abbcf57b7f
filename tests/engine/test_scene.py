"""The robot's scene: a table, a reach cone and a tip of real size (engine/scene.py), the
simulator as a robot senses it, resting truths and sessions that keep to the scene."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import (
    Contact,
    ContactSimulator,
    GroundTruth,
    NonContact,
    ObjectModel,
    ParameterError,
    PriorLibrary,
    Session,
    make_truth,
    session_preset,
)
from tactile_viz.engine.belief.particles import Particles
from tactile_viz.engine.io.cache import ArrayCache
from tactile_viz.engine.scene import FREE, Scene
from tactile_viz.engine.shape.resting import (
    hull_points,
    lowest_heights,
    seeds_on_table,
    stable_rotations,
)


def _box_model(tmp_path, extents=(6.0, 3.0, 2.0), name="box"):
    mesh = trimesh.creation.box(extents=extents)
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, name,
                                   cache=ArrayCache(tmp_path), longest_side=max(extents))


def _angle_from_down(direction, scene):
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    return np.degrees(np.arccos(np.clip(-(direction @ scene.up), -1, 1)))


@pytest.mark.parametrize("kwargs", [dict(reach_angle_deg=0), dict(reach_angle_deg=181),
                                    dict(reach_angle_deg=np.nan), dict(tip_radius=-1e-3),
                                    dict(tip_radius=np.inf), dict(up=(0, 0, 0)),
                                    dict(table_point=(0, np.nan, 0))])
def test_a_bad_scene_is_one_parameter_error(kwargs):
    with pytest.raises(ParameterError):
        Scene(**kwargs)


def test_the_default_scene_is_the_papers_free_space():
    assert FREE.is_free and not FREE.has_table and not FREE.limited_reach
    assert Scene.from_dict(Scene.on_table(0.2, 60, 0.005).as_dict()).as_dict() == \
        Scene.on_table(0.2, 60, 0.005).as_dict()


@pytest.mark.parametrize("normal", [(0, 0, 1), (1, 0, 0), (0.3, -0.2, -1), (0, 0, -1)])
def test_an_approach_lies_in_the_cone_and_is_the_normal_when_it_can(normal):
    scene = Scene.on_table(0.0, 60.0, 0.0)
    direction = scene.approach(np.asarray(normal, float) / np.linalg.norm(normal))
    assert np.linalg.norm(direction) == pytest.approx(1.0)
    assert _angle_from_down(direction, scene) <= 60.0 + 1e-9
    if normal == (0, 0, 1):
        np.testing.assert_allclose(direction, [0, 0, -1], atol=1e-12)
    if normal == (1, 0, 0):  # the rim, turned toward -normal
        assert direction[0] < 0 and _angle_from_down(direction, scene) == pytest.approx(60.0)


def test_a_line_ends_where_the_tip_meets_the_table():
    scene = Scene.on_table(0.5, 60.0, 0.1)
    path = scene.line(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), 2.0, 5.0)
    assert path[0][2] == pytest.approx(3.0)
    assert path[-1][2] == pytest.approx(0.6)  # the centre one radius above the plane
    scene.check_path(path, 1e-9)


def test_a_path_below_the_table_or_outside_the_cone_is_refused():
    scene = Scene.on_table(0.0, 60.0, 0.1)
    with pytest.raises(ParameterError, match="below the table"):
        scene.check_path(np.array([[0, 0, 1.0], [0, 0, -0.5]]), 1e-6)
    with pytest.raises(ParameterError, match="outside the reach cone"):
        scene.check_path(np.array([[0, 0, 1.0], [3.0, 0, 1.0]]), 1e-6)


def test_reachable_leaves_out_the_bottom_the_undersides_and_narrow_gaps():
    scene = Scene.on_table(0.0, 60.0, 0.2)
    # A top, a side lower than the tip's radius, an underside, a side, a face turned up
    # a hair above the table (a knife lying flat), and a top in a slot narrower than the tip.
    vertices = np.array([[0, 0, 1.0], [0, 0, 0.05], [0, 0, 1.0], [0, 0, 1.0], [0, 0, 0.01],
                         [0, 0, 1.0]])
    normals = np.array([[0, 0, 1.0], [1, 0, 0], [0, 0, -1.0], [1, 0, 0], [0, 0, 1.0],
                        [0, 0, 1.0]])

    def outside(points):  # the last point's tip would sit in a slot 0.2 wide
        return np.where(np.arange(len(points)) == len(points) - 1, 0.05, 1.0)

    keep = scene.reachable(vertices, normals, outside)
    np.testing.assert_array_equal(keep, [True, False, False, True, True, False])


def test_the_tip_stops_one_radius_off_the_surface_and_reports_the_surface(tmp_path):
    model = _box_model(tmp_path)
    truth = GroundTruth(model, np.eye(3), np.array([0.0, 0.0, 1.0]))  # resting on z = 0
    scene = Scene.on_table(0.0, 60.0, 0.3)
    simulator = ContactSimulator(truth, scene=scene)
    contact = simulator.probe(np.array([[0.5, 0.2, 6.0], [0.5, 0.2, 0.5]]))
    assert isinstance(contact, Contact)
    np.testing.assert_allclose(contact.position, [0.5, 0.2, 2.0], atol=0.02)
    np.testing.assert_allclose(contact.normal, [0, 0, 1], atol=0.1)
    # Beside the box the tip comes down on the table.
    table = simulator.probe(np.array([[5.0, 0.0, 6.0], [5.0, 0.0, 0.3]]))
    assert isinstance(table, Contact)
    np.testing.assert_allclose(table.position, [5.0, 0.0, 0.0], atol=0.02)
    assert scene.is_table_contact(table.position, table.normal, 0.02)
    assert not scene.is_table_contact(contact.position, contact.normal, 0.02)


def test_a_tip_wider_than_a_gap_does_not_enter_it(tmp_path):
    left = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    left.apply_translation([-1.5, 0, 1.0])
    right = left.copy()
    right.apply_translation([3.0, 0, 0])  # a slot 1.0 wide between x = -0.5 and 0.5
    mesh = trimesh.util.concatenate([left, right])
    model = ObjectModel.from_arrays(mesh.vertices, mesh.faces, "slot",
                                    cache=ArrayCache(tmp_path), longest_side=5.0)
    truth = GroundTruth(model, np.eye(3), -model.file_to_object[:3, 3])
    down = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, 0.0]])
    narrow = ContactSimulator(truth, scene=Scene.on_table(0.0, 60.0, 0.3))
    wide = ContactSimulator(truth, scene=Scene.on_table(0.0, 60.0, 0.7))
    down_narrow = down.copy()
    down_narrow[-1, 2] = 0.3
    reached = narrow.probe(down_narrow)
    assert reached.position[2] < 0.05  # down to the table between the blocks
    down_wide = down.copy()
    down_wide[-1, 2] = 0.7
    stopped = wide.probe(down_wide)
    assert isinstance(stopped, Contact) and stopped.position[2] > 1.9  # on a block's edge


def test_the_simulator_refuses_a_path_that_breaks_the_scene(tmp_path):
    truth = GroundTruth(_box_model(tmp_path), np.eye(3), np.array([0.0, 0.0, 1.0]))
    simulator = ContactSimulator(truth, scene=Scene.on_table(0.0, 45.0, 0.0))
    with pytest.raises(ParameterError):
        simulator.probe(np.array([[0.0, 5.0, 3.0], [0.0, -5.0, 3.0]]))
    with pytest.raises(ParameterError):
        simulator.probe(np.array([[9.0, 0.0, 3.0], [9.0, 0.0, -3.0]]))


@pytest.mark.parametrize("name", ["mug_1", "guitar_1", "office_chair"])
def test_a_resting_truth_lies_on_the_table_in_a_stable_pose(bundled, name):
    model = bundled[name]
    scene = Scene.on_table(-0.7, 60.0, 0.0)
    for seed in range(3):
        truth = make_truth(model, rng=seed, scene=scene)
        low = lowest_heights(hull_points(model), truth.rotation[None],
                             truth.translation[None], scene.up, scene.table_point)[0]
        assert abs(low) < 1e-9
        rotations, probabilities = stable_rotations(model)
        assert probabilities.sum() == pytest.approx(1.0)
        # Up to a turn about the vertical, the pose is one of the stable ones: the up
        # direction in the object frame matches a stable pose's.
        up_in_object = truth.rotation.T @ scene.up
        stable_ups = rotations.transpose(0, 2, 1) @ np.array([0.0, 0.0, 1.0])
        assert np.max(stable_ups @ up_in_object) > 1 - 1e-9


def test_stable_poses_are_kept_on_disk_by_mesh_content(tmp_path, monkeypatch):
    """A new process (here: a new model of the same mesh) reads the stable poses from the
    disk cache instead of running trimesh again; a model with no cache computes them."""
    first = stable_rotations(_box_model(tmp_path))
    assert len(list(tmp_path.glob("stable1-*.npz"))) == 1

    def refused(*args, **kwargs):
        raise AssertionError("computed again")

    monkeypatch.setattr(trimesh.poses, "compute_stable_poses", refused)
    again = stable_rotations(_box_model(tmp_path))
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    monkeypatch.undo()
    model = _box_model(tmp_path, extents=(4.0, 3.0, 2.0))
    model.cache = ArrayCache(False)  # memory only: computed, nothing stored
    rotations, probabilities = stable_rotations(model)
    assert probabilities.sum() == pytest.approx(1.0) and rotations.shape[1:] == (3, 3)
    assert len(list(tmp_path.glob("stable1-*.npz"))) == 1


def test_the_filter_weighs_down_a_hypothesis_off_the_table(tmp_path):
    model = _box_model(tmp_path)
    library = PriorLibrary([model])
    session = Session(library, scene=Scene.on_table(0.0))
    resting = np.array([0.0, 0.0, 1.0])
    particles = Particles(np.zeros(3, np.int64), np.repeat(np.eye(3)[None], 3, axis=0),
                          np.array([resting, resting + [0, 0, 1.0], resting - [0, 0, 0.5]]),
                          np.zeros(3))
    support = session.filter.log_support(particles)
    assert support[0] == pytest.approx(0.0, abs=1e-9)
    assert support[1] < support[2] < support[0]
    free = Session(library)
    np.testing.assert_array_equal(free.filter.log_support(particles), np.zeros(3))


def test_a_table_contact_is_a_miss_of_the_object(tmp_path):
    library = PriorLibrary([_box_model(tmp_path)])
    session = Session(library, scene=Scene.on_table(0.0, 60.0, 0.1))
    seen = session._seen(Contact([2.0, 3.0, 0.0], [0.0, 0.0, 1.0]))
    assert isinstance(seen, NonContact)
    np.testing.assert_allclose(seen.position, [2.0, 3.0, 0.1])
    wall = Contact([2.0, 3.0, 0.05], [1.0, 0.0, 0.0])  # the object's side near the table
    assert session._seen(wall) is wall


@pytest.mark.parametrize("name, seed", [("mug_1", 11), ("elephant", 12)])
def test_a_session_on_a_table_keeps_to_the_scene_and_stops_by_itself(bundled, name, seed):
    known_library = PriorLibrary(bundled[n] for n in
                                 ("armadillo", "elephant", "mug_1", "bottle_1", "vase_1"))
    scene = Scene.on_table(0.0, 60.0, 0.1)
    truth = make_truth(bundled[name], rng=[seed, 0], scene=scene)
    session = Session.simulated(truth, known_library, params=session_preset("recognise"), seed=seed,
                      scene=scene)
    last = session.run(max_steps=120)
    assert last.terminated and last.step < 120
    for snapshot in session.snapshots:
        for path in snapshot.paths:
            scene.check_path(path, 1e-6)  # every move above the table, inside the cone
        contacts = snapshot.contacts
        assert (scene.height(contacts) > -0.05).all()  # no table contact in the belief
    assert not last.novel and last.map_class == name


def test_resting_seeds_hold_the_true_pose_and_rest_on_the_table(bundled):
    model = bundled["mug_1"]
    scene = Scene.on_table(0.3, 60.0, 0.0)
    truth = make_truth(model, rng=5, scene=scene)
    library = PriorLibrary([model])
    session = Session.simulated(truth, library, scene=scene, seed=5)  # the bank of the one prior
    bank = session.filter.bank
    # A contact at a feature point of the truth, as the first touch would give it.
    point, normal = bank.points[0][17], bank.normals[0][17]
    position = truth.to_world(point[None])[0]
    rotations, translations = seeds_on_table(
        bank.points[0], bank.normals[0], hull_points(model), stable_rotations(model)[0],
        position, truth.rotation @ normal, scene.up, scene.table_point, 0.25, 0.3, 8)
    assert len(rotations) > 0
    gaps = lowest_heights(hull_points(model), rotations, translations, scene.up,
                          scene.table_point)
    np.testing.assert_allclose(gaps, 0.0, atol=1e-9)
    angle = np.degrees(np.arccos(np.clip(
        (np.trace(np.einsum("ij,nkj->nik", truth.rotation, rotations), axis1=1, axis2=2) - 1)
        / 2, -1, 1)))
    offset = np.linalg.norm(translations - truth.translation, axis=1)
    best = int(np.argmin(angle + offset))
    assert angle[best] < 0.5 and offset[best] < 0.02
