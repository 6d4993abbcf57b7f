"""The robot's scene on every command line: ``--table``, ``--table-height``,
``--reach-angle``, ``--tip-radius`` (``trial``, ``replay``, ``bench decide``, ``bench
paper``), their one-line errors, the scene in the JSON, a recording's ``# scene:`` line."""

import argparse
import gzip
import json

import numpy as np
import pytest

from tactile_viz.__main__ import build_parser, main
from tactile_viz.cli import scene_from_args, scenes_from_args, stop_logging
from tactile_viz.engine.scene import Scene

SCENE = ["--table", "--tip-radius", "0.1", "--reach-angle", "60"]


@pytest.fixture(autouse=True)
def no_logging_left():
    yield
    stop_logging()


@pytest.fixture
def touches(tmp_path):
    path = tmp_path / "touches.csv"
    path.write_text("kind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n")
    return str(path)


def exit_status(argv):
    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code


# ------------------------------------------------------------------ parsing
def test_no_scene_option_is_the_papers_free_space():
    args = build_parser().parse_args(["trial", "--object", "mug_1"])
    assert scene_from_args(args) is None
    assert scene_from_args(argparse.Namespace()) is None  # a command without the options


def test_the_options_make_the_scene():
    parse = build_parser().parse_args
    scene = scene_from_args(parse(["trial", "--object", "mug_1", *SCENE]))
    assert scene.as_dict() == {"table_point": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0],
                               "reach_angle_deg": 60.0, "tip_radius": 0.1}
    high = scene_from_args(parse(["trial", "--object", "mug_1", "--table-height", "-0.25"]))
    assert high.has_table and high.table_point.tolist() == [0.0, 0.0, -0.25]  # implies --table
    held = scene_from_args(parse(["replay", "--observations", __file__, "--reach-angle",
                                  "90"]))
    assert not held.has_table and held.reach_angle_deg == 90 and held.tip_radius == 0
    tip = scene_from_args(parse(["trial", "--object", "mug_1", "--tip-radius", "0.2"]))
    assert not tip.has_table and not tip.limited_reach and tip.tip_radius == 0.2


def test_a_benchmark_takes_a_list_of_tip_radii():
    args = argparse.Namespace(table=True, table_height=None, reach_angle=60.0,
                              tip_radius=[0.0, 0.005, 0.01, 0.005])
    scenes = scenes_from_args(args)
    assert [s.tip_radius for s in scenes] == [0.0, 0.005, 0.01]  # repeats once
    assert all(s.has_table and s.reach_angle_deg == 60 for s in scenes)
    free = scenes_from_args(argparse.Namespace(table=False, table_height=None,
                                               reach_angle=180.0, tip_radius=[0.0, 0.01]))
    assert free[0] is None and free[1].tip_radius == 0.01


BAD = [(["--tip-radius", "-1"], "at least 0"), (["--tip-radius", "nan"], "finite"),
       (["--tip-radius", "x"], "expected a number"),
       (["--reach-angle", "0"], "(0, 180]"), (["--reach-angle", "200"], "(0, 180]"),
       (["--reach-angle", "-5"], "(0, 180]"), (["--reach-angle", "inf"], "finite"),
       (["--table-height", "nan"], "finite"), (["--table-height", "x"], "expected a number")]
COMMANDS = {"trial": ["trial", "--object", "mug_1", "--no-progress"],
            "replay": ["replay", "--observations", "TOUCHES", "--no-progress"],
            "bench decide": ["bench", "decide", "--no-progress"],
            "bench paper": ["bench", "paper", "--no-progress"]}
CASES = [(command, option, message) for command in COMMANDS for option, message in BAD]


@pytest.mark.parametrize("command, option, message", CASES,
                         ids=[f"{c}:{' '.join(o)}" for c, o, _ in CASES])
def test_a_bad_scene_value_is_one_line_and_status_2(command, option, message, touches,
                                                    capsys, tmp_path):
    argv = [touches if word == "TOUCHES" else word for word in COMMANDS[command]]
    if command.startswith("bench"):
        argv += ["--out", str(tmp_path / "out")]
    assert exit_status(argv + option) == 2
    captured = capsys.readouterr()
    assert len(captured.err.splitlines()) == 1 and "Traceback" not in captured.err
    assert f"argument {option[0]}" in captured.err and message in captured.err
    assert captured.out == ""
    assert not (tmp_path / "out").exists()  # nothing run


def test_a_bad_radius_in_a_benchmarks_list_is_one_line(capsys, tmp_path):
    assert exit_status(["bench", "decide", "--tip-radii", "0", "0.005", "-0.01", "--out",
                        str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "argument --tip-radius/--tip-radii" in err


# ------------------------------------------------------------------ trial and replay
@pytest.mark.slow
def test_a_trial_on_a_table_records_its_scene_and_replays_in_it(tmp_path):
    out, replayed = tmp_path / "trial.json", tmp_path / "replay.json"
    assert main(["trial", "--object", "mug_1", *SCENE, "--max-steps", "5", "--json", str(out),
                 "--export", str(tmp_path / "out"), "--no-progress"]) == 0
    result = json.loads(out.read_text())
    assert result["scene"] == {"table_point": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0],
                               "reach_angle_deg": 60.0, "tip_radius": 0.1}
    assert len(result["steps"]) == 5
    # At rest on the table: the object's lowest point on the plane (z = 0).
    assert result["truth_pose"]["translation"][2] > 0
    recording = tmp_path / "out" / "observations.csv"
    lines = recording.read_text().splitlines()
    assert lines[0].startswith("# scene: ") and lines[1].startswith("step,kind")
    # The recording names its scene: the replay is the trial's estimate, step for step.
    assert main(["replay", "--observations", str(recording), "--json", str(replayed),
                 "--no-progress"]) == 0
    again = json.loads(replayed.read_text())
    assert again["scene"] == result["scene"]
    assert [s["map_class"] for s in again["steps"]] == [s["map_class"] for s in result["steps"]]
    np.testing.assert_allclose(again["steps"][-1]["map_translation"],
                               result["steps"][-1]["map_translation"])


@pytest.mark.slow
def test_a_replay_takes_the_options_before_the_files_scene(tmp_path, touches):
    out = tmp_path / "replay.json"
    assert main(["replay", "--observations", touches, "--json", str(out),
                 "--no-progress"]) == 0
    assert json.loads(out.read_text())["scene"] is None
    named = tmp_path / "named.csv"
    named.write_text('# scene: {"table_point": [0, 0, 0], "tip_radius": 0.1}\n'
                     "kind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n")
    assert main(["replay", "--observations", str(named), "--json", str(out),
                 "--no-progress"]) == 0
    assert json.loads(out.read_text())["scene"]["tip_radius"] == 0.1
    assert main(["replay", "--observations", str(named), "--reach-angle", "45", "--json",
                 str(out), "--no-progress"]) == 0
    assert json.loads(out.read_text())["scene"] == {
        "table_point": None, "up": [0.0, 0.0, 1.0], "reach_angle_deg": 45.0, "tip_radius": 0.0}


def test_a_recordings_scene_line_is_in_its_unit(tmp_path):
    from tactile_viz.commands.inputs import recorded_scene

    path = tmp_path / "touches.csv"
    path.write_text('# units: mm\n# scene: {"table_point": [0, 0, -20], "reach_angle_deg": 60, '
                    '"tip_radius": 5}\nkind,x,y,z,nx,ny,nz\ncontact,0,0,10,0,0,1\n')
    in_mm = recorded_scene(path)
    assert in_mm.table_point.tolist() == [0, 0, -20] and in_mm.tip_radius == 5
    in_m = recorded_scene(path, "m")
    np.testing.assert_allclose(in_m.table_point, [0, 0, -0.02])
    assert in_m.tip_radius == pytest.approx(0.005) and in_m.reach_angle_deg == 60
    from tactile_viz.engine.io.observation_file import read_observations

    assert len(read_observations(path, "m")) == 1  # the reader skips the line


@pytest.mark.parametrize("line", ['# scene: {"tip_radius": -1}', "# scene: table",
                                  '# scene: {"reach_angle_deg": 0}', "# scene: [1, 2]"])
def test_a_bad_scene_line_is_one_line_naming_the_file(tmp_path, capsys, line):
    path = tmp_path / "touches.csv"
    path.write_text(f"{line}\nkind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n")
    assert main(["replay", "--observations", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "touches.csv, line 1: the scene line" in err


def test_the_scene_line_is_written_once_after_the_units(tmp_path):
    from tactile_viz.commands.inputs import recorded_scene, write_scene_line

    path = tmp_path / "observations.csv"
    path.write_text("# units: m\nstep,kind,x,y,z,nx,ny,nz\n1,contact,0,0,1,0,0,1\n")
    write_scene_line(path, None)
    write_scene_line(path, Scene())  # free space: no line
    assert recorded_scene(path) is None
    scene = Scene.on_table(0.1, 45, 0.002)
    write_scene_line(path, scene)
    write_scene_line(path, Scene.on_table(0.5))  # a file that names a scene keeps it
    lines = path.read_text().splitlines()
    assert lines[0] == "# units: m" and lines[1].startswith("# scene: ")
    assert lines[2].startswith("step,") and len(lines) == 4
    assert recorded_scene(path).as_dict() == scene.as_dict()


@pytest.mark.slow
def test_a_metric_trial_on_a_table_with_a_saved_library(tmp_path, monkeypatch):
    """The robot's use: a mesh in metres, a saved library, a table, a 5 mm tip, a 60 degree
    reach, the sensor's noise."""
    import trimesh

    from tactile_viz.engine.shape.library import PriorLibrary

    monkeypatch.chdir(tmp_path)
    make = trimesh.creation
    make.cylinder(radius=0.033, height=0.12).export("can.stl")
    make.box((0.08, 0.05, 0.03)).export("box.stl")
    library = PriorLibrary()
    for name in ("can.stl", "box.stl"):
        library.add_file(name, units="m")
    library.save("lib")
    assert main(["trial", "--object-file", "can.stl:m", "--library-dir", "lib", "--table",
                 "--tip-radius", "0.005", "--reach-angle", "60", "--preset", "recognise",
                 "--position-noise", "0.002", "--normal-noise", "2", "--max-steps", "12",
                 "--json", "out.json", "--no-progress"]) == 0
    result = json.loads((tmp_path / "out.json").read_text())
    assert result["units"] == "m" and result["scene"]["tip_radius"] == 0.005
    assert result["sensor"]["position_noise"] == 0.002 and result["steps"]


# ------------------------------------------------------------------ bench decide
def _result(name, decided_at, radius, map_class=None, pose=0.001, tag="known"):
    steps = [{"t": t, "map_class": map_class or name, "pose_error": pose, "novel": False,
              "decided": decided_at is not None and t >= decided_at, "rotation_error_deg": 2.0,
              "n_contacts": t, "n_noncontacts": 1} for t in range(1, 11)]
    scene = Scene.on_table(0.0, 60, radius).as_dict()
    return {"object": name, "seed": 0, "object_size": 0.1, "seconds": 3.0, "steps": steps,
            "sensor": {"position_noise": 0.0, "normal_noise_deg": 0.0}, "scene": scene,
            "task": {"tag": tag}}


def test_decide_plans_every_trial_once_per_tip_radius(tmp_path):
    from tactile_viz.experiments import decide

    scenes = [None, Scene.on_table(0, 60, 0.005)]
    made = decide.tasks(["mug_1"], ["neptune"], [(0.0, 0.0), (0.002, 2.0)], 2, 1, None,
                        "recognise", {}, 60, scenes=scenes, max_steps=8)
    assert len(made) == 2 * 2 * (2 + 1)
    assert sum("scene" in t for t in made) == 6
    assert {t["scene"]["tip_radius"] for t in made if "scene" in t} == {0.005}
    assert {t["max_steps"] for t in made} == {8}  # the cap, below --novel-steps too
    plain = decide.tasks(["mug_1"], [], [(0.0, 0.0)], 1, 0, None, "recognise", {}, 60)
    assert plain[0]["max_steps"] is None and "scene" not in plain[0]


def test_decide_summarises_each_tip_radius_and_noise_level():
    from tactile_viz.experiments import decide

    summaries = [decide.summary(r) for r in [
        _result("mug_1", 4, 0.0), _result("mug_1", 6, 0.0, map_class="cup"),
        _result("mug_1", None, 0.01), _result("neptune", None, 0.01, tag="novel")]]
    assert [s["outcome"] for s in summaries[:3]] == ["right", "wrong", "undecided"]
    assert summaries[0]["contacts_at_decision"] == 4 and summaries[2]["tip_radius"] == 0.01
    text = decide.markdown(summaries)
    assert text.startswith("Scene: a table at z = 0 m, reach within 60 deg of straight down.")
    assert "| 0 | 0, 0 | 2 | 1 (50.0%) | 1 (50.0%) | 0 | 5.0 | 5.0 | 2.00 |" in text
    assert "| 0.01 | 0, 0 | 1 | 0 (0.0%) | 0 (0.0%) | 1 | - | - | - | 0 | 0/1 | 0 |" in text
    assert "| mug_1 | 0 | 0.01 | 0, 0 | - |" in text


@pytest.mark.slow
def test_decide_runs_objects_at_rest_on_a_table(tmp_path, monkeypatch):
    from tactile_viz.experiments import decide

    monkeypatch.setattr(decide, "hard_meshes", lambda folder: {})  # the bundled priors only
    out = tmp_path / "decide"
    assert main(["bench", "decide", "--objects", "mug_1", "--seeds", "1", "--novel-seeds",
                 "0", "--noise", "0:0", "--max-steps", "3", "--workers", "1", "--table",
                 "--reach-angle", "60", "--tip-radii", "0", "0.005", "--out", str(out),
                 "--no-progress"]) == 0
    summaries = json.loads((out / "decide.json").read_text())
    assert [s["tip_radius"] for s in summaries] == [0.0, 0.005]
    assert all(s["scene"]["table_point"] == [0.0, 0.0, 0.0]
               and s["scene"]["reach_angle_deg"] == 60 and s["steps"] <= 3 for s in summaries)
    assert all(s["outcome"] in ("right", "wrong", "undecided") for s in summaries)
    text = (out / "decide.md").read_text()
    assert "| tip radius (m) | noise (m, deg) |" in text
    assert "\n| 0 | 0, 0 | 1 |" in text and "\n| 0.005 | 0, 0 | 1 |" in text


# ------------------------------------------------------------------ bench paper
def test_paper_tasks_take_the_scene_and_keep_it_in_their_key():
    from tactile_viz.experiments import paper
    from tactile_viz.experiments.runner import task_key

    tasks = paper.protocol_tasks(["mug_1"], ["gpis-dhd"], 1, 0, "paper", None, False,
                                 paper.object_sets())
    plain = task_key(tasks[0])
    more = paper.with_setting(tasks, {"position_noise": 0.0}, Scene.on_table(0, 60, 0.1))
    assert tasks[0]["scene"]["tip_radius"] == 0.1
    assert task_key(tasks[0]) == plain + "__scene-table0-reach60-tip0.1"
    later = more(paper.learned_tasks({"name": "x", "vertices": [], "faces": []}, 1, 0,
                                     "paper", None))
    assert later[0]["scene"]["reach_angle_deg"] == 60
    free = paper.protocol_tasks(["mug_1"], ["gpis-dhd"], 1, 0, "paper", None, False,
                                paper.object_sets())
    paper.with_setting(free, {"position_noise": 0.0}, None)
    assert "scene" not in free[0] and task_key(free[0]) == plain


@pytest.mark.slow
def test_paper_runs_its_trials_on_the_table(tmp_path):
    out = tmp_path / "run"
    assert main(["bench", "paper", "--trials", "1", "--objects", "mug_1", "--strategies",
                 "gpis-dhd", "--max-steps", "2", "--no-learned", "--out", str(out),
                 "--no-progress", *SCENE]) == 0
    files = list((out / "trials").glob("*"))
    assert len(files) == 1 and "__scene-table0-reach60-tip0.1" in files[0].name
    result = json.loads(gzip.decompress(files[0].read_bytes()))
    assert result["scene"]["tip_radius"] == 0.1 and result["task"]["scene"]["tip_radius"] == 0.1
    assert "Robot's scene of the trials" in (out / "summary.md").read_text()
