"""Fuzzing the readers with hypothesis: the mesh loader, the prior-library reader and the
session reader. Whatever the bytes, nothing escapes but the project's own errors
(:class:`~tactile_viz.engine.errors.TactileVizError` subclasses), and what loads is usable.

Each test is bounded (``max_examples``, no deadline) so the module takes about 12 s.
"""

import hashlib
import io
import json
import warnings

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings, strategies as st

from tactile_viz.engine import (
    LibraryError,
    MeshError,
    ObjectModel,
    PriorLibrary,
    TactileVizError,
    load_mesh,
    prepare_mesh,
)
from tactile_viz.engine.session import Session, SessionError, make_truth

FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


def _seed_files():
    """Small valid files of every supported format (the starting points of mutation)."""
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    return {
        ".obj": mesh.export(file_type="obj").encode(),
        ".ply": mesh.export(file_type="ply", encoding="binary"),
        ".ply ascii": mesh.export(file_type="ply", encoding="ascii"),
        ".stl": mesh.export(file_type="stl"),
        ".stl ascii": mesh.export(file_type="stl_ascii").encode(),
        ".off": mesh.export(file_type="off").encode(),
        ".glb": mesh.export(file_type="glb"),
    }


SEEDS = _seed_files()


@st.composite
def mutated(draw, seed_data):
    """Bytes of a valid file changed by truncation, byte flips, insertions and deletions."""
    data = bytearray(seed_data)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete", "digits"]))
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        if kind == "truncate":
            del data[at:]
        elif kind == "flip":
            data[at] = draw(st.integers(0, 255))
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif kind == "delete":
            del data[at:at + draw(st.integers(1, 64))]
        else:  # numbers in text formats: change one digit into something odd
            data[at:at + 1] = draw(st.sampled_from([b"nan", b"-", b"1e309", b"9" * 12, b" ",
                                                    b"\n", b"0"]))
    return bytes(data)


def _check_loaded_mesh(mesh):
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.extents.max() == pytest.approx(6.0)
    assert np.all(np.isfinite(mesh.vertices))


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(SEEDS))
@FUZZ
@given(data=st.data())
def test_mesh_loader_on_mutated_files(tmp_path, kind, data):
    content = data.draw(mutated(SEEDS[kind]))
    path = tmp_path / f"fuzzed{kind.split()[0]}"
    path.write_bytes(content)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trimesh may warn about odd files
        try:
            mesh = load_mesh(path, longest_side=6.0)
        except MeshError as error:
            assert "fuzzed" in str(error)
            return
    _check_loaded_mesh(mesh)


@settings(max_examples=200, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.binary(max_size=600),
       suffix=st.sampled_from([".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".xyz", ""]))
def test_mesh_loader_on_random_bytes(tmp_path, content, suffix):
    path = tmp_path / f"random{suffix}"
    path.write_bytes(content)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = load_mesh(path, longest_side=6.0)
        except MeshError as error:
            assert "random" in str(error)
            return
    _check_loaded_mesh(mesh)


@FUZZ
@given(vertices=st.lists(st.tuples(*[st.sampled_from([0.0, 1.0, -1.0, 2.0, 0.5, 1e-9, 1e9,
                                                       float("nan")])] * 3),
                         min_size=0, max_size=10),
       faces=st.lists(st.tuples(*[st.integers(-2, 11)] * 3), min_size=0, max_size=16))
def test_prepare_mesh_on_random_arrays(vertices, faces):
    try:
        mesh = prepare_mesh(np.array(vertices, dtype=float).reshape(-1, 3),
                            np.array(faces, dtype=np.int64).reshape(-1, 3), source="fuzzed")
    except MeshError as error:
        assert "fuzzed" in str(error)
        return
    _check_loaded_mesh(mesh)


# ----------------------------------------------------------------- library folders
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-5, 5) | st.floats(allow_nan=True)
    | st.text(max_size=8) | st.sampled_from(["tactile_viz-prior-library", "box.ply"]),
    lambda children: st.lists(children, max_size=3)
    | st.dictionaries(st.sampled_from(["format", "version", "objects", "name", "file",
                                       "sha256"]), children, max_size=4),
    max_leaves=12)


@FUZZ
@given(manifest=json_values)
def test_library_reader_on_random_manifests(small_library, manifest):
    _, folder = small_library
    (folder / "library.json").write_text(json.dumps(manifest))
    with pytest.raises(LibraryError, match="library"):
        PriorLibrary.load(folder)


@pytest.mark.slow
@FUZZ
@given(data=st.data())
def test_library_reader_on_mutated_meshes_with_matching_checksums(small_library, data):
    """Mutate a prior's PLY file and update its checksum, as a hand edit would: the reader
    must still refuse bad meshes with a LibraryError (or load a usable model)."""
    _, folder = small_library
    originals = {path: path.read_bytes() for path in folder.iterdir()}
    manifest = json.loads((folder / "library.json").read_text())
    entry = manifest["objects"][0]
    path = folder / entry["file"]
    content = data.draw(mutated(path.read_bytes()))
    path.write_bytes(content)
    entry["sha256"] = hashlib.sha256(content).hexdigest()
    (folder / "library.json").write_text(json.dumps(manifest))
    try:
        library = PriorLibrary.load(folder)
    except LibraryError as error:
        assert entry["file"] in str(error)
        return
    finally:  # the next example starts from the same folder
        for original, saved in originals.items():
            original.write_bytes(saved)
    mesh = library[entry["name"]].mesh
    assert len(mesh.faces) and np.all(np.isfinite(mesh.vertices))
    assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)


# ----------------------------------------------------------------- session files
@pytest.fixture(scope="module")
def session_file(tmp_path_factory):
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    library = PriorLibrary([ObjectModel.from_arrays(box.vertices, box.faces, "box"),
                            ObjectModel.from_arrays(cylinder.vertices, cylinder.faces,
                                                    "cylinder")])
    session = Session.simulated(make_truth(library["box"], rng=0), library, seed=0)
    session.run(max_steps=1)
    path = session.save(tmp_path_factory.mktemp("fuzz") / "session.npz")
    with np.load(path) as stored:
        arrays = {name: stored[name] for name in stored.files}
    return path.read_bytes(), arrays


def _load_session(path):
    try:
        session = Session.load(path)
    except SessionError as error:
        assert path.name in str(error)
        return None
    assert session.step_count <= 1
    return session


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_session_reader_on_mutated_bytes(tmp_path, session_file, data):
    content = data.draw(mutated(session_file[0]))
    path = tmp_path / "fuzzed.npz"
    path.write_bytes(content)
    _load_session(path)


small_arrays = st.one_of(
    st.just(np.zeros((0, 3))), st.just(np.zeros((3,))), st.just(np.full((4, 3), np.nan)),
    st.just(np.eye(3)), st.just(np.array([[0, 1, 2], [0, 2, 3]])), st.just(np.array(["a"])),
    st.just(np.array([[-1, 0, 1]])), st.just(np.array([[0.5, 1.5, 2.5]])),
    st.just(np.ones((2, 2, 2))), st.just(np.array(7)))


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(replaced=st.dictionaries(
    st.sampled_from(["truth_rotation", "truth_translation", "truth_vertices", "truth_faces",
                     "prior0_vertices", "prior0_faces", "prior1_faces", "contacts",
                     "noncontacts"]), small_arrays, min_size=1, max_size=3),
       config=st.dictionaries(st.sampled_from(["steps", "seed", "strategy", "sensor_noise",
                                               "library", "truth_name", "params", "format"]),
                              json_values, max_size=2))
def test_session_reader_on_wrong_arrays_and_config(tmp_path, session_file, replaced, config):
    _, arrays = session_file
    arrays = dict(arrays, **replaced)
    stored = json.loads(arrays["config"].tobytes())
    stored.update(config)
    arrays["config"] = np.frombuffer(json.dumps(stored).encode(), dtype=np.uint8)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path = tmp_path / "fuzzed.npz"
    path.write_bytes(buffer.getvalue())
    try:
        _load_session(path)
    except TactileVizError as error:  # pragma: no cover - shown with its type on failure
        pytest.fail(f"{type(error).__name__} instead of SessionError: {error}")
