import numpy as np
import pytest
import trimesh

from tactile_viz.engine import ObjectModel, PriorLibrary


@pytest.fixture
def sphere_model(tmp_path):
    """A sphere of radius 3 (longest side 6) with a private cache."""
    from tactile_viz.engine.io.cache import ArrayCache

    mesh = trimesh.creation.icosphere(subdivisions=4, radius=3.0)
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, "sphere", cache=ArrayCache(tmp_path),
                                   longest_side=6.0)


@pytest.fixture
def small_library(tmp_path):
    """A saved two-prior library folder and the library itself."""
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    library = PriorLibrary()
    library.add_arrays(box.vertices, box.faces, "box")
    library.add_arrays(cylinder.vertices, cylinder.faces, "cylinder")
    folder = library.save(tmp_path / "library")
    return library, folder


def snapshot(folder):
    """Bytes of every file in a folder, to check that nothing changed."""
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def surface_at(session, snapshot, resolution):
    """``snapshot``'s GPIS surface refitted at ``resolution`` cells, in the lengths of its
    MAP prior (what learning it does)."""
    from tactile_viz.engine.session.learning import surface_at as refitted

    model = session.filter.models[session.filter.class_names.index(snapshot.map_class)]
    return refitted(session.parts(model).estimator, snapshot, resolution)
