"""Shapes and distances the belief tests share."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import ObjectModel, PriorLibrary


@pytest.fixture(scope="session")
def knobbed_shapes(tmp_path_factory):
    """A box 6 x 3 x 2, the same box with a knob on one end, and a cylinder."""
    from tactile_viz.engine.io.cache import ArrayCache

    cache = ArrayCache(tmp_path_factory.mktemp("cache"))
    box = trimesh.creation.box(extents=(6, 3, 2))
    knob = trimesh.creation.box(extents=(0.8, 0.8, 0.8))
    knob.apply_translation([2.0, 0.0, 1.4])
    knobbed = trimesh.util.concatenate([box, knob])  # overlapping parts: united on loading
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    models = [ObjectModel.from_arrays(m.vertices, m.faces, name, cache=cache)
              for m, name in ((box, "box"), (knobbed, "knobbed"), (cylinder, "cylinder"))]
    return PriorLibrary(models)


def box_distance(points, half):
    """A box's exact signed distance and outward unit gradient at ``points (..., 3)``
    (its frame), its half extents ``half`` broadcasting against them."""
    q = np.abs(points) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    values = outside + np.minimum(q.max(axis=-1), 0.0)
    face = np.eye(3)[np.argmax(q, axis=-1)] * np.sign(points)
    corner = np.sign(points) * np.maximum(q, 0.0) / np.maximum(outside, 1e-300)[..., None]
    return values, np.where((outside > 0)[..., None], corner, face)
