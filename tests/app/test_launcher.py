"""app.py without a window: its options (a user's scene, bad values refused before any work)
and its logging (errors the window shows and uncaught ones reach the log)."""

import importlib.util
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def launcher():
    spec = importlib.util.spec_from_file_location("app_launcher", REPO_ROOT / "app.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def log_file(tmp_path):
    from tactile_viz.cli import setup_logging, stop_logging

    yield setup_logging(log_file=tmp_path / "app.log")
    stop_logging()


class FakeWindow:
    def __init__(self):
        self.shown = []

    def show_error(self, error):
        self.shown.append(error)


def test_errors_shown_and_uncaught_are_logged(launcher, log_file, monkeypatch):
    window = FakeWindow()
    passed_on = []
    # pytest-qt fails a test whose exceptions reach its own hook: stand in for the default.
    monkeypatch.setattr(sys, "excepthook", lambda *info: passed_on.append(info[1]))
    original_hook = sys.excepthook
    default_hook = launcher.log_errors_shown(window)
    try:
        try:
            raise ValueError("sigma_d must be positive")
        except ValueError as error:
            window.show_error(error)
        assert [str(e) for e in window.shown] == ["sigma_d must be positive"]
        try:
            raise RuntimeError("worker died")
        except RuntimeError:
            sys.excepthook(*sys.exc_info())
    finally:
        sys.excepthook = default_hook
    assert default_hook is original_hook
    assert [str(e) for e in passed_on] == ["worker died"]  # and on to the default hook
    text = log_file.read_text()
    assert "shown to the user: sigma_d must be positive" in text
    assert "uncaught exception" in text and "RuntimeError: worker died" in text
    assert text.count("Traceback") == 2


def test_default_log_file_option(launcher, monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    assert launcher.parse_args([]).log_file == str(tmp_path / "tactile_viz" / "app.log")
    assert launcher.parse_args(["--log-file", ""]).log_file == ""


# ---------------------------------------------------------------- options of a user's scene
@pytest.fixture
def box_file(tmp_path):
    import trimesh

    path = tmp_path / "crate.stl"
    trimesh.creation.box(extents=(6, 3, 2)).export(path)
    return path


@pytest.fixture
def touches_file(tmp_path):
    path = tmp_path / "touches.csv"
    path.write_text("kind,x,y,z,nx,ny,nz\ncontact,0.5,0,1,0,0,1\nnoncontact,2,0.4,0.1,,,\n")
    return path


def _refused(launcher, capsys, argv):
    """The options ``argv`` end the launcher with status 2 and one line on stderr."""
    with pytest.raises(SystemExit) as stop:
        launcher.main(["--log-file", "", *argv])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("argv, said", [
    (["--object-file", "no_such.stl"], "--object-file no_such.stl: no such file"),
    (["--prior-file", "{tmp}"], "not a file"),
    (["--observations", "{tmp}/none.csv"], "--observations"),
    (["--library-dir", "{tmp}/none"], "no such folder"),
    (["--seed", "-1"], "--seed must be 0 or more"),
    (["--steps", "-3"], "--steps must be 0 or more"),
    (["--seed", "x"], "invalid int value"),
    (["--library", "known", "--library-dir", "{tmp}"], "not allowed with"),
    (["--object", "mug_1", "--observations", "{tmp}/t.csv"], "not allowed with"),
    (["--object", "mug_1", "--object-name", "cup"], "--object-name names an --object-file"),
])
def test_bad_options_exit_2_with_one_line(launcher, capsys, tmp_path, argv, said):
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in argv]
    assert said in _refused(launcher, capsys, argv)


def test_screenshot_path_is_checked_first(launcher, capsys, tmp_path):
    err = _refused(launcher, capsys, ["--object-file", "no_such.stl", "--screenshot",
                                      str(tmp_path / "none" / "shot.png")])
    assert "--screenshot" in err and "does not exist" in err
    (tmp_path / "dir.png").mkdir()
    assert "is a folder" in _refused(launcher, capsys, ["--screenshot", str(tmp_path / "dir.png")])
    assert ".png" in _refused(launcher, capsys, ["--screenshot", str(tmp_path / "shot.gif")])


def test_broken_mesh_exits_2_before_the_window(launcher, capsys, tmp_path, monkeypatch):
    pytest.importorskip("PySide6")
    monkeypatch.setenv("DISPLAY", ":0")  # the display is not reached: the mesh fails first
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"\x00garbage" * 7)
    for argv in (["--object-file", str(broken)], ["--prior-file", str(broken)]):
        assert launcher.main(["--log-file", "", *argv]) == 2
        err = capsys.readouterr().err
        assert err.startswith("app.py: error: ") and "broken.stl" in err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_prior_files_add_to_a_library_or_stand_alone(launcher, box_file, tmp_path):
    from tactile_viz.engine import PriorLibrary

    def names(*argv):
        return launcher.load_priors(launcher.parse_args(["--log-file", "", *argv])).names

    known = PriorLibrary.bundled("known").names
    assert names() == known
    assert names("--prior-file", str(box_file)) == ["crate"]
    assert names("--library", "known", "--prior-file", str(box_file)) == known + ["crate"]
    PriorLibrary([PriorLibrary.bundled("novel")["vase_2"]]).save(tmp_path / "saved")
    assert names("--library-dir", str(tmp_path / "saved"), "--prior-file",
                 str(box_file)) == ["vase_2", "crate"]


def test_scene_from_a_mesh_file_and_from_recorded_touches(launcher, box_file, touches_file):
    args = launcher.parse_args(["--log-file", "", "--object-file", str(box_file), "--seed", "4",
                                "--prior-file", str(box_file)])
    scene = launcher.build_scene(args)
    assert scene.truth_model.name == "crate" and scene.seed == 4
    assert scene.library.names == ["crate"]
    args = launcher.parse_args(["--log-file", "", "--object-file", str(box_file),
                                "--object-name", "mug", "--prior-file", str(box_file)])
    assert launcher.build_scene(args).truth_model.name == "mug"  # a scan set's textured.obj
    args = launcher.parse_args(["--log-file", "", "--observations", str(touches_file),
                                "--library", "novel"])
    scene = launcher.build_scene(args)
    assert scene.truth is None and scene.recording[0] == str(touches_file)
    assert len(scene.recording[1]) == 2 and "vase_2" in scene.library.names
    assert scene.step().step == 1  # the recording's first touch


def test_the_app_command_runs_the_launcher_with_its_options(monkeypatch, capsys):
    import tactile_viz.launcher
    from tactile_viz.__main__ import main

    monkeypatch.setattr(sys, "argv", ["/venv/bin/tactile-viz"])  # the installed command
    with pytest.raises(SystemExit) as stop:
        main(["app", "--log-file", "", "--seed", "-1"])
    assert stop.value.code == 2
    assert capsys.readouterr().err == "tactile-viz app: error: --seed must be 0 or more, not -1\n"
    calls = []
    monkeypatch.setattr(tactile_viz.launcher, "main",
                        lambda argv, prog: calls.append((argv, prog)) or 0)
    assert main(["--verbose", "app", "--object", "vase_2", "--table"]) == 0
    assert calls == [(["--verbose", "--object", "vase_2", "--table"], "tactile-viz app")]
    with pytest.raises(SystemExit):  # the other commands still refuse unknown options
        main(["objects", "--table"])
    assert "unrecognized arguments: --table" in capsys.readouterr().err
