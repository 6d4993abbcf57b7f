"""``bench paper`` end to end on a tiny run, and its task planning."""

import numpy as np
import trimesh

from tactile_viz.__main__ import main as cli
from tactile_viz.experiments import paper
from tactile_viz.experiments.trial_files import read_trial


def test_tiny_run_writes_trials_table_and_plots(tmp_path):
    out = tmp_path / "run"
    argv = ["bench", "paper", "--trials", "1", "--objects", "mug_1", "--strategies",
            "gpis-dhd", "--max-steps", "3", "--no-learned", "--out", str(out), "--no-progress"]
    assert cli(argv) == 0
    files = list((out / "trials").glob("*"))
    assert len(files) == 1 and files[0].name.endswith(".json.gz")  # compressed (issue 18)
    result = read_trial(files[0])
    assert result["object"] == "mug_1" and len(result["steps"]) == 3
    summary = (out / "summary.md").read_text()
    assert "## Known objects" in summary and "| mug_1 | gpis-dhd | 1 |" in summary
    assert (f"Code version(s) of the trials (number of trials): {result['code_version']} (1)"
            in summary)
    assert (out / "overview.png").stat().st_size > 1000
    stamp = files[0].stat().st_mtime_ns
    assert cli(argv + ["--resume"]) == 0  # nothing to rerun
    assert files[0].stat().st_mtime_ns == stamp
    command = next(line for line in (out / "summary.md").read_text().splitlines()
                   if line.startswith("Command:"))
    assert "--resume" in command
    assert cli(["bench", "paper", "--report-only", "--out", str(out)]) == 0
    assert command in (out / "summary.md").read_text()  # the run's command, not --report-only


def test_protocol_plan_orders_costly_trials_first_and_learns_from_the_home_chair():
    sets = paper.object_sets()
    tasks = paper.protocol_tasks(["mug_1", "home_chair"], ["gpis-dhd", "rrt"], 2, 10,
                                 "paper", None, True, sets)
    assert len(tasks) == 8
    assert [(t["object"], t["strategy"]) for t in tasks[::2]] == [
        ("home_chair", "gpis-dhd"), ("mug_1", "gpis-dhd"), ("home_chair", "rrt"), ("mug_1", "rrt")]
    assert tasks[0]["poisson"]
    assert not any(t["poisson"] for t in tasks if t["object"] == "mug_1")
    planned = paper.learn_task(tasks, 10, "paper", None, True)
    assert planned[0]["learn_as"] == paper.LEARNED_NAME
    assert (planned[0]["object"], planned[0]["strategy"], planned[0]["seed"]) == (
        "home_chair", "gpis-dhd", 10)
    alone = paper.learn_task([t for t in tasks if t["object"] == "mug_1"], 10, "paper", None,
                             True)
    assert alone[0]["kind"] == "learn" and len(alone) == 5
    # Within a group, trial 0 of every object comes before trial 1 of any.
    novel = paper.protocol_tasks(["mug_2", "home_chair"], ["gpis-dhd"], 2, 0, "paper", None,
                                 False, sets)
    assert [(t["object"], t["seed"]) for t in novel] == [
        ("home_chair", 0), ("mug_2", 0), ("home_chair", 1), ("mug_2", 1)]


def test_learned_surface_is_saved_and_becomes_a_prior(tmp_path):
    box = trimesh.creation.box((6, 3, 2))
    result = {"learned": {"name": "home_chair_learned", "vertices": box.vertices.tolist(),
                          "faces": box.faces.tolist(), "shape_error": 0.02,
                          "normal_error": 0.3}}
    prior = paper.save_learned(result, tmp_path)
    assert result["learned"]["n_faces"] == 12 and "vertices" not in result["learned"]
    loaded = paper.load_learned(tmp_path)
    assert np.allclose(loaded["vertices"], prior["vertices"])
    # Its own errors come with it, as from a learned library's manifest.
    assert (loaded["shape_error"], loaded["normal_error"]) == (0.02, 0.3)
    tasks = paper.learned_tasks(loaded, 3, 0, "paper", 5)
    assert [t["seed"] for t in tasks] == [1000, 1001, 1002]
    assert tasks[0]["extra_priors"][0]["name"] == "home_chair_learned"
    assert paper.save_learned({"learned": {"error": "not novel"}}, tmp_path) is None


def test_step_time_section_splits_novel_and_known_steps():
    from tactile_viz.experiments.paper import _step_time_section

    results = [{"steps": [{"novel": False, "step_seconds": 0.01},
                          {"novel": True, "step_seconds": 0.3},
                          {"novel": True, "step_seconds": 0.1}]},
               {"steps": [{"novel": True, "step_seconds": 0.2}]}]
    lines = _step_time_section(results)
    assert "while novel: median 0.200 s" in lines[3] and "(3 steps)" in lines[3]
    assert "while known: median 0.010 s" in lines[4] and "(1 steps)" in lines[4]
    assert _step_time_section([]) == []


def test_the_learned_section_names_the_reconstruction_the_prior_came_from():
    from tactile_viz.experiments.paper import _learned_source

    before = [{"seed": 7, "gpis_error": 0.41}, {"seed": 8, "gpis_error": 0.632}]
    results = [{"seed": 7}, {"seed": 8, "learned": {"file": "x.ply"}}]
    line = _learned_source(before, results)[1]
    assert "seed 8, 0.632 off the home_chair" in line and "under 0.6" in line
    # A prior passed with --learned-from (no trial learned it) and a failed one: no line.
    assert _learned_source(before, [{"seed": 8}]) == []
    assert _learned_source([{"seed": 8, "gpis_error": None}], results) == []


def test_learned_trials_can_take_the_prior_of_an_earlier_run(tmp_path, capsys):
    import pytest

    box = trimesh.creation.box((6, 3, 2))
    mesh_path = tmp_path / "earlier.ply"
    box.export(mesh_path)
    out = tmp_path / "run"
    assert cli(["bench", "paper", "--trials", "1", "--objects", "mug_1", "--strategies",
                "gpis-dhd", "--max-steps", "2", "--learned-from", str(mesh_path), "--out",
                str(out), "--no-progress"]) == 0
    names = sorted(p.name for p in (out / "trials").glob("*"))
    assert len(names) == 2 and names[0].startswith("learned__home_chair")
    learned = read_trial(out / "trials" / names[0])
    assert learned["library"][-1] == "home_chair_learned" and learned["seed"] == 1000
    assert "## Learned prior (home chair)" in (out / "summary.md").read_text()
    with pytest.raises(SystemExit) as stop:  # a missing file stops before any trial
        cli(["bench", "paper", "--trials", "1", "--objects", "mug_1", "--learned-from",
             str(tmp_path / "missing.ply"), "--out", str(out), "--no-progress"])
    assert stop.value.code == 2 and "no such file" in capsys.readouterr().err


def test_set_changes_every_tasks_preset_and_the_later_ones():
    tasks = paper.protocol_tasks(["mug_1"], ["gpis-dhd"], 2, 5, "recommended", None, False,
                                 {"mug_1": "known"})
    later = paper.with_setting(tasks, {}, None, [("gpis_agnostic", False), ("eps", 0.3)])
    assert all(t["params"]["gpis_agnostic"] is False and t["params"]["eps"] == 0.3
               for t in tasks)
    more = later(paper.learned_tasks({"name": "x"}, 1, 5, "recognise", None))
    assert more[0]["params"]["eps"] == 0.3 and more[0]["params"]["stop_at_decision"]
    plain = paper.protocol_tasks(["mug_1"], ["gpis-dhd"], 1, 5, "recommended", None, False,
                                 {"mug_1": "known"})
    paper.with_setting(plain, {}, None)
    assert plain[0]["params"] is None  # the preset as it is
