"""Pareto front, configurations and growth exponents (no long runs)."""

import os
from pathlib import Path

import numpy as np
import pytest

from tactile_viz.engine.session import SessionParams
from tactile_viz.experiments import tradeoff
from tactile_viz.experiments.aggregate import markdown_table
from tactile_viz.experiments.prior_scaling import library_of_size
from tactile_viz.experiments.scaling import growth_exponent


def test_pareto_front():
    times = [1.0, 2.0, 3.0, 2.5, 1.0, np.nan]
    errors = [0.9, 0.5, 0.4, 0.6, 1.0, 0.1]
    assert tradeoff.pareto_front(times, errors) == [0, 1, 2]


def test_every_configuration_is_valid_and_the_presets_are_unchanged():
    for name in tradeoff.CONFIGS:
        SessionParams.from_dict(tradeoff.config_params(name))
    assert tradeoff.config_params("gpis24")["gpis_resolution"] == 24
    assert tradeoff.config_params("coarse-keys")["filter"]["distance_step"] == 0.2
    assert tradeoff.config_params("recommended") == SessionParams().to_dict()
    assert tradeoff.describe("eps0.4") == "eps=0.4"


def test_rows_mark_the_front():
    def result(config, seconds, pose):
        return {"object": "mug_1", "seed": 0, "strategy": "gpis-dhd", "seconds": seconds,
                "terminated_at": 1, "task": {"kind": "tradeoff", "tag": config},
                "steps": [{"t": 1, "map_class": "mug_1", "pose_error": pose, "dhd": 0.5,
                           "novel": False, "recon_error": None, "n_particles": 10}]}

    rows = tradeoff.rows_from_results([result("fast", 1.0, 0.5), result("paper", 2.0, 0.3),
                                       result("sdf32", 3.0, 0.6)], {"mug_1": "known"})
    front = {r["config"]: bool(r.get("front_pose_error")) for r in rows}
    assert front == {"fast": True, "paper": True, "sdf32": False}
    assert rows[0]["pose_error_ci"] == 0 and rows[0]["max_particles"] == 10


def test_a_point_is_near_the_front_unless_beaten_beyond_its_interval():
    times, errors = [1.0, 2.0, 3.0], [0.5, 0.55, 0.9]
    # The second is slower and worse than the first, but within its interval (0.45-0.65);
    # the third's interval (0.8-1.0) lies above the first's mean.
    lower = [0.4, 0.45, 0.8]
    assert tradeoff.pareto_front(times, errors) == [0]
    assert tradeoff.front_within_interval(times, errors, lower) == [0, 1]


def test_rows_give_t_intervals_over_seeds():
    def result(seed, pose):
        return {"object": "mug_1", "seed": seed, "strategy": "gpis-dhd", "seconds": 1.0,
                "terminated_at": 1, "task": {"kind": "tradeoff", "tag": "paper"},
                "steps": [{"t": 1, "map_class": "mug_1", "pose_error": pose, "dhd": 0.5,
                           "novel": False, "recon_error": None, "n_particles": 10}]}

    poses = [0.1, 0.2, 0.3, 0.4, 0.5]
    (row,) = tradeoff.rows_from_results([result(i, p) for i, p in enumerate(poses)],
                                        {"mug_1": "known"})
    assert row["pose_error"] == pytest.approx(0.3)
    # t(0.975, 4) = 2.776, sd 0.158: not the normal 1.96.
    assert row["pose_error_ci"] == pytest.approx(2.776 * np.std(poses, ddof=1) / np.sqrt(5),
                                                 rel=1e-3)


def test_growth_exponent_of_a_power_law():
    sizes = np.array([10, 20, 40, 80])
    assert growth_exponent(sizes, 3e-4 * sizes ** 1.7) == pytest.approx(1.7)
    assert np.isnan(growth_exponent([10], [1.0]))


def test_library_of_forty_priors_has_unique_names():
    library = library_of_size(40)
    assert len(library) == 40 and len(set(library.names)) == 40
    assert len({model.content_hash for model in library}) == 40
    # Variants keep their stretched size: a stretched mug is another object.
    lengths = [model.length for model in library]
    assert lengths[:20] == pytest.approx([6.0] * 20) and 6 * 0.75 <= min(lengths)
    assert len({round(length, 6) for length in lengths[20:]}) == 20 and max(lengths) <= 8.0


def test_small_values_keep_their_digits():
    assert "0.000123" in markdown_table(["x"], [[0.000123]])


def test_matching_trials_of_another_run_are_reused(tmp_path):
    from tactile_viz.engine.shape.library import PriorLibrary
    from tactile_viz.experiments.runner import task_key
    from tactile_viz.experiments.trial_files import read_trials, write_trial

    (other := tmp_path / "paper_run" / "trials").mkdir(parents=True)
    tasks = tradeoff.plan(["mug_1"], 2, ["recommended", "fast"], None)
    done = {"object": "mug_1", "seed": 1, "strategy": "gpis-dhd", "seconds": 2.0,
            "params": tradeoff.config_params("recommended"),
            "library": PriorLibrary.bundled("known").names,
            "task": {"kind": "protocol", "max_steps": None}, "steps": []}
    write_trial(other, "protocol__mug_1__s1", done)
    out = tmp_path / "out"
    out.mkdir()
    left = tradeoff.reuse_trials(tasks, [tmp_path / "paper_run"], out)
    assert len(left) == 3 and all((t["tag"], t["seed"]) != ("recommended", 1) for t in left)
    (copied,) = read_trials(out)
    assert copied["task"]["tag"] == "recommended" and copied["task"]["reused"]
    reused = next(t for t in tasks if t["tag"] == "recommended" and t["seed"] == 1)
    assert (out / f"{task_key(reused)}.json.gz").exists()


def test_prior_sweep_measures_whole_trials_on_a_small_library():
    """bench scaling's prior sweep end to end on 3 priors and 4 short trials (every prior
    once before any twice), and the projection from two sizes."""
    from tactile_viz.experiments import prior_scaling

    result = prior_scaling.measure_size(3, trials=4, max_steps=3)
    rows = result["trials"]
    assert len(rows) == 4 and rows[3]["object"] == rows[0]["object"]
    assert len({row["object"] for row in rows[:3]}) == 3
    assert all(row["steps"] == 3 and row["filter_mean"] > 0 for row in rows)
    summary = prior_scaling.summary_row(result)
    assert summary["trials"] == 4 and 0 < summary["bank_megabytes"] < 5
    assert summary["resident_megabytes"] > 0 and summary["peak_megabytes"] > 0
    assert 0 <= summary["built"] <= 3 and summary["build_resident_megabytes"] > 0
    assert summary["build_workers"] == 0  # fewer than CHILD_MIN to build: in the process
    start = prior_scaling.start_row({**summary, "built": 2, "bank_seconds": 3.0})
    assert start["built_seconds_each"] == 1.5 and start["build_workers"] == 0
    warm = prior_scaling.measure_load(3)
    assert warm["warm_resident_megabytes"] > 0 and warm["warm_peak_megabytes"] > 0
    other = {**summary, "priors": 30, "resident_megabytes": summary["resident_megabytes"] + 27,
             "bank_megabytes": summary["bank_megabytes"] * 10,
             "filter_mean": summary["filter_mean"] * 2}
    projected = prior_scaling.projection([summary, other], target=300)
    assert projected["megabytes_per_prior"] == pytest.approx(1.0)
    assert projected["update_seconds"] > other["filter_mean"]


def test_a_cold_sweep_gives_each_size_an_empty_cache_of_its_own(monkeypatch):
    from tactile_viz.engine.io.cache import ENV_VAR
    from tactile_viz.experiments.prior_scaling import _own_cache

    monkeypatch.setenv(ENV_VAR, "/somewhere/warm")
    with _own_cache(True):
        folder = Path(os.environ[ENV_VAR])
        assert folder.is_dir() and not any(folder.iterdir())
    assert os.environ[ENV_VAR] == "/somewhere/warm" and not folder.exists()
    with _own_cache(False):
        assert os.environ[ENV_VAR] == "/somewhere/warm"
