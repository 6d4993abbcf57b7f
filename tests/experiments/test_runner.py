"""Running trials: the same JSON serially, in a process pool and on a Dask cluster."""

import json

import pytest

from tactile_viz.experiments.runner import (
    ProcessPool,
    SerialPool,
    make_task,
    run_task,
    run_tasks,
    strip_timings,
    task_key,
)

TASKS = [make_task("mug_1", "gpis-dhd", seed=3, max_steps=5),
         make_task("vase_2", "rrt", seed=4, max_steps=5, poisson=True, poisson_depth=6)]


@pytest.fixture(scope="module")
def serial():
    return {task_key(t): strip_timings(run_task(t)) for t in TASKS}


def _run(pool):
    try:
        return {task_key(t): strip_timings(r) for t, r in run_tasks(TASKS, pool, progress=False)}
    finally:
        pool.close()


def test_serial_results_carry_the_benchmark_fields(serial):
    for result in serial.values():
        assert "error" not in result, result.get("error")
        assert len(result["steps"]) == 5
        assert len(result["final"]["contacts"]) == result["steps"][-1]["n_contacts"]
        json.dumps(result)
    vase = serial[task_key(TASKS[1])]
    pytest.importorskip("pymeshlab")
    assert vase["poisson"]["depth"] == 6


@pytest.mark.slow
def test_dask_cluster_gives_the_serial_json(serial):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            from tactile_viz.experiments.runner import DaskPool

            assert _run(DaskPool(client)) == serial


def test_follow_up_tasks_are_run():
    first = make_task("mug_1", seed=0, max_steps=1)
    extra = make_task("mug_1", seed=1, max_steps=1)
    seen = [t["seed"] for t, _ in run_tasks(
        [first], SerialPool(), lambda task, _: [extra] if task is first else [],
        progress=False)]
    assert seen == [0, 1]


def test_a_failing_trial_is_reported_not_raised():
    result = run_task(make_task("no_such_object", max_steps=1))
    assert "error" in result and result["task"]["object"] == "no_such_object"


@pytest.mark.slow
def test_process_pool_gives_the_serial_json(serial):
    assert _run(ProcessPool(2)) == serial


def test_trial_files_are_compressed_and_older_plain_ones_still_read(tmp_path):
    import gzip
    import json

    from tactile_viz.experiments.trial_files import read_trials, rounded, trial_path, write_trial

    result = {"object": "mug_1", "steps": [{"t": t, "dhd": 1.0 / (t + 1), "novel": t > 9,
                                            "recon_error": None} for t in range(400)]}
    (tmp_path / "a.json").write_text(json.dumps(result))  # an older run's file
    assert trial_path(tmp_path, "a").name == "a.json"
    written = write_trial(tmp_path, "b", result)
    stored = json.loads(gzip.decompress(written.read_bytes()))
    assert written.name == "b.json.gz" and stored == rounded(result)
    assert written.stat().st_size < len(json.dumps(result, indent=1)) / 4
    # Floats keep six significant digits; ints, booleans and None stay as they are.
    assert stored["steps"][2] == {"t": 2, "dhd": 0.333333, "novel": False, "recon_error": None}
    assert max(abs(s["dhd"] * (s["t"] + 1) - 1) for s in stored["steps"]) < 5e-6
    assert read_trials(tmp_path) == [result, rounded(result)]
    write_trial(tmp_path, "a", result)  # rewriting an old trial replaces its plain file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json.gz", "b.json.gz"]


def test_a_commands_workers_show_warnings_as_one_line(capfd, monkeypatch):
    # Under a command's one-line warnings (``python -m tactile_viz``), a worker's warning
    # is one line with the command's prefix, not Python's two lines with a source path.
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        raise AssertionError("the parent's own function is not for the workers")

    show.prog = "tactile-viz bench learn"
    monkeypatch.setattr(warnings, "showwarning", show)
    pool = ProcessPool(1)
    try:
        pool.executor.submit(warnings.warn, "cup.ply: repaired on loading\n1 hole closed").result()
    finally:
        pool.executor.shutdown()
    err = capfd.readouterr().err
    assert "tactile-viz bench learn: warning: cup.ply: repaired on loading 1 hole closed" in err
    assert "UserWarning" not in err and ".py:" not in err
