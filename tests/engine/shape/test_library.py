import json

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import LibraryError, ObjectModel, PriorLibrary, bundled_names

from ..conftest import snapshot


def test_save_and_load_round_trip(small_library):
    library, folder = small_library
    loaded = PriorLibrary.load(folder)
    assert loaded.names == library.names
    for name in library.names:
        np.testing.assert_array_equal(loaded[name].mesh.vertices, library[name].mesh.vertices)
        np.testing.assert_array_equal(loaded[name].mesh.faces, library[name].mesh.faces)
        assert loaded[name].content_hash == library[name].content_hash


def test_extend_from_file_and_arrays_then_save(small_library, tmp_path):
    library, folder = small_library
    path = tmp_path / "ball.obj"
    trimesh.creation.icosphere(2).export(path)
    library.add_file(path)
    cone = trimesh.creation.cone(radius=1.0, height=3.0)
    library.add_arrays(cone.vertices, cone.faces, "cone")
    library.save(folder)
    assert PriorLibrary.load(folder).names == ["box", "cylinder", "ball", "cone"]
    assert len(list(folder.glob("*.ply"))) == 4


def test_a_learned_prior_stays_learned_through_save_and_load(small_library, tmp_path):
    library, folder = small_library
    cone = trimesh.creation.cone(radius=1.0, height=3.0)
    library.add_arrays(cone.vertices, cone.faces, "learned cone", learned=True,
                       shape_error=0.03, normal_error=0.4)
    library.save(folder)
    loaded = PriorLibrary.load(folder)
    assert [loaded[name].learned for name in loaded.names] == [False, False, True]
    assert loaded["learned cone"].renamed("again").learned
    # Its own error travels with it (in its units) and a given mesh has none.
    assert loaded["learned cone"].renamed("again").shape_error == pytest.approx(0.03)
    assert loaded["box"].shape_error == 0.0
    assert loaded["learned cone"].renamed("again").normal_error == pytest.approx(0.4)
    assert loaded["box"].normal_error == 0.0


def test_names_are_unique(small_library):
    library, _ = small_library
    with pytest.raises(LibraryError, match="already has"):
        library.add(library["box"].renamed("cylinder"))
    library.add(library["box"].renamed("cylinder"), replace=True)
    assert library.names == ["box", "cylinder"]


def test_remove_and_missing_name(small_library):
    library, _ = small_library
    library.remove("box")
    assert library.names == ["cylinder"]
    with pytest.raises(LibraryError, match="no prior named 'box'"):
        library["box"]


def test_bundled_sets():
    known = PriorLibrary.bundled("known")
    assert len(known) == 10 and set(known.names) == set(bundled_names("known"))
    assert len(bundled_names("novel")) == 10


@pytest.mark.parametrize("damage, reason", [
    (lambda folder: (folder / "library.json").write_text('{"format": "tactile'), "corrupt"),
    (lambda folder: (folder / "library.json").unlink(), "no library.json"),
    (lambda folder: (folder / "library.json").write_text('{"format": "other", "objects": []}'),
     "not a tactile_viz library"),
    (lambda folder: next(folder.glob("box-*.ply")).unlink(), "cannot be read"),
    (lambda folder: next(folder.glob("box-*.ply")).write_bytes(b"ply\nformat binary"), "corrupt"),
    (lambda folder: (folder / "library.json").write_text(json.dumps(
        {"format": "tactile_viz-prior-library", "objects": [{"name": "x", "file": "../x.ply",
                                                            "sha256": "0"}]})), "outside"),
])
def test_corrupt_library_raises_library_error(small_library, damage, reason):
    _, folder = small_library
    damage(folder)
    with pytest.raises(LibraryError, match=reason):
        PriorLibrary.load(folder)


def test_missing_folder(tmp_path):
    with pytest.raises(LibraryError, match="does not exist"):
        PriorLibrary.load(tmp_path / "nowhere")


def test_interrupted_save_keeps_last_good_library(small_library, monkeypatch):
    library, folder = small_library
    before = snapshot(folder)
    cone = trimesh.creation.cone(radius=1.0, height=3.0)
    library.add(ObjectModel.from_arrays(cone.vertices, cone.faces, "cone"))

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("tactile_viz.engine.shape.library.write_atomic", fail)
    with pytest.raises(LibraryError, match="disk full"):
        library.save(folder)
    assert snapshot(folder) == before
    assert PriorLibrary.load(folder).names == ["box", "cylinder"]


def test_a_marked_learned_file_carries_its_own_errors(tmp_path):
    """A learned shape written with its own errors in the PLY header loads with them (the
    shape error scaled with the file's unit); a bad value is one clear error."""
    from tactile_viz.engine.errors import MeshError
    from tactile_viz.engine.shape.objects import ObjectModel, file_own_errors, mark_learned

    cone = trimesh.creation.cone(radius=1.0, height=3.0)
    path = tmp_path / "cone.ply"
    path.write_bytes(mark_learned(cone.export(file_type="ply"),
                                  {"shape_error": 0.03, "normal_error": 0.4}))
    assert file_own_errors(path) == {"shape_error": 0.03, "normal_error": 0.4}
    model = ObjectModel.from_file(path, scale=0.001)
    assert model.learned
    assert model.own_errors() == pytest.approx({"shape_error": 3e-5, "normal_error": 0.4})
    path.write_bytes(mark_learned(cone.export(file_type="ply"), {"shape_error": -1.0}))
    with pytest.raises(MeshError, match="shape_error"):
        ObjectModel.from_file(path)
