import numpy as np
import pytest
import trimesh

from tactile_viz.engine import (
    MeshError,
    MeshWarning,
    ObjectModel,
    PriorLibrary,
    load_mesh,
    prepare_mesh,
)
from tactile_viz.engine.shape.meshes import content_hash

from ..conftest import snapshot


def _sphere():
    return trimesh.creation.icosphere(subdivisions=3, radius=1.7)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl", ".off", ".glb"])
def test_every_format_loads_normalised(tmp_path, suffix):
    mesh = trimesh.creation.box(extents=(1.0, 2.0, 4.0))
    mesh.apply_translation([10.0, -3.0, 2.0])
    path = tmp_path / f"box{suffix}"
    mesh.export(path)
    loaded = load_mesh(path, longest_side=6.0)
    assert loaded.is_watertight and loaded.volume > 0
    np.testing.assert_allclose(loaded.extents, [1.5, 3.0, 6.0], atol=1e-6)
    np.testing.assert_allclose(loaded.bounds.mean(axis=0), 0.0, atol=1e-6)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_normalisation_removes_scale(scale):
    mesh = _sphere()
    normalised = prepare_mesh(mesh.vertices * scale + 5 * scale, mesh.faces, longest_side=6.0)
    assert normalised.extents.max() == pytest.approx(6.0)
    np.testing.assert_allclose(normalised.bounds.mean(axis=0), 0.0, atol=1e-6)
    reference = prepare_mesh(mesh.vertices, mesh.faces, longest_side=6.0)
    np.testing.assert_allclose(normalised.vertices, reference.vertices, atol=1e-6)


def test_inverted_and_duplicated_faces_are_repaired():
    mesh = _sphere()
    faces = np.vstack([mesh.faces[:, ::-1], mesh.faces[:10, ::-1]])
    repaired = prepare_mesh(mesh.vertices, faces)
    assert repaired.is_watertight and repaired.volume > 0
    assert len(repaired.faces) == len(mesh.faces)


def test_small_hole_is_closed():
    mesh = _sphere()
    repaired = prepare_mesh(mesh.vertices, mesh.faces[3:])
    assert repaired.is_watertight and repaired.volume > 0


def test_content_hash_depends_on_geometry():
    mesh = _sphere()
    a = prepare_mesh(mesh.vertices, mesh.faces)
    b = prepare_mesh(mesh.vertices * [1.0, 1.0, 0.9], mesh.faces)
    assert content_hash(a) == content_hash(prepare_mesh(mesh.vertices, mesh.faces))
    assert content_hash(a) != content_hash(b)


def _write_nan_obj(path):
    mesh = _sphere()
    lines = [f"v {x} {y} {z}" for x, y, z in mesh.vertices]
    lines[5] = "v nan 0.0 1.0"
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    path.write_text("\n".join(lines) + "\n")


def _write_open_cylinder(path):
    mesh = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=32)
    keep = mesh.triangles_center[:, 2] < 0.99  # drop the whole top cap
    trimesh.Trimesh(mesh.vertices, mesh.faces[keep]).export(path)


def _write_flat_sheet(path):
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                    [[0, 1, 2], [0, 2, 3]]).export(path)


def _write_non_manifold(path):
    box = trimesh.creation.box()
    fin = trimesh.Trimesh(np.vstack([box.vertices, [[3.0, 3.0, 3.0]]]),
                          np.vstack([box.faces, [[box.faces[0][0], box.faces[0][1], 8]]]))
    fin.export(path)


BAD_FILES = {
    "empty.stl": (lambda p: p.write_bytes(b""), "empty"),
    "garbage.ply": (lambda p: p.write_bytes(bytes(range(256)) * 40), "cannot be read"),
    "garbage.obj": (lambda p: p.write_bytes(b"\x00\xff\x13garbage" * 100), "no triangles"),
    "truncated.stl": (lambda p: p.write_bytes(_sphere().export(file_type="stl")[:300]),
                      "truncated"),
    "truncated.ply": (lambda p: p.write_bytes(_sphere().export(file_type="ply")[:700]),
                      "cannot be read"),
    "nan.obj": (_write_nan_obj, "not finite"),
    "open.stl": (_write_open_cylinder, "open hole"),
    "sheet.obj": (_write_flat_sheet, "hole"),
    "mesh.xyz": (lambda p: p.write_text("1 2 3\n"), "unsupported file type"),
}


@pytest.mark.parametrize("filename", sorted(BAD_FILES))
def test_bad_files_raise_one_clear_error(tmp_path, filename, small_library):
    library, folder = small_library
    before = snapshot(folder)
    write, reason = BAD_FILES[filename]
    path = tmp_path / filename
    write(path)
    with pytest.raises(MeshError) as raised:
        library.add_file(path)
    message = str(raised.value)
    assert filename in message and reason in message
    assert library.names == ["box", "cylinder"]
    assert snapshot(folder) == before
    assert PriorLibrary.load(folder).names == ["box", "cylinder"]


def test_a_fin_on_an_edge_is_split_off_with_a_warning(tmp_path):
    path = tmp_path / "fin.ply"
    _write_non_manifold(path)
    with pytest.warns(MeshWarning, match="fin.ply: repaired on loading: 1 non-manifold edge "
                                         "split; 1 open piece dropped"):
        mesh = load_mesh(path)
    assert mesh.is_watertight and mesh.volume == pytest.approx(1.0)


def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match="no such file"):
        ObjectModel.from_file(tmp_path / "nothing.obj")


@pytest.mark.parametrize("vertices, faces, reason", [
    (np.zeros((0, 3)), np.zeros((0, 3), int), "shape"),
    (np.zeros((4, 2)), [[0, 1, 2]], "shape"),
    (np.ones((4, 3)), [[0, 1, 2], [0, 2, 3]], "coincide"),
    (np.eye(3), [[0, 1, 5]], "do not exist"),
    (np.eye(3), [[0.0, 1.0, 2.0]], "integer"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], "degenerate"),
])
def test_bad_arrays(vertices, faces, reason):
    with pytest.raises(MeshError, match=reason):
        prepare_mesh(vertices, faces, source="arrays")
