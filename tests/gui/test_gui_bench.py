"""``bench gui`` on a few steps: every number of the table is there and the run ends."""

import pytest

from tactile_viz.experiments import gui_bench

pytestmark = pytest.mark.gui


def test_short_bench_gui_run(qapp, capsys):
    args = gui_bench._parser().parse_args(["--objects", "mug_1", "--max-steps", "4",
                                           "--pause-after", "2", "--size", "1280x720",
                                           "--repeats", "2"])
    rows = gui_bench.run(args)
    row = rows[0]
    assert row["steps"] == row["engine_steps"] == 4 and row["shown_last_step"]
    assert 1 <= row["drawn"] <= 4 and row["drawing_seconds"] > 0
    assert len(row["engine_runs"]) == 3 and len(row["gui_runs"]) == 2
    low, high = row["overhead_interval"]
    assert low <= sum(row["overhead_runs"]) / 2 <= high and row["engine"] == "process"
    assert row["pause_extra_steps"] == 0 and row["close_extra_steps"] == 0
    assert row["close_latency"] < 30
    table = gui_bench.format_table(rows)
    assert table.count("\n") == 2 and "mug_1 | 4 |" in table
    assert "mug_1: overhead" in gui_bench.verdicts(rows)
