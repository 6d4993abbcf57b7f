"""Sessions and prior libraries on disk: corrupt files, out-of-range parameters and writes
killed midway.

Every corrupt file gives one error of the project's own type that names the file and the
fault; a write that fails or is killed (SIGKILL, in a subprocess) leaves the last good file
loadable.
"""

import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import (
    LibraryError,
    ObjectModel,
    ParameterError,
    PriorLibrary,
    TactileVizError,
)
from tactile_viz.engine.session import Session, SessionError, SessionParams, make_truth

from ..conftest import snapshot


@pytest.fixture(scope="module")
def shapes():
    box = trimesh.creation.box(extents=(6, 3, 2))
    cylinder = trimesh.creation.cylinder(radius=1.5, height=6, sections=48)
    return PriorLibrary([ObjectModel.from_arrays(box.vertices, box.faces, "box"),
                         ObjectModel.from_arrays(cylinder.vertices, cylinder.faces, "cylinder")])


@pytest.fixture(scope="module")
def saved_session(shapes, tmp_path_factory):
    """A two-step session on the cylinder, saved; and its arrays and config."""
    session = Session.simulated(make_truth(shapes["cylinder"], rng=0), shapes, seed=0)
    session.run(max_steps=2)
    path = session.save(tmp_path_factory.mktemp("session") / "good.npz")
    with np.load(path) as stored:
        arrays = {name: stored[name] for name in stored.files}
    return path, arrays, json.loads(arrays["config"].tobytes())


def _write_session(path, arrays, new_config=None, **changes):
    arrays = dict(arrays, **changes)
    if new_config is not None:
        arrays["config"] = np.frombuffer(json.dumps(new_config).encode(), dtype=np.uint8)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    return path


# ----------------------------------------------------------------- session files
def test_every_truncation_of_a_session_file_is_a_session_error(saved_session, tmp_path):
    good, _, _ = saved_session
    data = good.read_bytes()
    path = tmp_path / "cut.npz"
    for length in np.unique(np.linspace(0, len(data) - 1, 25).astype(int)):
        path.write_bytes(data[:length])
        with pytest.raises(SessionError, match="cut.npz"):
            Session.load(path)


def _config_change(key, value):
    def change(config):
        return dict(config, **{key: value})
    return change


def _params_change(key, value):
    def change(config):
        return dict(config, params=dict(config["params"], **{key: value}))
    return change


CORRUPT_CONFIGS = {
    "steps negative": (_config_change("steps", -1), "steps"),
    "steps beyond the cap": (_config_change("steps", 10**9), "steps"),
    "steps a string": (_config_change("steps", "2"), "steps"),
    "eps zero": (_params_change("eps", 0.0), "eps"),
    "eps a list": (_params_change("eps", [0.6]), "eps"),
    "params a list": (_config_change("params", [1, 2]), "must be a dict"),
    "unknown strategy": (_config_change("strategy", "teleport"), "strategy"),
    "noise not finite": (_config_change("sensor_noise", [float("nan"), 0.0]), "position_noise"),
    "negative seed": (_config_change("seed", -3), "not a readable session file"),
    "library not a list": (_config_change("library", 5), "not a readable session file"),
    "truth name a number": (_config_change("truth_name", 7), "name"),
    "own errors a list": (_config_change("own_errors", [0.1]), "own errors"),
    "own error unknown": (_config_change("own_errors", {"a": {"size": 1.0}}), "own errors"),
    "own error negative": (_config_change("own_errors", {"a": {"shape_error": -1.0}}),
                           "shape_error"),
    "own error not finite": (_config_change("own_errors", {"a": {"normal_error": None}}),
                             "normal_error"),
    "no format": (lambda config: {k: v for k, v in config.items() if k != "format"},
                  "not a tactile_viz session file"),
}


@pytest.mark.parametrize("case", sorted(CORRUPT_CONFIGS))
def test_corrupt_session_configs(saved_session, tmp_path, case):
    _, arrays, config = saved_session
    change, reason = CORRUPT_CONFIGS[case]
    path = _write_session(tmp_path / "bad.npz", arrays, change(config))
    with pytest.raises(SessionError, match="bad.npz") as raised:
        Session.load(path)
    assert reason in str(raised.value)


def _corrupt_arrays(arrays):
    faces, vertices = arrays["truth_faces"], arrays["truth_vertices"]
    nan_vertices = vertices.copy()
    nan_vertices[3] = np.nan
    return {
        "faces out of range": (dict(truth_faces=faces + len(vertices)), "do not exist"),
        "negative faces": (dict(prior0_faces=-np.ones_like(faces)), "do not exist"),
        "float faces": (dict(truth_faces=faces + 0.5), "integer"),
        "NaN vertices": (dict(truth_vertices=nan_vertices), "not finite"),
        "flat vertices": (dict(truth_vertices=vertices[:, :2]), "shape"),
        "no faces": (dict(prior1_faces=np.zeros((0, 3), dtype=np.int64)), "shape"),
        "rotation not a rotation": (dict(truth_rotation=2 * np.eye(3)), "not a rotation"),
        "rotation wrong shape": (dict(truth_rotation=np.eye(2)), "shapes"),
        "translation not finite": (dict(truth_translation=np.array([0, np.inf, 0])),
                                   "not finite"),
        "contacts wrong shape": (dict(contacts=np.zeros(5)), "did not reproduce"),
        "contacts moved": (dict(contacts=arrays["contacts"] + 1.0), "did not reproduce"),
        "config not text": (dict(config=np.array([0xff, 0xfe], dtype=np.uint8)),
                            "not a readable session file"),
    }


@pytest.mark.parametrize("case", [
    "faces out of range", "negative faces", "float faces", "NaN vertices", "flat vertices",
    "no faces", "rotation not a rotation", "rotation wrong shape", "translation not finite",
    "contacts wrong shape", "contacts moved", "config not text"])
def test_corrupt_session_arrays(saved_session, tmp_path, case):
    _, arrays, _ = saved_session
    changes, reason = _corrupt_arrays(arrays)[case]
    path = _write_session(tmp_path / "bad.npz", arrays, **changes)
    with pytest.raises(SessionError, match="bad.npz") as raised:
        Session.load(path)
    assert reason in str(raised.value)


def test_missing_array_in_session_file(saved_session, tmp_path):
    _, arrays, _ = saved_session
    path = tmp_path / "bad.npz"
    np.savez(path, **{k: v for k, v in arrays.items() if k != "truth_rotation"})
    with pytest.raises(SessionError, match="bad.npz.*truth_rotation"):
        Session.load(path)


# ----------------------------------------------------------------- session parameters
@pytest.mark.parametrize("changes, field", [
    (dict(eps=0.0), "eps"), (dict(eps=-0.6), "eps"), (dict(eps=float("nan")), "eps"),
    (dict(eps="0.6"), "eps"), (dict(gpis_noise=0.0), "gpis_noise"),
    (dict(gpis_scale=float("inf")), "gpis_scale"), (dict(max_steps_known=0), "max_steps_known"),
    (dict(variance_points=1.5), "variance_points"), (dict(gpis_resolution=4), "gpis_resolution"),
    (dict(filter={"sigma_d": 0.5}), "filter"),
])
def test_out_of_range_session_parameters_name_the_parameter(changes, field):
    with pytest.raises(ParameterError, match=field) as raised:
        SessionParams(**changes)
    assert isinstance(raised.value, (TactileVizError, ValueError))


def test_session_parameters_from_bad_dicts():
    with pytest.raises(ParameterError, match="unknown session parameter"):
        SessionParams.from_dict({"epsilon": 0.6})
    with pytest.raises(ParameterError, match="sigma_d"):
        SessionParams.from_dict({"filter": {"sigma_d": -1}})
    with pytest.raises(ParameterError, match="must be a dict"):
        SessionParams.from_dict([("eps", 0.6)])
    assert SessionParams.from_dict({"eps": 0.3, "max_steps_known": 50.0}).max_steps_known == 50


# ----------------------------------------------------------------- library folders
def test_every_truncation_of_a_manifest_is_a_library_error(small_library):
    _, folder = small_library
    manifest = (folder / "library.json").read_bytes()
    for length in range(0, len(manifest) - 1, max(1, len(manifest) // 40)):
        (folder / "library.json").write_bytes(manifest[:length])
        with pytest.raises(LibraryError, match="library"):
            PriorLibrary.load(folder)


@pytest.mark.parametrize("manifest", [
    [], "a string", 42, None, {"format": "tactile_viz-prior-library"},
    {"format": "tactile_viz-prior-library", "objects": {"box": "box.ply"}},
    {"format": "tactile_viz-prior-library", "objects": [["box", "box.ply", "0"]]},
    {"format": "tactile_viz-prior-library", "objects": [{"name": 1, "file": "a", "sha256": "0"}]},
    {"format": "tactile_viz-prior-library", "objects": [{"name": "a", "file": "/etc/passwd",
                                                         "sha256": "0"}]},
    {"format": ["tactile_viz-prior-library"], "objects": []},
])
def test_manifests_of_the_wrong_shape(small_library, manifest):
    _, folder = small_library
    (folder / "library.json").write_text(json.dumps(manifest))
    with pytest.raises(LibraryError, match="library.json"):
        PriorLibrary.load(folder)


def _ply(vertices, faces):
    return trimesh.Trimesh(vertices, faces, process=False).export(file_type="ply",
                                                                  encoding="ascii")


@pytest.mark.parametrize("case", ["NaN vertices", "faces out of range", "no faces"])
def test_mesh_with_a_valid_checksum_but_bad_arrays(small_library, case):
    """A hand-edited library (checksum updated): the arrays are still checked, so libigl
    never sees indices out of range or NaN."""
    import hashlib

    _, folder = small_library
    box = trimesh.creation.box()
    vertices, faces = box.vertices.copy(), box.faces.copy()
    if case == "NaN vertices":
        vertices[0] = np.nan
        data = _ply(vertices, faces)
    elif case == "faces out of range":
        data = _ply(vertices, faces).replace(b"\n3 0 ", b"\n3 99 ", 1)
    else:
        data = b"ply\nformat ascii 1.0\nelement vertex 0\nend_header\n"
    path = next(folder.glob("box-*.ply"))
    path.write_bytes(data)
    manifest = json.loads((folder / "library.json").read_text())
    for entry in manifest["objects"]:
        if entry["file"] == path.name:
            entry["sha256"] = hashlib.sha256(data).hexdigest()
    (folder / "library.json").write_text(json.dumps(manifest))
    with pytest.raises(LibraryError, match=path.name):
        PriorLibrary.load(folder)


# ----------------------------------------------------------------- failed writes
def test_session_save_failing_midway_keeps_the_last_good_file(saved_session, shapes, tmp_path,
                                                              monkeypatch):
    good, _, _ = saved_session
    path = tmp_path / "trial.npz"
    path.write_bytes(good.read_bytes())
    session = Session.simulated(make_truth(shapes["box"], rng=1), shapes, seed=1)
    session.run(max_steps=1)

    def fail(*args):
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", fail)  # after the temporary file is written
    with pytest.raises(SessionError, match="disk full"):
        session.save(path)
    monkeypatch.undo()
    assert path.read_bytes() == good.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ["trial.npz"]  # no temporary left
    assert Session.load(path).step_count == 2


def test_library_save_failing_at_the_manifest_keeps_the_last_good_library(small_library,
                                                                          monkeypatch):
    library, folder = small_library
    before = snapshot(folder)
    cone = trimesh.creation.cone(radius=1.0, height=3.0)
    library.add_arrays(cone.vertices, cone.faces, "cone")
    real_replace = os.replace

    def fail_on_manifest(source, target):
        if str(target).endswith("library.json"):
            raise OSError("the disk went away")
        real_replace(source, target)

    monkeypatch.setattr(os, "replace", fail_on_manifest)
    with pytest.raises(LibraryError, match="the disk went away"):
        library.save(folder)
    monkeypatch.undo()
    after = snapshot(folder)
    assert {name: after[name] for name in before} == before  # old files untouched
    assert PriorLibrary.load(folder).names == ["box", "cylinder"]


WRITER = textwrap.dedent("""
    import sys
    import numpy as np
    import trimesh
    from tactile_viz.engine import ObjectModel, PriorLibrary
    from tactile_viz.engine.session import Session, make_truth

    library_folder, session_path = sys.argv[1], sys.argv[2]
    base = PriorLibrary.load(library_folder).subset(["box", "cylinder"])
    ball = trimesh.creation.icosphere(subdivisions=6, radius=2.0)  # 82k faces, a 2 MB PLY
    big = PriorLibrary(list(base) + [ObjectModel.from_arrays(ball.vertices, ball.faces, "ball")])
    sessions = [Session.load(session_path)]
    sessions.append(Session.simulated(sessions[0].truth, big, seed=5))
    print("ready", flush=True)
    while True:  # alternate between two good states of each file until killed
        for library, session in zip((big, base), sessions):
            library.save(library_folder)
            session.save(session_path)
""")


@pytest.mark.slow
def test_writes_killed_midway_never_destroy_the_last_good_files(small_library, saved_session,
                                                                tmp_path):
    """A subprocess saves a library (with an 82k-face prior) and a session over and over;
    SIGKILL at three moments; each time both still load as one of their good states."""
    _, folder = small_library
    good, _, _ = saved_session
    session_path = tmp_path / "session.npz"
    session_path.write_bytes(good.read_bytes())
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    for delay in (0.3, 0.9, 1.7):
        writer = subprocess.Popen([sys.executable, str(script), str(folder), str(session_path)],
                                  stdout=subprocess.PIPE, text=True,
                                  env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
        try:
            assert writer.stdout.readline().strip() == "ready"
            time.sleep(delay)
        finally:
            os.kill(writer.pid, signal.SIGKILL)
            writer.wait()
        assert writer.returncode == -signal.SIGKILL
        assert PriorLibrary.load(folder).names in (["box", "cylinder"],
                                                   ["box", "cylinder", "ball"])
        with np.load(session_path) as stored:  # whole and readable (loading replays it)
            config = json.loads(stored["config"].tobytes())
            assert config["library"] in (["box", "cylinder"], ["box", "cylinder", "ball"])
    assert Session.load(session_path).step_count in (0, 2)
