"""The main window under Xvfb: stepping, running, pausing, layers, errors, closing."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QMessageBox

from tactile_viz.app.scene import Scene
from tactile_viz.cli import stop_logging
from tactile_viz.engine import PriorLibrary, load_bundled
from tactile_viz.gui.main_window import MainWindow

pytestmark = pytest.mark.gui
REPO_ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def known_library():
    return PriorLibrary.bundled("known")


@pytest.fixture
def settings(tmp_path):
    return QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat)


@pytest.fixture
def window(qtbot, known_library, settings):
    library = PriorLibrary(list(known_library))  # a fresh container per test
    scene = Scene("mug_1", seed=0, library=library)
    window = MainWindow(scene, settings=settings)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    yield window
    window.wait_for_worker()


@pytest.fixture
def errors(monkeypatch):
    shown = []
    monkeypatch.setattr(QMessageBox, "critical",
                        lambda parent, title, text, *a, **k: shown.append(text))
    return shown


def _wait_idle(qtbot, window, timeout=60_000):
    qtbot.waitUntil(lambda: not window.running, timeout=timeout)


def test_window_opens_with_default_scene(window):
    assert "truth" in window.layers.actors
    assert window.priors_panel.prior_list.count() == 10
    assert window.loop_panel.step_label.text() == "step 0"
    assert window.scene_panel.object_box.currentText() == "mug_1"


def test_step_adds_contacts_and_advances_counter(qtbot, window):
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert window.loop_panel.step_label.text().startswith("step 1")
    contacts = window.layers.actors["contacts"]
    assert contacts.mapper.dataset.n_points > 0
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert window.loop_panel.step_label.text().startswith("step 2")
    assert len(window.scene.latest.contacts) == 2
    assert "map" in window.layers.actors


def test_run_then_pause_stops_within_one_step(qtbot, window):
    window.loop_panel.run_button.setChecked(True)
    qtbot.waitUntil(lambda: window.scene.latest is not None and window.scene.latest.step >= 3,
                    timeout=60_000)
    at_pause = window.scene.latest.step
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    assert window.scene.latest.step <= at_pause + 1
    loop = window.loop_panel
    assert not loop.run_button.isChecked() and loop.step_button.isEnabled()


def test_toggling_a_layer_hides_its_actor(qtbot, window):
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    window.layers_panel.layer_boxes["contacts"].setChecked(False)
    assert not window.layers.actors["contacts"].GetVisibility()
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert not window.layers.actors["contacts"].GetVisibility()  # stays hidden across steps
    window.layers_panel.layer_boxes["contacts"].setChecked(True)
    assert window.layers.actors["contacts"].GetVisibility()
    window.layers_panel.layer_boxes["truth"].setChecked(False)
    assert not window.layers.actors["truth"].GetVisibility()


def test_broken_mesh_shows_error_and_changes_nothing(qtbot, window, errors, tmp_path):
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    session, truth = window.scene.session, window.scene.truth
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"\x00garbage" * 7)
    window.load_truth_file(bad)
    assert errors and "broken.stl" in errors[0]
    assert window.scene.truth is truth and window.scene.session is session
    window._guarded(window.scene.add_prior_file, str(bad))
    assert len(errors) == 2 and window.priors_panel.prior_list.count() == 10


def test_invalid_parameter_is_refused(window, errors):
    window.exploration_panel.parameter_boxes["lam"].setValue(0.01)
    assert window.scene.parameter("lam") == pytest.approx(0.01)
    window.scene.set_parameter("lam", 0.97)
    with pytest.raises(ValueError):
        window.scene.set_parameter("sigma_d", -1.0)
    assert window.scene.parameter("sigma_d") == 0.5


def test_unchecking_priors_restricts_the_filter(qtbot, window):
    for index in range(window.priors_panel.prior_list.count()):
        item = window.priors_panel.prior_list.item(index)
        if item.text() not in ("mug_1", "vase_1"):
            item.setCheckState(item.checkState().__class__.Unchecked)
    assert window.scene.active_library().names == ["mug_1", "vase_1"]
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert set(window.scene.latest.class_posterior) == {"mug_1", "vase_1"}


def test_closing_during_run_stops_the_worker(qtbot, window):
    window.loop_panel.run_button.setChecked(True)
    qtbot.waitUntil(lambda: window.scene.latest is not None, timeout=60_000)
    window.close()
    assert not window.running


def test_headless_screenshot_mode(qapp, tmp_path):
    spec = importlib.util.spec_from_file_location("app", REPO_ROOT / "app.py")
    app = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(app)
    out, log_file = tmp_path / "shot.png", tmp_path / "app.log"
    hook = sys.excepthook
    try:
        assert app.main(["--object", "bottle_1", "--steps", "3", "--screenshot", str(out),
                         "--log-file", str(log_file)]) == 0
    finally:
        stop_logging()
    assert out.stat().st_size > 10_000
    assert sys.excepthook is hook  # the app's hook is gone again
    assert "app started" in log_file.read_text()


def _open(qtbot, scene, settings):
    window = MainWindow(scene, settings=settings)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    return window


def test_scene_changing_controls_are_disabled_during_run(qtbot, window):
    window.loop_panel.run_button.setChecked(True)
    assert window.running and window.loop_panel.run_button.text() == "Pause"
    assert window.loop_panel.run_button.isEnabled()
    assert all(not control.isEnabled() for control in window.scene_controls())
    strategy = window.scene.strategy
    assert not window._guarded(window.scene.set_strategy, "rrt")  # refused while running
    assert window.scene.strategy == strategy
    qtbot.waitUntil(lambda: window.scene.latest is not None, timeout=60_000)
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    run_button = window.loop_panel.run_button
    assert run_button.text() == "Run" and not run_button.isChecked()
    enabled = [c for c in window.scene_controls() if c is not window.priors_panel.learn_button]
    assert all(control.isEnabled() for control in enabled)


def test_controls_show_the_command_line_settings(qtbot, known_library, settings):
    scene = Scene("vase_1", seed=4, library=PriorLibrary(list(known_library)),
                  strategy="rrt", preset="fast")
    window = _open(qtbot, scene, settings)
    assert window.exploration_panel.strategy_box.currentText() == "rrt"
    assert window.exploration_panel.preset_box.currentText() == "fast"
    truth = window.scene_panel
    assert truth.object_box.currentText() == "vase_1" and truth.seed_box.value() == 4
    for name, box in window.exploration_panel.parameter_boxes.items():
        assert box.value() == pytest.approx(scene.parameter(name), abs=1e-3)
    window.close()


def test_controls_show_a_loaded_session(qtbot, window, known_library, tmp_path):
    other = Scene("vase_1", seed=3, library=PriorLibrary(list(known_library)), strategy="rrt")
    other.set_parameter("eps", 0.8)
    other.step()
    other.step()
    path = other.save_session(tmp_path / "session.npz")
    assert window.load_session(path)
    qtbot.waitUntil(lambda: not window.loading, timeout=60_000)
    assert window.exploration_panel.strategy_box.currentText() == "rrt"
    assert window.exploration_panel.parameter_boxes["eps"].value() == pytest.approx(0.8)
    truth = window.scene_panel
    assert truth.object_box.currentText() == "vase_1" and truth.seed_box.value() == 3
    assert window.loop_panel.step_label.text().startswith("step 2")


def _legend_labels(layers):
    legend = layers.legend
    if not legend.GetVisibility():
        return []
    return [legend.GetEntryString(i) for i in range(legend.GetNumberOfEntries())]


def test_legend_lists_only_present_and_visible_layers(qtbot, window):
    from tactile_viz.gui.layers import LAYERS

    assert _legend_labels(window.layers) == [LAYERS["truth"][0]]
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    expected = [LAYERS[n][0] for n in LAYERS if window.layers.shown(n)]
    assert _legend_labels(window.layers) == expected and LAYERS["contacts"][0] in expected
    assert LAYERS["gpis"][0] not in expected  # a known object has no reconstruction yet
    window.layers_panel.layer_boxes["contacts"].setChecked(False)
    assert LAYERS["contacts"][0] not in _legend_labels(window.layers)
    window.layers_panel.layer_boxes["contacts"].setChecked(True)
    assert LAYERS["contacts"][0] in _legend_labels(window.layers)


def test_history_slider_shows_earlier_steps(qtbot, window):
    for _ in range(3):
        window.loop_panel.step_button.click()
        _wait_idle(qtbot, window)
    slider = window.loop_panel.history_slider
    assert (slider.minimum(), slider.maximum(), slider.value()) == (1, 3, 3)
    points = window.layers.actors["contacts"].mapper.dataset.n_points
    first, last = (len(window.scene.snapshots[i].contacts) for i in (0, 2))
    slider.setValue(1)
    assert window.loop_panel.step_label.text().startswith("step 1")
    assert window.layers.latest.step == 1 and window.plots._steps == [1]
    assert window.layers.actors["contacts"].mapper.dataset.n_points * last == points * first
    slider.setValue(3)
    assert window.layers.latest is window.scene.latest and window.plots._steps == [1, 2, 3]
    window.loop_panel.run_button.setChecked(True)
    assert not slider.isEnabled()
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    window.loop_panel.reset_button.click()
    assert (slider.minimum(), slider.maximum()) == (0, 0)


def test_dhd_stop_line_follows_eps(window):
    assert window.plots.eps_line.get_ydata()[0] == pytest.approx(window.scene.parameter("eps"))
    window.exploration_panel.parameter_boxes["eps"].setValue(0.8)
    assert window.scene.parameter("eps") == pytest.approx(0.8)
    assert window.plots.eps_line.get_ydata()[0] == pytest.approx(0.8)
    assert "eps 0.80" in window.dhd_label.text()


def test_recording_writes_a_frame_per_drawn_step(qtbot, window, errors, tmp_path):
    import imageio.v2 as imageio

    path = tmp_path / "steps.gif"
    assert window.start_recording(path) and window.actions["record"].isChecked()
    for _ in range(2):
        window.loop_panel.step_button.click()
        _wait_idle(qtbot, window)
    assert window.stop_recording() == path and not window.actions["record"].isChecked()
    frames = imageio.mimread(path)
    assert len(frames) == 2 and frames[0].shape[0] > 300
    assert not window.start_recording(tmp_path / "steps.avi") and errors
    assert window.recorder is None


def test_screenshot_is_the_whole_window(window, tmp_path):
    from PySide6.QtGui import QImage

    path = tmp_path / "window.png"
    assert window.save_screenshot(path)
    image = QImage(str(path))
    assert (image.width(), image.height()) == (window.width(), window.height())


def test_dropped_mesh_goes_through_the_scene(qtbot, window, errors, tmp_path):
    path = tmp_path / "dropped_vase.obj"
    load_bundled("vase_1").mesh.export(path)
    window.loop_panel.run_button.setChecked(True)
    window.plotter.files_dropped.emit([str(path)])  # refused while running
    assert window.scene.truth_model.name == "mug_1"
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    window.plotter.files_dropped.emit([str(path)])
    assert window.scene.truth_model.name == "dropped_vase" and window.scene.session is None
    assert window.scene_panel.object_box.currentText() == "dropped_vase" and not errors


def test_belief_ghosts_show_the_other_hypotheses_by_weight(qtbot, window):
    from tactile_viz.gui.layers import LAYERS

    for _ in range(3):
        window.loop_panel.step_button.click()
        _wait_idle(qtbot, window)
    box = window.layers_panel.layer_boxes["hypotheses"]
    assert not box.isChecked() and "hypotheses" not in window.layers.actors  # off at start
    hypotheses = window.scene.latest.hypotheses
    assert 1 <= len(hypotheses) <= 4
    box.setChecked(True)
    actor = window.layers.actors["hypotheses"]
    assert actor.GetVisibility() and LAYERS["hypotheses"][0] in _legend_labels(window.layers)
    models = window.scene.session.library
    sizes = [len(models[name].mesh.vertices) for name, *_ in hypotheses]
    rgba = np.asarray(actor.mapper.dataset.point_data["rgba"])
    assert len(rgba) == sum(sizes)
    starts = np.cumsum([0] + sizes[:-1])
    weights = np.array([weight for *_, weight in hypotheses])
    alphas = rgba[starts, 3].astype(float)
    assert alphas[np.argmax(weights)] == alphas.max()
    assert np.all(np.diff(alphas[np.argsort(weights)]) >= 0)  # heavier: more opaque
    box.setChecked(False)
    assert not actor.GetVisibility()


def test_fits_1280_by_720(qtbot, window):
    window.resize(1280, 720)
    qtbot.waitUntil(lambda: window.width() == 1280, timeout=5_000)
    qtbot.wait(50)
    assert window.plotter.width() >= 480  # the docks leave the viewport room
    assert window.controls_dock.geometry().bottom() <= window.height()
    assert not window.loop_panel.run_button.visibleRegion().isEmpty()  # the loop is above the fold


def test_recorded_touches_step_like_a_session_and_export(qtbot, window, errors, tmp_path):
    other = Scene("bottle_1", seed=2, library=PriorLibrary(list(window.scene.library)))
    for _ in range(4):
        other.step()
    recording = other.export(tmp_path / "recorded")[0]
    assert recording.name == "observations.csv"
    bad = tmp_path / "bad.csv"
    bad.write_text("kind,x,y,z\n")
    assert not window.open_observations(bad) and errors and "bad.csv, line 1" in errors[0]
    assert window.scene.recording is None and "truth" in window.layers.actors
    window.plotter.files_dropped.emit([str(recording)])  # a dropped CSV is replayed
    assert window.scene.recording is not None and not window.layers.shown("truth")
    window.actions["finish"].trigger()
    _wait_idle(qtbot, window)
    latest = window.scene.latest
    assert latest.step == 4 and latest.pose_error is None and window.scene.session.terminated
    np.testing.assert_array_equal(latest.contacts, other.latest.contacts)
    assert "pose error -" in window.loop_panel.status_label.text()
    assert window.export(tmp_path / "again")
    assert (tmp_path / "again" / "estimate.json").exists() and len(errors) == 1
    window.scene_panel.pose_requested.emit(5)  # a new pose goes back to the simulator
    assert window.scene.recording is None and window.layers.shown("truth")
