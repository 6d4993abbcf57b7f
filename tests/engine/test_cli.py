import json
import subprocess
import sys

import pytest

from tactile_viz.__main__ import main


def test_objects_json_contract(capsys):
    assert main(["objects", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert len(listed) == 20
    assert all(set(item) == {"name", "set", "variant_of"} for item in listed)
    variants = {item["name"]: item["variant_of"] for item in listed}
    assert variants["mug_2"] == "mug_1" and variants["mug_1"] is None
    assert sum(item["set"] == "known" for item in listed) == 10
    assert {"mug_1", "home_chair"} <= {item["name"] for item in listed}


def test_objects_table_for_people():
    result = subprocess.run([sys.executable, "-m", "tactile_viz", "objects"],
                            capture_output=True, text=True, check=True)
    lines = result.stdout.splitlines()
    assert lines[0].split()[:2] == ["name", "set"]
    assert any(line.split()[:3] == ["mug_2", "novel", "mug_1"] for line in lines)


def test_help_lists_commands():
    result = subprocess.run([sys.executable, "-m", "tactile_viz", "--help"],
                            capture_output=True, text=True, check=True)
    assert "objects" in result.stdout and "bench" in result.stdout


def test_repeated_prior_file_flags_add_up(tmp_path, monkeypatch):
    """``--prior-file B --prior-file C`` means both files, not only C (issue 17)."""
    from tactile_viz.__main__ import build_parser

    monkeypatch.chdir(tmp_path)
    for name in "ABCD":
        (tmp_path / f"{name}.off").write_text("")  # only their existence is checked here
    parse = build_parser().parse_args
    args = parse(["trial", "--object-file", "A.off", "--prior-file", "B.off",
                  "--prior-file", "C.off"])
    assert args.prior_file == ["B.off", "C.off"]
    args = parse(["trial", "--object-file", "A.off", "--prior-file", "B.off", "C.off",
                  "--prior-file", "D.off"])
    assert args.prior_file == ["B.off", "C.off", "D.off"]
    assert parse(["trial", "--object", "mug_1"]).prior_file is None


def test_extend_list_replaces_the_default_then_adds_up():
    import argparse

    from tactile_viz.cli import ExtendList

    parser = argparse.ArgumentParser()
    parser.add_argument("--objects", action=ExtendList, default=["mug_1", "elephant"])
    parser.add_argument("--sizes", type=int, action=ExtendList, default=[50])
    assert parser.parse_args([]).objects == ["mug_1", "elephant"]
    args = parser.parse_args(["--objects", "a", "--sizes", "1", "2", "--objects", "b", "c",
                              "--sizes", "3"])
    assert args.objects == ["a", "b", "c"] and args.sizes == [1, 2, 3]
    assert parser.parse_args([]).objects == ["mug_1", "elephant"]  # default not mutated


def test_every_list_option_adds_up():
    """No command line takes several values with a plain ``nargs="+"`` (the last repeat
    would win): each uses :class:`tactile_viz.cli.ExtendList`."""
    from pathlib import Path

    import tactile_viz

    package = Path(tactile_viz.__file__).parent
    sources = [*package.rglob("*.py"), package.parent / "app.py"]
    offenders = [str(path) for path in sources if path.exists()
                 and 'nargs="+"' in path.read_text() and path.name != "cli.py"]
    assert offenders == []


def test_benchmark_list_options_add_up(monkeypatch):
    """A benchmark's parser (built inside its ``main``): repeated ``--objects`` add up."""
    import argparse

    import pytest

    from tactile_viz.experiments import sdf_speed

    parsed = []
    original = argparse.ArgumentParser.parse_args

    def parse_and_stop(self, args=None, namespace=None):
        parsed.append(original(self, args, namespace))
        raise SystemExit(0)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_and_stop)
    with pytest.raises(SystemExit):
        sdf_speed.main(["--objects", "mug_1", "--objects", "armadillo", "vase_2"])
    assert parsed[0].objects == ["mug_1", "armadillo", "vase_2"]


def test_comma_list_options_add_up_too():
    from tactile_viz.experiments import paper, tradeoff
    from tactile_viz.experiments.paper import split_names

    args = paper.build_parser().parse_args(["--strategies", "gpis-dhd", "--strategies", "rrt"])
    assert split_names(args.strategies) == ["gpis-dhd", "rrt"]
    args = tradeoff.build_parser().parse_args(["--configs", "recommended,fast",
                                               "--configs", "paper"])
    assert split_names(args.configs) == ["recommended", "fast", "paper"]
    assert split_names(tradeoff.build_parser().parse_args([]).configs) == list(tradeoff.CONFIGS)


@pytest.fixture
def reset_logging():
    """Remove the handlers setup_logging attaches, so later tests log nowhere new."""
    from tactile_viz.cli import stop_logging

    yield
    stop_logging()


def test_log_file_gets_the_error_and_its_traceback(tmp_path, capsys, reset_logging):
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"")
    log_file = tmp_path / "logs" / "run.log"
    assert main(["--log-file", str(log_file), "trial", "--object-file", str(bad),
                 "--no-progress"]) == 2
    assert "broken.stl" in capsys.readouterr().err  # the user still sees the message
    text = log_file.read_text()
    assert "command: " in text and "Traceback" in text and "broken.stl" in text


def test_verbose_logs_debug_on_stderr(capsys, reset_logging):
    assert main(["--verbose", "objects", "--json"]) == 0
    assert "DEBUG tactile_viz.__main__: command: " in capsys.readouterr().err
    assert main(["objects", "--json"]) == 0
    assert "DEBUG" not in capsys.readouterr().err


def test_unwritable_log_file_is_reported_not_fatal(tmp_path, capsys, reset_logging):
    from tactile_viz.cli import setup_logging

    blocker = tmp_path / "file"
    blocker.write_text("")
    assert setup_logging(log_file=blocker / "app.log") is None
    assert "cannot write the log file" in capsys.readouterr().err


def test_default_log_file_is_in_the_state_folder(monkeypatch, tmp_path):
    from pathlib import Path

    from tactile_viz.cli import default_log_file

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    assert default_log_file() == tmp_path / "tactile_viz" / "app.log"
    monkeypatch.delenv("XDG_STATE_HOME")
    assert default_log_file() == Path.home() / ".local" / "state" / "tactile_viz" / "app.log"
