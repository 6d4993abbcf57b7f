"""``python -m tactile_viz library``: a library folder built, grown, pruned and listed
from the command line."""

import json
from pathlib import Path

import pytest
import trimesh

from tactile_viz.__main__ import main
from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.shape.library import MANIFEST


@pytest.fixture
def scans(tmp_path, monkeypatch):
    """A scan set that ships every object as <object>/google_16k/textured.obj, in mm."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    shapes = {"can": trimesh.creation.cylinder(radius=33, height=120),
              "box": trimesh.creation.box((80, 50, 30)),
              "ball": trimesh.creation.icosphere(radius=40)}
    for name, mesh in shapes.items():
        (tmp_path / "scans" / name / "google_16k").mkdir(parents=True)
        mesh.export(tmp_path / "scans" / name / "google_16k" / "textured.obj")
    return sorted(str(p) for p in (tmp_path / "scans").glob("*/google_16k/textured.obj"))


def test_a_set_of_one_file_name_builds_by_folder_name_and_is_kept(scans, capsys):
    assert main(["library", "build", "lib", *scans, "--mesh-units", "mm"]) == 2
    assert "the name 'textured' is" in capsys.readouterr().err
    assert not (Path("lib") / MANIFEST).exists()  # refused before anything was written
    assert main(["library", "build", "lib", *scans, "--mesh-units", "mm", "--name-from",
                 "grandparent", "--no-progress"]) == 0
    assert capsys.readouterr().out.startswith("built 3 priors; lib holds 3 (0.08 to 0.12 m")
    library = PriorLibrary.load("lib")
    assert library.names == ["ball", "box", "can"] and library.units == "m"
    assert library["can"].length == pytest.approx(0.12)
    assert main(["library", "remove", "lib", "box"]) == 0
    assert main(["library", "add", "lib", f"crate={scans[1]}:mm", "--no-progress"]) == 0
    assert PriorLibrary.load("lib").names == ["ball", "can", "crate"]
    capsys.readouterr()
    assert main(["library", "list", "lib"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0].split() == ["name", "longest", "side", "unit", "faces", "learned"]
    assert rows[2].split()[:3] == ["can", "0.12", "m"]
    assert main(["library", "show", "lib", "can"]) == 0
    assert "longest side 0.12 m" in capsys.readouterr().out
    # The folder is a library the session commands read.
    assert main(["trial", "--object-file", f"{scans[2]}:mm", "--library-dir", "lib",
                 "--max-steps", "3", "--no-progress", "--quiet", "--json", "t.json"]) == 0
    assert json.load(open("t.json"))["library"] == ["ball", "can", "crate"]


def test_bad_library_commands_are_one_line(scans, capsys):
    assert main(["library", "build", "lib", "missing.obj"]) == 2
    assert main(["library", "build", "lib", f"a={scans[0]}:mm", "--no-progress"]) == 0
    assert main(["library", "build", "lib", f"b={scans[1]}:mm"]) == 2  # use add
    assert main(["library", "remove", "lib", "a"]) == 2  # would leave it empty
    assert main(["library", "show", "lib", "nothing"]) == 2
    assert main(["library", "add", "lib", f"a={scans[1]}:mm", "--no-progress"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 5 and all(": error: " in line for line in err)
    assert "use library add" in err[1] and "already has a prior named 'a'" in err[4]


def test_another_library_is_added_whole(scans, capsys):
    assert main(["library", "build", "one", f"can={scans[2]}:mm", "--no-progress"]) == 0
    assert main(["library", "build", "two", f"ball={scans[0]}:mm", f"box={scans[1]}:mm",
                 "--no-progress"]) == 0
    assert main(["library", "add", "one", "--from-library", "two", "--no-progress"]) == 0
    assert PriorLibrary.load("one").names == ["can", "ball", "box"]


def test_a_library_is_built_for_the_presets_trials(scans, capsys, tmp_path, monkeypatch):
    """``--preset recognise`` builds the banded grids its trials read, the default the
    exact ones: each trial then finds its priors built."""
    from tactile_viz.engine.belief.prior_build import missing

    monkeypatch.setenv("TACTILE_VIZ_CACHE", str(tmp_path / "own_cache"))
    from tactile_viz.engine.presets import session_preset
    from tactile_viz.engine.session import Session

    assert main(["library", "build", "lib", *scans, "--mesh-units", "mm", "--name-from",
                 "grandparent", "--preset", "recognise", "--no-progress"]) == 0
    library = PriorLibrary.load("lib")

    def unbuilt(preset):
        pf = Session(library, params=session_preset(preset)).filter
        return missing(pf.models, pf.params.distance_step, pf.params.angle_step_deg)

    assert unbuilt("recognise") == [] and len(unbuilt("recommended")) == 3


def test_a_scan_sets_object_is_named_on_the_command_line(scans, capsys):
    """``--object-name`` names an ``--object-file`` object (a scan set's files are all
    ``textured.obj``); a bundled object keeps its own name."""
    assert main(["library", "build", "lib", *scans, "--mesh-units", "mm", "--name-from",
                 "grandparent", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["trial", "--object-file", f"{scans[2]}:mm", "--object-name", "can",
                 "--library-dir", "lib", "--max-steps", "2", "--no-progress",
                 "--json", "t.json"]) == 0
    assert json.load(open("t.json"))["object"] == "can"
    assert capsys.readouterr().err.startswith("can: ")
    assert main(["trial", "--object", "mug_1", "--object-name", "cup", "--max-steps",
                 "1", "--no-progress"]) == 2
    assert "--object-name names an --object-file object" in capsys.readouterr().err
