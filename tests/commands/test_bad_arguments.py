"""Every command's options with bad values: exit status 2, one line on stderr, no traceback,
and nothing run (the values are checked before any mesh is loaded or trial started)."""

import json
import subprocess
import sys

import pytest
import trimesh

from tactile_viz.__main__ import main
from tactile_viz.cli import stop_logging

# Placeholders, replaced by paths under tmp_path: MISSING does not exist, DIR is a folder,
# FILE an empty file, OBS an observation file.
COUNT = ["0", "-1", "nan", "1.5", "x", "", str(10**30)]
SEED = ["-1", "nan", "1e3", "x", str(10**30)]
STEPS = ["0", "-2", "inf", "x"]
WORKERS = ["0", "-1", "x", "100000"]
IN_FILE = ["MISSING", "DIR", ""]
IN_DIR = ["MISSING", "FILE"]
OUT_FILE = ["MISSING/out.json", "DIR", "FILE/out.json", ""]
OUT_DIR = ["FILE", "FILE/sub", ""]
NAME = ["nosuch", "", "mug_1,nosuch"]
NOISE = {"--position-noise": ["-1", "nan", "inf", "x"], "--normal-noise": ["-1", "nan", "x"],
         "--outlier-probability": ["-0.1", "0.5", "nan", "x"]}
UNITS = {**NOISE, "--units": ["parsec", ""], "--mesh-units": ["parsec", "0", "-1", "nan", "inf"],
         "--normalise": ["0", "-1", "nan", "inf", "x"], "--learn-to": OUT_DIR}

TRIAL = ["trial", "--object", "mug_1", "--no-progress"]
REPLAY = ["replay", "--observations", "OBS", "--no-progress"]
COMMANDS = {
    "trial": (TRIAL, {"--max-steps": STEPS, "--seed": SEED, "--json": OUT_FILE,
                      "--export": OUT_DIR, "--prior-file": IN_FILE, "--library-dir": IN_DIR,
                      "--library": NAME, "--strategy": NAME, "--preset": NAME, **UNITS}),
    "trial-object": (["trial"], {"--object": NAME, "--object-file": IN_FILE}),
    "replay": (REPLAY, {"--seed": SEED, "--json": OUT_FILE, "--export": OUT_DIR,
                        "--prior-file": IN_FILE, "--library-dir": IN_DIR, "--preset": NAME,
                        **UNITS}),
    "replay-observations": (["replay"], {"--observations": IN_FILE}),
    "objects": (["objects"], {"--jsn": [None], "--json": ["x"]}),
    "bench paper": (["bench", "paper"], {
        "--trials": COUNT, "--objects": NAME, "--strategies": NAME, "--workers": WORKERS,
        "--seed": SEED, "--max-steps": STEPS, "--out": OUT_DIR, "--learned-from": IN_FILE,
        "--preset": NAME, "--outliers": ["1", "-0.1", "x"], **NOISE}),
    "bench tradeoff": (["bench", "tradeoff"], {
        "--seeds": COUNT, "--objects": NAME, "--configs": NAME, "--workers": WORKERS,
        "--max-steps": STEPS, "--out": OUT_DIR, "--reuse": IN_DIR}),
    "bench scaling": (["bench", "scaling"], {
        "--sizes": COUNT, "--repeats": COUNT, "--priors": COUNT, "--prior-trials": COUNT,
        "--seed": SEED, "--object": NAME, "--prior-max-steps": COUNT, "--out": OUT_DIR}),
    "bench noise": (["bench", "noise"], {
        "--seeds": COUNT, "--contacts": COUNT, "--objects": NAME + ["mug_2"],
        "--levels": ["nan:1", "0:inf", "0.5:-1", "1", "x:y"], "--configs": NAME,
        "--out": OUT_DIR}),
    "bench sizes": (["bench", "sizes"], {
        "--seeds": COUNT, "--objects": NAME, "--workers": WORKERS, "--out": OUT_DIR}),
    "bench sdf": (["bench", "sdf"], {
        "--points": COUNT, "--resolution": ["0", "7", "100000", "nan"], "--objects": NAME,
        "--seed": SEED}),
    "bench step": (["bench", "step"], {
        "--sizes": COUNT, "--repeats": COUNT, "--seed": SEED, "--object": NAME}),
    "bench realmesh": (["bench", "realmesh"], {
        "--trials": COUNT, "--workers": WORKERS, "--seed": SEED, "--max-steps": STEPS,
        "--objects": NAME, "--cases": NAME, "--data-dir": IN_DIR, "--out": OUT_DIR,
        "--bundled": NAME}),
    "bench gui": (["bench", "gui"], {
        "--objects": NAME, "--seed": SEED, "--preset": NAME, "--max-steps": ["-1", "x"],
        "--repeats": COUNT, "--pause-after": COUNT, "--size": ["10x10", "x", "1500x"],
        "--json": OUT_FILE, "--engine": NAME}),
}
CASES = [(command, option, value) for command, (_, options) in COMMANDS.items()
         for option, values in options.items() for value in values]


@pytest.fixture
def paths(tmp_path):
    (tmp_path / "dir").mkdir()
    (tmp_path / "file").write_text("")
    observations = tmp_path / "touches.csv"
    observations.write_text("kind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n")
    places = {"MISSING": tmp_path / "missing", "DIR": tmp_path / "dir",
              "FILE": tmp_path / "file", "OBS": observations}

    def fill(word):
        for key, path in places.items():
            if word == key or word.startswith(key + "/"):
                return str(path) + word[len(key):]
        return word

    return fill


@pytest.fixture(autouse=True)
def no_logging_left():
    yield
    stop_logging()


def exit_status(argv):
    """``main(argv)``'s exit status, whether it returns it or exits."""
    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code


def assert_one_line_error(err):
    assert len(err.splitlines()) == 1, err
    assert "error: " in err and "Traceback" not in err


@pytest.mark.parametrize("command, option, value", CASES,
                         ids=[f"{c}:{o}={v}" for c, o, v in CASES])
def test_bad_value_is_one_line_and_status_2(command, option, value, paths, capsys):
    base, _ = COMMANDS[command]
    argv = [paths(word) for word in base] + [option] + ([] if value is None else [paths(value)])
    assert exit_status(argv) == 2
    captured = capsys.readouterr()
    assert_one_line_error(captured.err)
    assert captured.out == ""


def test_library_with_library_dir_is_still_refused(paths, capsys):
    assert exit_status(TRIAL + ["--library", "known", "--library-dir", paths("DIR")]) == 2
    assert "not allowed with argument" in capsys.readouterr().err


@pytest.mark.parametrize("what", ["paper", "tradeoff", "scaling", "noise", "sizes", "sdf",
                                  "step", "realmesh", "gui"])
def test_bench_help_lists_its_options(what, capsys):
    assert exit_status(["bench", what, "--help"]) == 0
    assert "usage: python -m tactile_viz bench " + what in capsys.readouterr().out


def test_unknown_command_is_one_line(capsys):
    assert exit_status(["nosuch"]) == 2
    assert_one_line_error(capsys.readouterr().err)
    assert exit_status(["bench", "nosuch"]) == 2
    assert_one_line_error(capsys.readouterr().err)


def test_unexpected_error_is_one_line_and_its_traceback_is_logged(tmp_path, capsys,
                                                                  monkeypatch):
    from tactile_viz.engine.shape import objects

    def broken():
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(objects, "bundled_manifest", broken)
    log_file = tmp_path / "run.log"
    assert main(["--log-file", str(log_file), "objects"]) == 1
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert "ZeroDivisionError: a bug" in err and str(log_file) in err
    text = log_file.read_text()
    assert "Traceback" in text and "ZeroDivisionError: a bug" in text
    assert main(["objects"]) == 1  # without a log file: where to find the traceback
    assert "--verbose" in capsys.readouterr().err


def test_a_benchmark_stopping_with_a_message_is_one_line(tmp_path, capsys):
    """A benchmark's ``SystemExit("message")`` is shown like any error, with status 2."""
    broken = tmp_path / "broken.ply"
    broken.write_text("not a mesh")
    assert main(["bench", "paper", "--trials", "1", "--objects", "mug_1", "--learned-from",
                 str(broken), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert "cannot read the learned prior" in err


@pytest.mark.slow
@pytest.mark.parametrize("argv", [["trial", "--object", "mug_1", "--max-steps", "0"],
                                  ["bench", "sdf", "--points", "-5"]])
def test_no_traceback_from_the_real_command_line(argv):
    result = subprocess.run([sys.executable, "-m", "tactile_viz", *argv],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and result.stdout == ""
    assert_one_line_error(result.stderr)


def test_real_command_line_logs_the_traceback_to_the_file(tmp_path):
    """Run as ``python -m`` (module ``__main__``), the error still reaches the log file."""
    empty = tmp_path / "empty.stl"
    empty.write_text("")
    log_file = tmp_path / "run.log"
    result = subprocess.run([sys.executable, "-m", "tactile_viz", "--log-file", str(log_file),
                             "trial", "--object-file", str(empty), "--no-progress"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert_one_line_error(result.stderr)
    assert "Traceback" in log_file.read_text()


@pytest.mark.parametrize("what", ["paper", "tradeoff", "realmesh"])
def test_report_only_without_trials_is_one_line(what, tmp_path, capsys):
    assert main(["bench", what, "--report-only", "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert "no trial files" in err


def test_run_trial_refuses_no_steps():
    from tactile_viz.commands.trial import run_trial
    from tactile_viz.engine.errors import ParameterError

    with pytest.raises(ParameterError, match="max_steps"):
        run_trial(None, None, max_steps=0)


def test_objects_json_names_the_variants(capsys):
    assert main(["objects", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert {"name", "set", "variant_of"} == set(listed[0])
    assert {item["name"]: item["variant_of"] for item in listed}["ice_cream_2"] == "ice_cream_1"


def test_every_parser_has_one_line_errors():
    """No parser of the package is a plain ``argparse.ArgumentParser`` (its errors add a
    usage line); the desktop app's own parsers are left to the app."""
    from pathlib import Path

    import tactile_viz

    package = Path(tactile_viz.__file__).parent
    offenders = [str(path) for path in package.rglob("*.py")
                 if "argparse.ArgumentParser(" in path.read_text()
                 and path.name != "cli.py" and "gui" not in path.parts]
    assert offenders == []


# ---------------------------------------------------------------- priors: bundled + extra
def _box_file(folder, name, size=(6, 3, 2)):
    path = folder / f"{name}.ply"
    trimesh.creation.box(size).export(path)
    return str(path)


def _priors(**given):
    import argparse

    from tactile_viz.commands.trial import load_priors

    args = argparse.Namespace(library=None, library_dir=None, prior_file=None)
    vars(args).update(given)
    return load_priors(args)


def test_prior_files_add_to_the_bundled_set(tmp_path):
    from tactile_viz.engine.shape.objects import bundled_names

    extra = _box_file(tmp_path, "brick")
    assert _priors(library="novel", prior_file=[extra]).names == [*bundled_names("novel"),
                                                                   "brick"]
    assert _priors(prior_file=[extra]).names == ["brick"]  # alone: only the files


def test_prior_files_add_to_a_saved_library(tmp_path):
    from tactile_viz.engine.shape.library import PriorLibrary

    saved = PriorLibrary()
    saved.add_file(_box_file(tmp_path, "slab", (6, 6, 1)))
    saved.save(tmp_path / "library")
    extra = _box_file(tmp_path, "brick")
    assert _priors(library_dir=str(tmp_path / "library"),
                   prior_file=[extra]).names == ["slab", "brick"]


def test_prior_file_with_the_name_of_a_prior_is_one_clear_error(tmp_path, capsys):
    clash = _box_file(tmp_path, "mug_1")
    assert main(["trial", "--object", "mug_2", "--library", "known", "--prior-file", clash,
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert "already a prior named 'mug_1'" in err
    brick = _box_file(tmp_path, "brick")
    with pytest.raises(Exception, match="already a prior named 'brick'"):
        _priors(prior_file=[brick, brick])
