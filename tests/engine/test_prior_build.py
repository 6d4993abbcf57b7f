"""A prior bank built from meshes (cold) holds what one read from the disk cache (warm)."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import LibraryError, ModelParams, ObjectModel
from tactile_viz.engine.io.cache import ArrayCache
from tactile_viz.engine.belief.prior_bank import PriorBank
from tactile_viz.engine.belief.prior_build import build_in_child, missing

PARAMS = ModelParams(sdf_resolution=24)
BANK_ARRAYS = ("codes", "gradient_codes", "offsets", "shapes", "origins", "spacings",
               "value_steps", "points", "normals", "frames")
PAIR_ARRAYS = ("keys", "starts", "classes", "first", "second")


def _models(folder, params=PARAMS):
    """Two priors of 1,280 and 128 faces in the cache ``folder`` (fresh models each call)."""
    meshes = {"ball": trimesh.creation.icosphere(subdivisions=3, radius=2.0),
              "can": trimesh.creation.cylinder(radius=1.0, height=5.0, sections=32)}
    return [ObjectModel.from_arrays(mesh.vertices, mesh.faces, name, params=params,
                                    cache=ArrayCache(folder)) for name, mesh in meshes.items()]


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


def test_the_child_builds_what_the_bank_then_reads(tmp_path):
    models = _models(tmp_path / "child")
    assert build_in_child(models, 0.1, 12.0, minimum=3) == 0  # too few: not started
    assert build_in_child(models, 0.1, 12.0, minimum=1) == 2
    assert not missing(models, 0.1, 12.0)
    assert "features" not in models[0].__dict__  # nothing was built here
    assert build_in_child(models, 0.1, 12.0, minimum=1) == 0  # nothing left to build
    here = PriorBank(_models(tmp_path / "here"), 0.1, 12.0)
    _assert_same_bank(PriorBank(models, 0.1, 12.0), here)


def test_a_failing_child_says_which_prior_and_why_in_one_line(tmp_path):
    models = _models(tmp_path, ModelParams(sdf_resolution=24, n_features=0))
    with pytest.raises(LibraryError) as raised:
        build_in_child(models, 0.1, 12.0, minimum=1)
    message = str(raised.value)
    assert "\n" not in message and "prior 'ball': ValueError" in message
    assert message.startswith("building the grids of 2 priors in a child process failed")


def test_a_disabled_disk_cache_builds_in_this_process():
    models = _models(False)
    assert missing(models, 0.1, 12.0) == []
    assert build_in_child(models, 0.1, 12.0, minimum=1) == 0
