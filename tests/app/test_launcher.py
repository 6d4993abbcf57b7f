"""app.py's logging, without Qt: errors the window shows and uncaught ones reach the log."""

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
