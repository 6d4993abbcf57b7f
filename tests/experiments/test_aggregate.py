"""Aggregation and tables on synthetic trial dicts (no engine runs)."""

import math

import numpy as np
import pytest

from tactile_viz.experiments import aggregate


def fake_trial(name, strategy="gpis-dhd", seed=0, pose=(2.0, 1.0, 0.5), recon=None,
               novel=False, map_class=None, poisson=None, kind="protocol",
               library="known", terminated=True):
    """A trial dict shaped like ``run_task``'s result."""
    recon = recon or [None] * len(pose)
    steps = [{"t": t + 1, "map_class": map_class or name, "pose_error": p, "dhd": 3.0 - t,
              "novel": novel, "recon_error": r, "n_particles": 100 * (t + 1), "n_contacts": t + 1,
              "n_noncontacts": 0, "step_seconds": 0.1}
             for t, (p, r) in enumerate(zip(pose, recon))]
    result = {"object": name, "seed": seed, "strategy": strategy, "preset": "paper",
              "terminated_at": len(steps) if terminated else None, "seconds": 1.0,
              "steps": steps, "task": {"kind": kind, "library_label": library}}
    if poisson is not None:
        result["poisson"] = {"recon_error": poisson}
    return result


def test_summary_of_a_known_trial():
    summary = aggregate.summarise_trial(fake_trial("mug_1"))
    assert summary["correct"] and not summary["novel"]
    assert summary["steps_to_pose"] == 3 and summary["steps"] == 3
    assert summary["pose_error"] == 0.5 and summary["recon_error"] == 0.5
    assert summary["max_particles"] == 300


def test_the_first_decided_step_is_reported_and_tabled():
    decided = fake_trial("mug_1", pose=(2.0, 1.0, 0.5, 0.4))
    for record, flag in zip(decided["steps"], (False, True, False, True)):
        record["decided"] = flag
    undecided = fake_trial("mug_1", seed=1)  # records made before the decision existed
    summaries = [aggregate.summarise_trial(t) for t in (decided, undecided)]
    assert summaries[0]["decided_at"] == 2 and summaries[1]["decided_at"] is None
    row = aggregate.known_rows(summaries)[0]
    header = aggregate.KNOWN_HEADER
    assert row[header.index("decided")] == "1/2"
    assert row[header.index("decided at (median)")] == 2.0


def test_summary_of_a_novel_trial_uses_the_gpis_error():
    summary = aggregate.summarise_trial(
        fake_trial("vase_2", pose=(2.0, 1.5, 1.4), recon=(None, 0.7, 0.4), novel=True,
                   map_class="bottle_1", poisson=0.9))
    assert not summary["correct"] and summary["novel"]
    assert summary["recon_error"] == 0.4 and summary["pose_error"] == 1.4
    assert summary["poisson_error"] == 0.9
    assert summary["steps_to_pose"] is None and summary["steps_to_recon"] == 3


def test_failed_trial_is_kept_with_its_error():
    summary = aggregate.summarise_trial({"object": "mug_1", "seed": 0, "strategy": "rrt",
                                         "error": "Traceback ...\nValueError: boom"})
    assert "boom" in summary["error"]
    rows = aggregate.known_rows([summary])
    assert rows[0][2] == 0


def test_curve_holds_the_last_value_and_has_a_band():
    trials = [fake_trial("mug_1", pose=(2.0, 1.0)), fake_trial("mug_1", pose=(4.0, 3.0, 1.0))]
    steps, mean, half = aggregate.curve(trials, "pose_error")
    assert steps.tolist() == [1, 2, 3]
    assert mean.tolist() == pytest.approx([3.0, 2.0, 1.0])
    assert half[0] == pytest.approx(12.706 * np.std([2.0, 4.0], ddof=1) / math.sqrt(2), rel=1e-4)
    assert half[2] == 0.0


def test_mean_std_ignores_none():
    assert aggregate.mean_std([1.0, None, 3.0])[:2] == (2.0, pytest.approx(math.sqrt(2)))
    assert math.isnan(aggregate.mean_std([None])[0])


def test_reconstruction_comparison_checks():
    summaries = [aggregate.summarise_trial(t) for t in (
        fake_trial("vase_2", pose=(1.5,), recon=(0.4,), novel=True, map_class="bottle_1",
                   poisson=0.6),
        fake_trial("dragon", pose=(3.0,), recon=(0.8,), novel=True, map_class="armadillo",
                   poisson=0.5),
        fake_trial("guitar_2", pose=(0.4,), novel=False, map_class="guitar_1", poisson=1.0),
        fake_trial("vase_2", strategy="rrt", pose=(9.0,), recon=(9.0,), novel=True,
                   poisson=0.1))]
    rows, checks = aggregate.reconstruction_comparison(summaries)
    assert [row[0] for row in rows] == ["dragon", "guitar_2", "vase_2"]
    assert checks["gpis_beats_poisson"] == (2, 3)  # vase_2 and guitar_2 (PF-MAP = GPIS)
    assert checks["gpis_beats_map_when_novel"] == (2, 2)
    vase = rows[2]
    assert vase[3] == 0.4 and vase[4] == 0.335  # ours next to the paper's


def test_markdown_tables_have_one_row_per_group():
    summaries = [aggregate.summarise_trial(fake_trial("mug_1", strategy=s, seed=k))
                 for s in ("gpis-dhd", "rrt") for k in range(3)]
    table = aggregate.markdown_table(aggregate.KNOWN_HEADER, aggregate.known_rows(summaries))
    lines = table.splitlines()
    assert len(lines) == 4 and lines[2].startswith("| mug_1 | gpis-dhd | 3 | 3/3 |")


def test_learned_rows_count_recognition_of_the_learned_prior():
    before = [aggregate.summarise_trial(fake_trial("home_chair", pose=(2.0,) * 5, novel=True,
                                                   map_class="office_chair"))]
    after = [aggregate.summarise_trial(fake_trial("home_chair", seed=1000 + k,
                                                  map_class="home_chair_learned", kind="learned"))
             for k in range(2)]
    after.append(aggregate.summarise_trial(fake_trial(
        "home_chair", seed=1002, novel=True, map_class="home_chair_learned", kind="learned")))
    rows = aggregate.learned_rows(before, after)
    # columns: library, trials, MAP class = learned, recognised, judged novel, ...
    assert rows[0][2:5] == ["0/1", "0/1", "1/1"] and rows[0][-1] == 5
    assert rows[1][2:5] == ["3/3", "2/3", "1/3"] and rows[1][-1] == 3


def test_confidence_half_widths_use_students_t():
    from tactile_viz.experiments.aggregate import ci95, curve, t95

    assert t95(10) == pytest.approx(2.262, abs=1e-3) and t95(1) == 0.0
    values = [1.0, 2.0, 4.0]
    assert ci95(values) == pytest.approx(4.303 * np.std(values, ddof=1) / np.sqrt(3), rel=1e-3)
    results = [{"steps": [{"e": v}, {"e": v}]} for v in values]
    _, mean, half = curve(results, "e")
    assert half[0] == pytest.approx(ci95(values)) and mean[1] == pytest.approx(7 / 3)
