"""bench learn: its libraries, its tasks, the met-again trial and the tables (no long runs)."""

import numpy as np
import pytest

from tactile_viz.__main__ import main
from tactile_viz.experiments import learn
from tactile_viz.experiments.runner import task_library


def test_few_unlike_priors_leave_out_the_objects_family_and_many_only_the_object():
    assert learn.library_names("mug_1", "few") == ["screwdriver_flat", "knife", "elephant"]
    assert learn.library_names("fork", "few") == ["mug_1", "screwdriver_flat", "elephant"]
    many = learn.library_names("ball_bumpy", "many")
    assert "ball_bumpy" not in many and "ball_smooth" in many
    assert len(many) == len(learn.sizes()) - 1


def test_tasks_leave_the_object_out_and_learn_it(tmp_path):
    files = {"block": tmp_path / "block.ply", "knife": tmp_path / "knife.ply",
             "screwdriver_flat": tmp_path / "s.ply"}
    tasks = learn.learn_tasks(["block", "mug_1"], ["few", "many"], [(0.0, 0.0), (0.002, 2.0)],
                              2, 5, files, None)
    assert len(tasks) == 2 * 2 * 2 * 2
    for task in tasks:
        names = [p["name"] for p in task["extra_priors"]]
        assert task["object"] not in names and task["library"] == "none"
        assert task["learn_as"] == f"{task['object']}_learned" and task["kind"] == "learn"
        assert task["seed"] in (5, 6) and task["preset"] == "recommended"
    block = next(t for t in tasks if t["object"] == "block")
    assert block["object_file"] == str(files["block"]) and block["longest_side"] == 0.02
    mug = next(t for t in tasks if t["object"] == "mug_1")
    assert mug["sizes"] == {"mug_1": learn.sizes()["mug_1"]}


def test_a_bundled_prior_of_a_task_has_its_size():
    task = {"library": "none", "extra_priors": [{"name": "elephant", "bundled": "elephant",
                                                 "longest_side": 0.15}]}
    library = task_library(task)
    assert library.names == ["elephant"]
    assert library["elephant"].length == pytest.approx(0.15, rel=1e-6)


def _result(name, steps, novel=True, learned=True, terminated=True, kind="learn"):
    records = [{"t": t, "novel": novel, "map_class": f"{name}_learned" if kind == "again"
                else "knife", "recon_error": 0.005, "recon_surface_error": 0.003,
                "pose_error": 0.004, "step_seconds": 0.01 * t,
                "decided": kind == "again" and t >= 9} for t in range(1, steps + 1)]
    result = {"object": name, "object_size": 0.1, "seed": 3, "seconds": 4.0, "steps": records,
              "terminated_at": steps if terminated else None,
              "sensor": {"position_noise": 0.0, "normal_noise_deg": 0.0},
              "task": {"tag": "few", "max_steps": None},
              "params": {"max_steps_novel": 40, "max_steps_known": 30}}
    if learned:
        result["learned"] = {"name": f"{name}_learned", "vertices": [[0, 0, 0]], "faces": [],
                             "shape_error": 0.002}
    return result


def test_the_met_again_trial_adds_the_learned_prior_at_another_pose():
    task = {"object": "cup", "seed": 3, "kind": "learn", "preset": "recommended",
            "learn_as": "cup_learned", "extra_priors": [{"name": "knife"}], "tag": "few"}
    assert learn.again_task(task, _result("cup", 10, learned=False), None) is None
    again = learn.again_task(task, _result("cup", 10), 50)
    assert again["seed"] == 3 + learn.AGAIN_SEED and again["preset"] == "recognise"
    assert again["kind"] == "again" and again["learn_as"] is None and again["max_steps"] == 50
    assert [p["name"] for p in again["extra_priors"]] == ["knife", "cup_learned"]
    assert again["extra_priors"][1]["learned"] is True
    assert task["extra_priors"] == [{"name": "knife"}]  # the learning task is unchanged


def test_summaries_and_tables():
    row = learn.learn_summary(_result("cup", 30))
    assert row["judged_novel"] and row["stopped"] and row["learned"]
    assert np.isclose(row["recon_share"], 0.05) and row["touches"] == 30
    assert np.isclose(row["surface_share"], 0.03) and np.isclose(row["own_share"], 0.02)
    capped = learn.learn_summary(_result("cup", 30, novel=False, learned=False,
                                         terminated=True))
    assert capped["recon_share"] is None and not capped["stopped"]  # the known cap, 30
    assert not learn.learn_summary(_result("cup", 30, terminated=False))["stopped"]
    row.update(learn.again_summary(_result("cup", 20, kind="again")))
    assert row["decided_learned"] and row["decided_at"] == 9
    assert np.isclose(row["pose_share"], 0.04)
    assert np.isclose(row["slowest_touch"], 0.3) and np.isclose(row["again_slowest_touch"], 0.2)
    text = learn.markdown([row, capped])
    assert ("| few | 0, 0 | 1/2 | 5.0 (5.0) | 3.0 (3.0) | 1/2 | 1/1 | 1/1 | 9 | 4.0 | 1/1 | "
            "4, 4 | 0.30, 0.20 |") in text
    assert "| cup | 10 | few | 0, 0 | yes | 5.0 | 3.0 | 2.0 | 30 | yes | yes | 9 |" in text
    assert "| cup | 10 | few | 0, 0 | no | - | - | - | 30 | cap | - | - | - | 4 | 0.30 |" in text
    # Decided as another class met again: no decision of the learned one, nor its touches.
    wrong = dict(row, decided_class="mug_1_large", decided_learned=False, decided_at=33)
    text = learn.markdown([wrong])
    assert "| few | 0, 0 | 1/1 | 5.0 (5.0) | 3.0 (3.0) | 1/1 | 1/1 | 0/1 | - | 4.0 |" in text
    assert "| 30 | yes | yes | 33, as mug_1_large | 4.0 |" in text


def test_known_trials_add_the_object_to_its_library_and_time_the_novel_one(tmp_path):
    files = {"block": tmp_path / "block.ply"}
    tasks = learn.learn_tasks(["block", "mug_1"], ["few"], [(0.0, 0.0)], 1, 5, files, None,
                              known=True)
    assert [t["kind"] for t in tasks] == ["learn", "known"] * 2
    for learning, known in zip(tasks[::2], tasks[1::2]):
        names = [p["name"] for p in known["extra_priors"]]
        assert names == [p["name"] for p in learning["extra_priors"]] + [learning["object"]]
        assert known["seed"] == learning["seed"] and known["learn_as"] is None
        assert known["preset"] == "recommended" and learning["object"] not in [
            p["name"] for p in learning["extra_priors"]]
    assert tasks[1]["extra_priors"][-1]["file"] == str(files["block"])
    assert tasks[3]["extra_priors"][-1] == {"name": "mug_1", "bundled": "mug_1",
                                            "longest_side": learn.sizes()["mug_1"]}
    row = learn.learn_summary(_result("cup", 30))
    known = _result("cup", 20, learned=False)
    for record in known["steps"]:
        record.update(novel=False, map_class="cup")
    known["seconds"] = 1.6
    row.update(learn.known_summary(known))
    assert row["known_right"] and row["known_stopped"] and row["known_touches"] == 20
    text = learn.markdown([row])
    # Median touches: 0.155 s of the novel session's 30, 0.105 s of the known one's 20.
    assert "| cup | few | 0, 0 | yes, 20, yes, 1.6, 105 | 30, 4.0, 155 | 2.50, 1.48 |" in text
    assert "Novel / known session: median 2.50, largest 2.50 (1 trial)." in text
    assert "Novel / known median touch: median 1.48, largest 1.48 (1 trial)." in text
    assert "novel / known" not in learn.markdown([learn.learn_summary(_result("cup", 30))])


@pytest.mark.parametrize("argv", [["--objects", "teapot"], ["--libraries", "all"],
                                  ["--noise", "x"], ["--seeds", "0"]])
def test_bad_arguments_are_one_line(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["bench", "learn", *argv])
    assert stop.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_settings_change_both_phases_presets(tmp_path):
    tasks = learn.learn_tasks(["mug_1"], ["few"], [(0.0, 0.0)], 1, 0, {}, None,
                              [("gpis_fill_radius", 3.0)])
    assert tasks[0]["params"]["gpis_fill_radius"] == 3.0
    assert not tasks[0]["params"]["stop_at_decision"]  # the recommended preset's
    again = learn.again_task(tasks[0], _result("mug_1", 10), None)
    assert again["params"]["gpis_fill_radius"] == 3.0 and again["params"]["stop_at_decision"]
    assert learn.learn_tasks(["mug_1"], ["few"], [(0.0, 0.0)], 1, 0, {}, None)[0]["params"] is None
