"""The Screened Poisson baseline: a sphere from oriented points; the missing-extra message."""

import sys

import numpy as np
import pytest

from tactile_viz.experiments import poisson


def sphere_points(count, radius, rng):
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return radius * directions, directions


@pytest.mark.slow
def test_sphere_is_reconstructed():
    pytest.importorskip("pymeshlab")
    rng = np.random.default_rng(0)
    points, normals = sphere_points(300, 3.0, rng)
    truth, _ = sphere_points(3000, 3.0, rng)
    vertices, faces = poisson.screened_poisson(points, normals, depth=6)
    assert len(faces) > 100
    radii = np.linalg.norm(vertices, axis=1)
    assert np.all(np.abs(radii - 3.0) < 0.2)
    result = poisson.poisson_error(points, normals, truth, samples=2000, depth=6)
    assert result["recon_error"] < 0.4


def test_too_few_points_give_an_empty_surface():
    pytest.importorskip("pymeshlab")
    result = poisson.poisson_error(np.zeros((2, 3)), np.eye(3)[:2], np.zeros((5, 3)))
    assert result["recon_error"] is None and result["n_faces"] == 0


def test_missing_pymeshlab_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pymeshlab", None)  # import raises ImportError
    with pytest.raises(poisson.MissingDependency, match=r"tactile_viz\[bench\]"):
        poisson.require_poisson()
