"""A prior bank built from meshes (cold) holds what one read from the disk cache (warm), and
child processes build the same cache files as this process."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import LibraryError, ModelParams, ObjectModel
from tactile_viz.engine.belief import prior_build
from tactile_viz.engine.belief.prior_bank import PriorBank
from tactile_viz.engine.belief.prior_build import _reason, build_derived, build_in_child, missing
from tactile_viz.engine.io.cache import ArrayCache

PARAMS = ModelParams(sdf_resolution=24)
BANK_ARRAYS = ("codes", "gradient_codes", "offsets", "shapes", "origins", "spacings",
               "value_steps", "points", "normals", "frames")
PAIR_ARRAYS = ("keys", "starts", "classes", "first", "second")


def _models(folder, params=PARAMS, more=False):
    """Two priors of 1,280 and 128 faces in the cache ``folder`` (fresh models each call);
    ``more``: also a box and a stretched ball."""
    meshes = {"ball": trimesh.creation.icosphere(subdivisions=3, radius=2.0),
              "can": trimesh.creation.cylinder(radius=1.0, height=5.0, sections=32)}
    if more:
        meshes["box"] = trimesh.creation.box((4.0, 2.0, 1.0))
        egg = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        meshes["egg"] = trimesh.Trimesh(egg.vertices * [1.0, 1.5, 2.5], egg.faces)
    return [ObjectModel.from_arrays(mesh.vertices, mesh.faces, name, params=params,
                                    cache=ArrayCache(folder)) for name, mesh in meshes.items()]


def _files(folder):
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


def _assert_same_bank(first, second):
    for name in BANK_ARRAYS:
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)
    for name in PAIR_ARRAYS:
        np.testing.assert_array_equal(getattr(first.pairs, name), getattr(second.pairs, name),
                                      err_msg=name)
    assert first.nbytes == second.nbytes


def test_a_bank_built_from_meshes_holds_what_a_warm_one_does(tmp_path):
    cold_models = _models(tmp_path)
    assert len(missing(cold_models, 0.1, 12.0)) == 2
    cold = PriorBank(cold_models, 0.1, 12.0)  # two priors: built in this process
    assert not missing(cold_models, 0.1, 12.0)
    warm_models = _models(tmp_path)
    warm = PriorBank(warm_models, 0.1, 12.0)
    _assert_same_bank(cold, warm)
    for cold_model, warm_model in zip(cold_models, warm_models):
        assert set(cold_model.__dict__) == set(warm_model.__dict__)
        # Before the features were sampled on a bare copy, trimesh's triangles, cross
        # products and areas stayed on the cold mesh: 4 times the ball's mesh arrays.
        assert cold_model.nbytes == pytest.approx(warm_model.nbytes, rel=0.01)


def test_children_build_the_files_one_process_builds_and_the_bank_reads(tmp_path):
    serial = _models(tmp_path / "serial", more=True)
    for model in serial:  # what a build in this process writes, one prior after another
        build_derived(model, 0.1, 12.0)
    models = _models(tmp_path / "children", more=True)
    assert build_in_child(models, 0.1, 12.0, minimum=5) == 0  # too few: not started
    done = []
    assert build_in_child(models, 0.1, 12.0, minimum=1, workers=2,
                          progress=lambda items: (done.append(i) or i for i in items)) == 4
    assert sorted(done) == [0, 1, 2, 3]  # one item as each prior was built
    assert not missing(models, 0.1, 12.0)
    assert "features" not in models[0].__dict__  # nothing was built here
    files = _files(tmp_path / "children")
    assert len(files) == 4 * 5 and files == _files(tmp_path / "serial")  # byte for byte
    assert build_in_child(models, 0.1, 12.0, minimum=1) == 0  # nothing left to build
    _assert_same_bank(PriorBank(models, 0.1, 12.0), PriorBank(serial, 0.1, 12.0))


def test_a_failing_child_says_which_prior_and_why_in_one_line(tmp_path):
    broken = ModelParams(sdf_resolution=24, n_features=0)
    models = [_models(tmp_path)[1], _models(tmp_path, broken)[0]]  # the can, then the ball
    with pytest.raises(LibraryError) as raised:
        build_in_child(models, 0.1, 12.0, minimum=1, workers=2)
    message = str(raised.value)
    assert "\n" not in message and "prior 'ball': ValueError" in message
    assert message.startswith("building the grids of 2 priors in 2 child processes failed: ")
    assert not missing(models[:1], 0.1, 12.0)  # the other child finished its prior


def test_a_child_that_stops_without_a_word_is_named_by_its_prior():
    assert _reason("can", -9, []) == "prior 'can': it was killed by signal 9 (out of memory?)"
    assert _reason("can", 1, []) == "prior 'can': it stopped with status 1"
    assert _reason("can", 1, ["Traceback ...", "ImportError: no numpy"]) == (
        "prior 'can': ImportError: no numpy")
    assert _reason("can", 1, ["prior 'can': ValueError: bad"]) == "prior 'can': ValueError: bad"


def test_a_disabled_disk_cache_builds_in_this_process():
    models = _models(False)
    assert missing(models, 0.1, 12.0) == []
    assert build_in_child(models, 0.1, 12.0, minimum=1) == 0


def test_one_child_a_core_as_memory_allows(monkeypatch):
    monkeypatch.setattr(prior_build.os, "cpu_count", lambda: 8)
    monkeypatch.setattr(prior_build, "_available_bytes", lambda: 10 * prior_build.CHILD_BYTES)
    assert [prior_build.default_workers(n) for n in (1, 5, 78)] == [1, 5, 8]
    monkeypatch.setattr(prior_build, "_available_bytes", lambda: 2.5 * prior_build.CHILD_BYTES)
    assert prior_build.default_workers(78) == 2
    monkeypatch.setattr(prior_build, "_available_bytes", lambda: 0.0)
    assert prior_build.default_workers(78) == 1
    monkeypatch.setattr(prior_build, "_available_bytes", lambda: None)  # not Linux
    assert prior_build.default_workers(78) == 8


def test_a_priors_inertia_is_built_once_and_read_from_the_disk_cache(tmp_path, monkeypatch):
    model = _models(tmp_path, more=True)[2]  # the 4 x 2 x 1 box
    axes, moments, centre = model.inertia
    box = trimesh.creation.box((4.0, 2.0, 1.0))
    np.testing.assert_allclose(np.abs(axes), np.abs(box.principal_inertia_vectors), atol=1e-9)
    np.testing.assert_allclose(moments, box.principal_inertia_components, rtol=1e-9)
    np.testing.assert_allclose(centre, np.zeros(3), atol=1e-9)
    again = _models(tmp_path, more=True)[2]
    monkeypatch.setattr(type(again), "_build_inertia", lambda self: 1 / 0)
    for first, second in zip(model.inertia, again.inertia):
        np.testing.assert_array_equal(first, second)
