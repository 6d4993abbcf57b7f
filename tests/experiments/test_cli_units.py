"""The command line in a metric scene: meshes in millimetres, a recording replayed against
them, learning from the command line (needs no bundled object)."""

import json

import numpy as np
import pytest
import trimesh

from tactile_viz.__main__ import main
from tactile_viz.cli import stop_logging
from tactile_viz.engine.library import PriorLibrary


@pytest.fixture
def mm_meshes(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    points = np.random.default_rng(7).uniform([-30, -15, -8], [30, 15, 8], size=(40, 3))
    block = trimesh.convex.convex_hull(points)
    block.apply_translation([100.0, -40.0, 25.0])
    block.export(tmp_path / "block_mm.stl")
    trimesh.creation.icosphere(subdivisions=3, radius=20.0).export(tmp_path / "ball_mm.stl")
    yield tmp_path
    stop_logging()


def _run(argv):
    assert main(argv) == 0


def test_a_metric_recording_is_recognised_from_the_command_line(mm_meshes):
    files = [str(mm_meshes / "block_mm.stl"), str(mm_meshes / "ball_mm.stl")]
    trial, replayed = mm_meshes / "trial.json", mm_meshes / "replay.json"
    _run(["trial", "--object-file", files[0], "--prior-file", *files, "--mesh-units", "mm",
          "--seed", "1", "--max-steps", "15", "--no-progress", "--json", str(trial),
          "--export", str(mm_meshes / "out")])
    result = json.loads(trial.read_text())
    assert result["units"] == "m" and result["object_size"] == pytest.approx(0.0554, rel=0.05)
    recording = mm_meshes / "out" / "observations.csv"
    assert recording.read_text().startswith("# units: m\n")
    # The recording, read into a millimetre scene against the files in millimetres.
    _run(["replay", "--observations", str(recording), "--prior-file", *files,
          "--units", "mm", "--no-progress", "--json", str(replayed)])
    last = json.loads(replayed.read_text())["steps"][-1]
    assert last["map_class"] == "block_mm" and not last["novel"]
    assert last["map_translation"] == pytest.approx(
        1000 * np.array(result["steps"][-1]["map_translation"]), abs=5.0)


def test_learning_needs_a_folder_and_a_free_name(mm_meshes, capsys):
    files = [str(mm_meshes / "block_mm.stl"), str(mm_meshes / "ball_mm.stl")]
    base = ["trial", "--object-file", files[0], "--prior-file", *files, "--no-progress"]
    assert main(base + ["--learn", "x"]) == 2
    assert "--learn-to" in capsys.readouterr().err
    assert main(base + ["--learn", "ball_mm", "--learn-to", str(mm_meshes / "lib")]) == 2
    assert "already has a prior" in capsys.readouterr().err
    assert not (mm_meshes / "lib").exists()


def test_a_learned_library_is_saved_with_the_learned_flag(mm_meshes):
    files = [str(mm_meshes / "block_mm.stl")]
    out = mm_meshes / "t.json"
    _run(["trial", "--object-file", str(mm_meshes / "ball_mm.stl"), "--prior-file", *files,
          "--mesh-units", "mm", "--max-steps", "12", "--no-progress", "--json", str(out),
          "--learn", "ball_learned", "--learn-to", str(mm_meshes / "lib")])
    note = json.loads(out.read_text())["learned"]
    assert note["saved_to"] == str(mm_meshes / "lib")
    library = PriorLibrary.load(mm_meshes / "lib")
    assert library.names == ["block_mm", "ball_learned"]
    assert library["ball_learned"].learned and not library["block_mm"].learned
    assert library["ball_learned"].length == pytest.approx(0.04, rel=0.4)
