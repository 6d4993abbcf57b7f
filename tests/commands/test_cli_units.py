"""The command line in a metric scene: meshes in millimetres, a recording replayed against
them, learning from the command line (needs no bundled object)."""

import json

import numpy as np
import pytest
import trimesh

from tactile_viz.__main__ import main
from tactile_viz.cli import stop_logging
from tactile_viz.engine.shape.library import PriorLibrary


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
    # Its own errors, in the scene's unit and degrees, as the library keeps them.
    assert note["shape_error"] == pytest.approx(library["ball_learned"].shape_error, rel=1e-6)
    assert 0 < note["shape_error"] < 0.04 and 0 <= note["normal_error_deg"] <= 180
    assert library.names == ["block_mm", "ball_learned"]
    assert library["ball_learned"].learned and not library["block_mm"].learned
    assert library["ball_learned"].length == pytest.approx(0.04, rel=0.4)


def _parse(argv):
    from tactile_viz.__main__ import build_parser

    return build_parser().parse_args(argv)


def test_each_file_may_name_its_own_unit(mm_meshes):
    from tactile_viz.commands.inputs import load_mesh, load_priors, scene_units

    trimesh.creation.icosphere(subdivisions=3, radius=0.02).export(mm_meshes / "ball_m.stl")
    args = _parse(["trial", "--object-file", f"{mm_meshes / 'ball_mm.stl'}:mm",
                   "--prior-file", f"{mm_meshes / 'block_mm.stl'}:mm",
                   f"{mm_meshes / 'ball_m.stl'}:m", f"{mm_meshes / 'ball_mm.stl'}:0.001"])
    library = load_priors(args)
    assert library.names == ["block_mm", "ball_m", "ball_mm"] and library.units == "m"
    assert scene_units(args, library) == "m"
    np.testing.assert_allclose([m.length for m in library], [0.0554, 0.04, 0.04], rtol=0.05)
    assert load_mesh(args, args.object_file, "m").length == pytest.approx(0.04, rel=0.05)
    # The suffix overrides --mesh-units for its file; the others take --mesh-units.
    args = _parse(["trial", "--object-file", str(mm_meshes / "ball_mm.stl"), "--mesh-units",
                   "mm", "--prior-file", f"{mm_meshes / 'ball_m.stl'}:m",
                   str(mm_meshes / "block_mm.stl")])
    np.testing.assert_allclose([m.length for m in load_priors(args)], [0.04, 0.0554], rtol=0.05)


@pytest.mark.parametrize("extra, fault", [
    (["--mesh-units", "mm", "--normalise", "6"], "--normalise 6 and the mesh unit mm"),
    (["--normalise", "6", "--prior-file", "BLOCK:mm"], "--normalise 6 and the mesh unit mm"),
    (["--learn-to", "LIB"], "--learn-to"),
    (["--learn", "x"], "--learn needs a library folder"),
    (["--library-dir", "LIB"], "no such folder"),
    (["--prior-file", "BLOCK:parsec"], "no such file"),
])
@pytest.mark.parametrize("command", ["trial", "replay"])
def test_contradictions_are_refused_in_one_line(mm_meshes, capsys, extra, fault, command):
    block, lib = str(mm_meshes / "block_mm.stl"), str(mm_meshes / "lib")
    recording = mm_meshes / "touches.csv"
    recording.write_text("kind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n")
    base = (["trial", "--object-file", block] if command == "trial"
            else ["replay", "--observations", str(recording)])
    argv = base + [word.replace("BLOCK", block).replace("LIB", lib) for word in extra]
    try:
        status = main(argv + ["--no-progress"])
    except SystemExit as stop:
        status = stop.code
    err = capsys.readouterr().err
    assert status == 2 and len(err.splitlines()) == 1 and fault in err
    assert err.startswith(f"python -m tactile_viz {command}: error: ")
    assert not (mm_meshes / "lib").exists()


def test_a_millimetre_object_against_a_metre_library_warns(mm_meshes, capsys):
    library = PriorLibrary()
    library.add_file(mm_meshes / "block_mm.stl", scale=0.001, units="m")
    library.save(mm_meshes / "lib")
    _run(["trial", "--object-file", str(mm_meshes / "ball_mm.stl"), "--library-dir",
          str(mm_meshes / "lib"), "--max-steps", "1", "--no-progress", "--json",
          str(mm_meshes / "t.json")])
    err = capsys.readouterr().err
    assert "warning: ball_mm.stl spans 40 m but the library's objects are 0.0554 m long" in err
    assert "is the file in mm?" in err and "ball_mm.stl:mm" in err
    assert json.loads((mm_meshes / "t.json").read_text())["units"] == "m"  # the library's
    _run(["trial", "--object-file", f"{mm_meshes / 'ball_mm.stl'}:mm", "--library-dir",
          str(mm_meshes / "lib"), "--max-steps", "1", "--no-progress", "--json",
          str(mm_meshes / "t.json")])
    assert "warning" not in capsys.readouterr().err


def test_learning_makes_the_library_folder_it_names(mm_meshes, capsys):
    lib = mm_meshes / "new" / "lib"
    _run(["trial", "--object-file", str(mm_meshes / "ball_mm.stl"), "--prior-file",
          str(mm_meshes / "block_mm.stl"), "--mesh-units", "mm", "--max-steps", "12",
          "--no-progress", "--json", str(mm_meshes / "t.json"), "--learn", "ball_learned",
          "--library-dir", str(lib)])
    library = PriorLibrary.load(lib)
    assert library.names[0] == "block_mm" and library.units == "m"
    note = json.loads((mm_meshes / "t.json").read_text())["learned"]
    assert note["saved_to"] == str(lib)
    err = capsys.readouterr().err
    assert ("note: learned ball_learned" in err) == ("ball_learned" in library)
    # The folder now holds a library: the same command line reads it back.
    assert PriorLibrary.load(lib).names == library.names


def test_learning_an_object_judged_known_says_so(mm_meshes, capsys):
    block = str(mm_meshes / "block_mm.stl")
    _run(["trial", "--object-file", block, "--prior-file", block, str(mm_meshes / "ball_mm.stl"),
          "--mesh-units", "mm", "--max-steps", "10", "--no-progress", "--quiet", "--json",
          str(mm_meshes / "t.json"), "--learn", "again", "--learn-to", str(mm_meshes / "lib")])
    result = json.loads((mm_meshes / "t.json").read_text())
    last, err = result["steps"][-1], capsys.readouterr().err
    if not last["novel"]:
        assert (f"trial: note: not learned: the object was judged known as "
                f"{last['map_class']}") in err
        assert result["learned"]["reason"].startswith("the object was judged known")
        assert "again" not in PriorLibrary.load(mm_meshes / "lib")  # made, unchanged
    else:
        assert "note: learned again" in err
    assert len(err.strip().splitlines()) == 1


def test_a_unit_declared_wrong_is_still_caught(mm_meshes, capsys):
    """A millimetre file given as metres beside priors in metres: a 55 m block warns with
    the likely unit, though its unit was declared."""
    block, ball = str(mm_meshes / "block_mm.stl"), str(mm_meshes / "ball_mm.stl")
    _run(["trial", "--object-file", f"{block}:m", "--prior-file", f"{ball}:mm",
          f"{block}:mm", "--max-steps", "1", "--no-progress", "--quiet", "--json",
          str(mm_meshes / "t.json")])
    err = capsys.readouterr().err
    assert "warning: block_mm.stl spans 55.4 m but the library's objects are" in err
    assert "is the file in mm?" in err
