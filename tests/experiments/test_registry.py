"""The benchmarks are registered once (:data:`tactile_viz.experiments.BENCHMARKS`): each
names a module that imports and has a ``main``, and ``bench NAME --help`` answers for
each (argparse only: no benchmark runs)."""

import importlib

import pytest

from tactile_viz.__main__ import build_parser, main
from tactile_viz.experiments import BENCHMARKS


@pytest.mark.parametrize("name", list(BENCHMARKS))
def test_a_registered_benchmark_imports_and_has_a_main(name):
    module, what = BENCHMARKS[name]
    assert callable(importlib.import_module(module).main)
    assert what and "\n" not in what


@pytest.mark.parametrize("name", list(BENCHMARKS))
def test_bench_name_help_exits_0(name, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["bench", name, "--help"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith("usage:")


def test_the_bench_command_lists_the_registered_benchmarks_in_order():
    parser = build_parser()
    bench = parser._subparsers._group_actions[0].choices["bench"]
    (what,) = [action for action in bench._actions if action.dest == "what"]
    assert list(what.choices) == list(BENCHMARKS)
    for name, (_, help_text) in BENCHMARKS.items():
        assert f"{name}: {help_text}" in what.help
