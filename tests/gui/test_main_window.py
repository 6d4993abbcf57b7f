"""The main window under Xvfb: stepping, running, pausing, layers, errors, closing."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QByteArray, QMimeData, QPointF, QSettings, Qt, QUrl
from PySide6.QtGui import QDragEnterEvent, QDropEvent
from PySide6.QtWidgets import QApplication, QFileDialog, QMessageBox, QPushButton

from tactile_viz.app.scene import Scene
from tactile_viz.cli import stop_logging
from tactile_viz.engine import PriorLibrary, load_bundled
from tactile_viz.engine.session import session_preset
from tactile_viz.gui.main_window import IDLE_MULTISAMPLES, RUNNING_MULTISAMPLES, MainWindow

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
    """At most one step ends after the pause: the one in progress. The step shown is not the
    measure: the engine runs ahead of the drawing (1 run in 8 ended two steps past the one
    shown at the pause)."""
    window.loop_panel.run_button.setChecked(True)
    qtbot.waitUntil(lambda: window.scene.latest is not None and window.scene.latest.step >= 3,
                    timeout=60_000)
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    runner = window.runner
    assert runner.stop_requested_at is not None and len(runner.step_ends) >= 3
    assert sum(end > runner.stop_requested_at for end in runner.step_ends) <= 1
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
    window.guarded(window.scene.add_prior_file, str(bad))
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
    assert not window.guarded(window.scene.set_strategy, "rrt")  # refused while running
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
    message = window.statusBar().currentMessage()
    assert "loaded" in message and "replaced" not in message  # the same priors


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


def _with_every_layer(snapshot):
    """``snapshot`` with a GPIS surface (a sphere at its first contact, as a novel step has),
    a non-contact and a sensor path, so that every layer has something to show."""
    from dataclasses import replace

    import pyvista as pv

    contact = np.asarray(snapshot.contacts[0])
    sphere = pv.Sphere(radius=1.0, center=tuple(contact))
    points = np.asarray(sphere.points)
    return replace(snapshot, gpis_vertices=points, gpis_faces=sphere.faces.reshape(-1, 4)[:, 1:],
                   gpis_variance=1.0 + points[:, 2] - points[:, 2].min(),
                   noncontacts=(contact + 2.0)[None], paths=[np.stack([contact + 3.0, contact])])


def test_legend_is_readable_at_1280_by_720(qtbot, window, settled_screenshot):
    from matplotlib import colormaps

    from tactile_viz.gui import layers as layers_module
    from tactile_viz.gui.layers import LAYERS, LEGEND_BACKGROUND, contrast_ratio

    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    window.layers_panel.layer_boxes["hypotheses"].setChecked(True)
    window.layers.show_snapshot(_with_every_layer(window.scene.latest))
    window.resize(1280, 720)  # the legend follows the viewport's new size
    qtbot.waitUntil(lambda: window.width() == 1280, timeout=5_000)
    qtbot.wait(50)
    entries = window.layers.legend_entries()
    # Every layer but the robot scene's (free space: no table, a point tip).
    names = [name for name in LAYERS if name not in ("table", "tip")]
    assert [label for label, *_ in entries] == [LAYERS[name][0] for name in names]
    for (label, text, fill), name in zip(entries, names):
        assert contrast_ratio(text, LEGEND_BACKGROUND) >= 4.5, label  # WCAG AA for text
        if name == "gpis":  # a viridis ramp, as the surface is drawn; never white
            ramp = colormaps["viridis"]([0.0, 1.0])[:, :3]
            np.testing.assert_allclose(fill[[0, -1]], ramp, atol=1 / 255)
            assert len(fill) > 2 and all(contrast_ratio(c, (1, 1, 1)) > 1.2 for c in fill)
        else:  # the layer's own colour
            np.testing.assert_allclose(fill, [pv_color(LAYERS[name][1])], atol=1 / 255)
    outline = layers_module.LEGEND_OUTLINE
    assert contrast_ratio(outline, LEGEND_BACKGROUND) >= 3  # light markers stay visible

    # As drawn: every row of the box has dark text on the light box, and is tall enough.
    image = settled_screenshot(window.plotter).astype(float) / 255
    height, width = image.shape[:2]
    legend = window.layers.legend
    left, bottom = legend.GetPosition()
    box_w, box_h = legend.GetPosition2()
    top, rows = round((1 - bottom - box_h) * height), len(entries)
    row_pixels = box_h * height / rows
    assert row_pixels >= 16  # about a 12 px font; the box is not a few pixels high
    x0, x1 = round(left * width), round((left + box_w) * width)
    for row in range(rows):
        strip = image[round(top + row * row_pixels) + 2:round(top + (row + 1) * row_pixels) - 2,
                      x0 + (x1 - x0) // 6:x1]  # the labels' part of the row
        luminance = strip @ [0.2126, 0.7152, 0.0722]
        darkest = strip.reshape(-1, 3)[np.argmin(luminance)]
        background = strip.reshape(-1, 3)[np.argmax(luminance)]
        assert contrast_ratio(darkest, background) >= 4.5, entries[row][0]
    _colour_bar_is_boxed(window.layers.colour_bar, image)


def _colour_bar_is_boxed(colour_bar, image):
    """Inside the colour bar's box, as drawn, nothing in colour but the bar's ramp: its title
    and labels stand on the box's white, never on a marker or surface behind them."""
    height, width = image.shape[:2]
    x0, y0, x1, y1 = (round(value) for value in colour_bar.box_pixels(width, height))
    inside = image[height - y1 + 2:height - y0 - 2, x0 + 2:x1 - 2]
    coloured = inside.max(axis=-1) - inside.min(axis=-1) > 0.15
    bar = colour_bar.bar
    ramp_end = (bar.GetPosition()[0] + bar.GetBarRatio() * bar.GetPosition2()[0]) * width
    assert coloured.any() and not coloured[:, round(ramp_end) - x0:].any()


def test_the_status_bar_is_not_cut_at_1280_by_720(qtbot, known_library, settings):
    from types import SimpleNamespace

    scene = Scene("mug_1", library=PriorLibrary(list(known_library)),
                  sensor_noise=(0.02, 2.0), sensor_outliers=0.05)
    window = MainWindow(scene, settings=settings, engine="thread")
    qtbot.addWidget(window)
    window.resize(1280, 720)
    window.show()
    qtbot.waitUntil(lambda: window.width() == 1280, timeout=5_000)
    bar = window.statusBar()
    assert bar.noise_label.text() == "noise 0.02 scene units, 2.0\u00b0, 5% outliers"
    assert bar.preset_label.text() == "preset recommended"
    longest = max(scene.library.names, key=len)  # as long a line as these priors give
    known = dict(step=400, map_class=longest, novel=False, decided=True,
                 decision_confidence=0.9993, pose_error=0.123, recon_error=None, dhd=12.34,
                 timings={"filter": 12.34})
    for snapshot in (known, dict(known, novel=True, recon_error=0.456)):
        snapshot = SimpleNamespace(**snapshot)
        bar.show_snapshot(snapshot, scene)
        qtbot.wait(20)
        for label in bar.labels():
            assert label.fontMetrics().horizontalAdvance(label.text()) <= (
                label.contentsRect().width()), label.text()
        assert bar.summary_label.text() == bar.summary_label.full_text  # not elided
        progress = bar.progress
        assert progress.fontMetrics().horizontalAdvance(progress.text()) <= (
            progress.contentsRect().width())
    assert "last step 12.34 s" in bar.time_label.text() and "DHD 12.34" in bar.dhd_label.text()


def pv_color(name):
    import pyvista as pv

    return pv.Color(name).float_rgb


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
    # On the paper's objects (6 long) a size unit is a scene unit and the threshold is 0.6.
    assert window.plots.threshold_line.get_ydata()[0] == pytest.approx(0.6)
    assert window.plots.error_axes.get_ylabel() == "error [scene units]"


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


def _drop(viewport, *paths, shift=False):
    """Drag ``paths`` onto the viewport and drop them there, as Qt's drag and drop does (a
    QDragEnterEvent, then a QDropEvent, Shift held or not); returns whether each was accepted."""
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(path)) for path in paths])
    modifiers = Qt.ShiftModifier if shift else Qt.NoModifier
    middle = QPointF(viewport.width() / 2, viewport.height() / 2)
    enter = QDragEnterEvent(middle, Qt.CopyAction, mime, Qt.LeftButton, modifiers)
    QApplication.sendEvent(viewport, enter)
    drop = QDropEvent(middle, Qt.CopyAction, mime, Qt.LeftButton, modifiers)
    QApplication.sendEvent(viewport, drop)
    return enter.isAccepted(), drop.isAccepted()


@pytest.fixture
def vase_file(tmp_path):
    path = tmp_path / "dropped_vase.obj"
    load_bundled("vase_1").mesh.export(path)
    return path


def test_dropped_mesh_becomes_the_truth_through_the_scene(qtbot, window, errors, vase_file):
    window.loop_panel.run_button.setChecked(True)
    assert _drop(window.plotter, vase_file) == (False, False)  # refused while running
    assert "Pause first" in window.statusBar().currentMessage()
    assert window.scene.truth_model.name == "mug_1"
    window.loop_panel.run_button.setChecked(False)
    _wait_idle(qtbot, window)
    assert _drop(window.plotter, vase_file) == (True, True)
    assert window.scene.truth_model.name == "dropped_vase" and window.scene.session is None
    assert window.scene_panel.object_box.currentText() == "dropped_vase" and not errors
    assert window.priors_panel.prior_list.count() == 10  # not a prior
    assert "ground truth" in window.statusBar().currentMessage()


def test_shift_drop_adds_a_mesh_as_a_prior(qtbot, window, errors, vase_file, tmp_path):
    assert _drop(window.plotter, vase_file, shift=True) == (True, True)
    assert window.scene.library.names[-1] == "dropped_vase" and window.scene.enabled[
        "dropped_vase"]
    assert window.priors_panel.prior_list.count() == 11
    assert window.priors_panel.prior_list.item(10).checkState() == Qt.Checked
    assert window.scene.truth_model.name == "mug_1" and not errors
    assert "added the prior 'dropped_vase'" in window.statusBar().currentMessage()
    _drop(window.plotter, vase_file, shift=True)  # checked like Load mesh: the name is taken
    assert errors and "dropped_vase" in errors[0] and len(window.scene.library) == 11
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"\x00garbage" * 7)
    _drop(window.plotter, bad, shift=True)
    assert len(errors) == 2 and "broken.stl" in errors[1] and len(window.scene.library) == 11
    # (Refused during Run like any drop: test_dropped_mesh_becomes_the_truth_through_the_scene.
    # A run here would first build the new prior's tables, which takes longer than the
    # thread check of the teardown allows on a machine with a cold cache.)


def test_dropped_csv_replays_the_recorded_touches(window, errors, tmp_path):
    path = tmp_path / "touches.csv"
    path.write_text("kind,x,y,z,nx,ny,nz\ncontact,0.5,0.0,1.0,0.0,0.0,1.0\n"
                    "noncontact,2.0,0.4,0.1,,,\n")
    assert _drop(window.plotter, path) == (True, True)
    assert window.scene.recording is not None and window.scene.recording[0] == str(path)
    assert not window.layers.shown("truth") and not errors
    assert "replaying" in window.statusBar().currentMessage()


def test_other_dropped_files_are_refused(window, errors, tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("not a mesh")
    missing = tmp_path / "missing.obj"
    session, truth = window.scene.session, window.scene.truth
    for path in (text, missing, tmp_path):
        for shift in (False, True):
            assert _drop(window.plotter, path, shift=shift) == (False, False)
    assert "only mesh files" in window.statusBar().currentMessage()
    assert window.scene.truth is truth and window.scene.session is session
    assert window.scene.recording is None and len(window.scene.library) == 10 and not errors


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
    assert _drop(window.plotter, recording) == (True, True)  # a dropped CSV is replayed
    assert window.scene.recording is not None and not window.layers.shown("truth")
    window.actions["finish"].trigger()
    _wait_idle(qtbot, window)
    latest = window.scene.latest
    assert latest.step == 4 and latest.pose_error is None and window.scene.session.terminated
    np.testing.assert_array_equal(latest.contacts, other.latest.contacts)
    assert "pose error -" in window.loop_panel.status_label.text().replace("\u00a0", " ")
    assert window.export(tmp_path / "again")
    assert (tmp_path / "again" / "estimate.json").exists() and len(errors) == 1
    window.scene_panel.pose_requested.emit(5)  # a new pose goes back to the simulator
    assert window.scene.recording is None and window.layers.shown("truth")


# ---------------------------------------------------------------------- toolbar, keys, status
LOOP_AND_VIEW_KEYS = {"step": "F6", "run": "F5", "finish": "Shift+F5", "reset": "Ctrl+R",
                      "camera": "Home", "iso": "Ctrl+0", "xy": "Ctrl+1", "xz": "Ctrl+2",
                      "yz": "Ctrl+3", "screenshot": "F12"}


def _cap_steps(scene, steps):
    """A preset like the paper's whose sessions stop after ``steps`` steps."""
    scene.presets["tiny"] = session_preset("recommended", max_steps_known=steps,
                                           max_steps_novel=steps)
    scene.set_preset("tiny")


def _activate(qtbot, window):
    """Make the window the active one (window shortcuts fire only in the active window)."""
    window.activateWindow()
    qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=5_000)


def _view_direction(window):
    camera = window.plotter.camera
    direction = np.subtract(camera.position, camera.focal_point)
    return direction / np.linalg.norm(direction)


def test_toolbar_holds_the_loop_view_and_screenshot_actions(window):
    toolbar = window.toolbar
    assert toolbar.isVisible()
    in_toolbar = [action for action in toolbar.actions() if not action.isSeparator()]
    assert [action.text() for action in in_toolbar[:4]] == ["Step", "Run", "Run to termination",
                                                             "Reset"]
    for name, keys in LOOP_AND_VIEW_KEYS.items():
        action = window.actions[name]
        assert action in in_toolbar, name
        assert action.shortcut().toString() == keys and keys in action.toolTip()
    assert window.actions["record"] in in_toolbar and window.actions["run"].isCheckable()
    texts = [action.text() for action in in_toolbar]
    assert {"Reset camera", "Isometric view", "Top view", "Front view", "Side view",
            "Save screenshot..."} <= set(texts)


def test_shortcuts_drive_the_loop_the_views_and_screenshots(qtbot, window, monkeypatch,
                                                            tmp_path):
    scene = window.scene
    _cap_steps(scene, 3)
    _activate(qtbot, window)
    qtbot.keyClick(window, Qt.Key_F6)  # Step
    _wait_idle(qtbot, window)
    assert scene.latest.step == 1
    qtbot.keyClick(window, Qt.Key_F5)  # Run: the toolbar's Run reads Pause
    assert window.running and window.actions["run"].text() == "Pause"
    assert window.actions["run"].isChecked() and window.loop_panel.run_button.isChecked()
    qtbot.keyClick(window, Qt.Key_F5)  # Pause, after the step in progress
    _wait_idle(qtbot, window)
    assert window.actions["run"].text() == "Run" and not window.actions["run"].isChecked()
    qtbot.keyClick(window, Qt.Key_R, Qt.ControlModifier)  # Reset
    assert scene.latest is None and window.loop_panel.step_label.text() == "step 0"
    qtbot.keyClick(window, Qt.Key_F5, Qt.ShiftModifier)  # Run to termination
    _wait_idle(qtbot, window)
    assert scene.latest.step == 3 and scene.session.terminated

    for key, axis in ((Qt.Key_1, 2), (Qt.Key_2, 1), (Qt.Key_3, 0)):  # top, front, side
        qtbot.keyClick(window, key, Qt.ControlModifier)
        assert abs(_view_direction(window)[axis]) == pytest.approx(1.0, abs=1e-6)
    qtbot.keyClick(window, Qt.Key_0, Qt.ControlModifier)  # isometric
    np.testing.assert_allclose(np.abs(_view_direction(window)), np.full(3, 3 ** -0.5), atol=1e-6)
    window.plotter.camera.zoom(3.0)
    window.plotter.camera.focal_point = (50.0, 50.0, 50.0)
    qtbot.keyClick(window, Qt.Key_Home)  # camera reset: back on the ground truth
    bounds = np.reshape(window.layers.actors["truth"].GetBounds(), (3, 2))
    np.testing.assert_allclose(window.plotter.camera.focal_point, bounds.mean(axis=1), atol=1e-6)

    path = tmp_path / "shot.png"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args: (str(path), ""))
    qtbot.keyClick(window, Qt.Key_F12)  # screenshot of the whole window
    assert path.stat().st_size > 10_000
    assert window.statusBar().currentMessage() == f"saved a screenshot to {path}"


def test_help_keys_lists_the_shortcuts(qtbot, window, monkeypatch):
    shown = []
    monkeypatch.setattr(QMessageBox, "information",
                        lambda parent, title, text, *a, **k: shown.append((title, text)))
    help_menu = next(action.menu() for action in window.menuBar().actions()
                     if action.text() == "&Help")
    assert window.actions["keys"] in help_menu.actions()
    _activate(qtbot, window)
    qtbot.keyClick(window, Qt.Key_F1)
    (title, text), = shown
    assert title == "Keys"
    for name, keys in LOOP_AND_VIEW_KEYS.items():
        action = window.actions[name]
        assert f"<b>{keys}</b></td><td>{action.text()}</td>" in text, name
    for name in ("record", "open_observations", "export", "load_session"):
        assert f"<b>{window.actions[name].shortcut().toString()}</b>" in text
    assert "Shift" in text and ".csv" in text  # drops: Shift adds a mesh as a prior


def test_progress_shows_the_step_of_the_cap_and_dhd_against_eps(qtbot, window):
    scene = window.scene
    _cap_steps(scene, 5)
    scene.set_parameter("eps", 0.8)
    assert window.progress.text() == "step 0 of 5" and window.dhd_label.text() == (
        "DHD - / eps 0.80")
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert (window.progress.value(), window.progress.maximum()) == (1, 5)
    assert window.progress.text() == "step 1 of 5"
    assert window.dhd_label.text() == f"DHD {scene.latest.dhd:.2f} / eps 0.80"
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    assert window.progress.text() == "step 2 of 5"
    assert window.dhd_label.text() == f"DHD {scene.latest.dhd:.2f} / eps 0.80"
    window.loop_panel.reset_button.click()
    assert window.progress.text() == "step 0 of 5" and window.dhd_label.text().startswith("DHD -")


# ---------------------------------------------------------------------- sessions and saves
def _saved_session(tmp_path, library, steps):
    other = Scene("vase_1", seed=3, library=library)
    for _ in range(steps):
        other.step()
    return other.save_session(tmp_path / "session.npz")


def test_cancelling_load_session_changes_nothing(qtbot, window, known_library, tmp_path):
    path = _saved_session(tmp_path, PriorLibrary(list(known_library)), 3)
    scene = window.scene
    before = (scene.session, scene.truth, scene.library, scene.generation)
    assert window.load_session(path)
    assert window.loading and all(not control.isEnabled() for control in window.scene_controls())
    loader = window.loader
    dialog = loader.dialog
    assert dialog.isVisible() and dialog.windowTitle() == "Load session"
    dialog.findChild(QPushButton).click()  # Cancel
    qtbot.waitUntil(lambda: not window.loading, timeout=60_000)
    assert window.statusBar().currentMessage() == (
        "loading the session was cancelled; nothing changed")
    assert (scene.session, scene.truth, scene.library, scene.generation) == before
    assert window.scene_panel.object_box.currentText() == "mug_1"
    assert loader.dialog is None  # closed and deleted
    enabled = [c for c in window.scene_controls() if c is not window.priors_panel.learn_button]
    assert all(control.isEnabled() for control in enabled)


def test_loading_a_session_says_it_replaced_the_priors(qtbot, window, known_library, tmp_path):
    library = PriorLibrary([known_library["mug_1"], known_library["vase_1"]])
    path = _saved_session(tmp_path, library, 1)
    assert window.load_session(path)
    qtbot.waitUntil(lambda: not window.loading, timeout=60_000)
    message = window.statusBar().currentMessage()
    assert message.startswith(f"loaded {path} (1 steps)")
    assert message.endswith("; the priors were replaced by the session's 2: mug_1, vase_1")
    assert window.priors_panel.prior_list.count() == 2


class _Dialogs:
    """QFileDialog's static functions answering with preset paths, recording where each
    dialog started."""

    def __init__(self, monkeypatch):
        self.answer, self.started = "", []
        for name in ("getSaveFileName", "getOpenFileName"):
            monkeypatch.setattr(QFileDialog, name, self._file)
        monkeypatch.setattr(QFileDialog, "getExistingDirectory", self._folder)

    def _file(self, parent, caption, start, filter_=""):
        self.started.append(start)
        return str(self.answer), ""

    def _folder(self, parent, caption, start):
        self.started.append(start)
        return str(self.answer)


def test_saves_confirm_in_the_status_bar(qtbot, window, settings, monkeypatch, tmp_path):
    dialogs = _Dialogs(monkeypatch)
    status = window.statusBar()
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    (tmp_path / "sessions").mkdir()
    dialogs.answer = tmp_path / "sessions" / "run.npz"
    window.actions["save_session"].trigger()
    assert dialogs.answer.exists()
    assert status.currentMessage() == f"saved the session (1 steps) to {dialogs.answer}"
    dialogs.answer = tmp_path / "library"
    window.actions["save_library"].trigger()
    assert status.currentMessage() == f"saved 10 priors to {dialogs.answer}"
    dialogs.answer = tmp_path / "export"
    window.actions["export"].trigger()
    assert status.currentMessage() == f"exported step 1 to {dialogs.answer}"
    assert (dialogs.answer / "estimate.json").exists()
    dialogs.answer = tmp_path / "window.png"
    window.actions["screenshot"].trigger()
    assert status.currentMessage() == f"saved a screenshot to {dialogs.answer}"
    # Each dialog starts in the folder last used for its kind of file.
    assert settings.value("folders/sessions") == str(tmp_path / "sessions")
    dialogs.answer = ""  # cancelled: nothing saved, nothing said
    window.actions["save_session"].trigger()
    assert dialogs.started[-1] == str(tmp_path / "sessions" / "session.npz")
    assert status.currentMessage() == f"saved a screenshot to {tmp_path / 'window.png'}"


def test_window_geometry_docks_and_folders_are_restored(qtbot, known_library, settings,
                                                        monkeypatch, tmp_path):
    dialogs = _Dialogs(monkeypatch)
    first = _open(qtbot, Scene("mug_1", library=PriorLibrary(list(known_library))), settings)
    first.resize(760, 560)  # within pytest-xvfb's 800x600 screen (Qt keeps windows on it)
    qtbot.waitUntil(lambda: first.width() == 760, timeout=5_000)
    first.addDockWidget(Qt.RightDockWidgetArea, first.controls_dock)
    first.plots_dock.toggleViewAction().trigger()  # View > Plots: hidden
    assert not first.plots_dock.isVisible()
    (tmp_path / "recorded").mkdir()
    dialogs.answer = tmp_path / "recorded" / "none.csv"  # a bad file: an error, but remembered
    monkeypatch.setattr(QMessageBox, "critical", lambda *args, **kwargs: None)
    first.actions["open_observations"].trigger()
    first.close()
    assert isinstance(settings.value("window/geometry"), QByteArray)

    second = _open(qtbot, Scene("mug_1", library=PriorLibrary(list(known_library))), settings)
    assert (second.width(), second.height()) == (760, 560)  # not the default 1500x900
    assert second.dockWidgetArea(second.controls_dock) == Qt.RightDockWidgetArea
    assert not second.plots_dock.isVisible() and second.controls_dock.isVisible()
    dialogs.answer = ""
    second.actions["open_observations"].trigger()
    assert dialogs.started[-1] == str(tmp_path / "recorded")
    second.close()


def test_one_render_per_drawn_step(qtbot, window, monkeypatch):
    # Drawing a step asks for exactly one render, in the next paint, and does not render
    # beside it (every add_mesh used to render: about 7 renders a step).
    renders, asked = [], []
    ren_win = window.plotter.ren_win
    tag = ren_win.AddObserver("StartEvent", lambda *args: renders.append(1))
    schedule = window.plotter.schedule_render
    monkeypatch.setattr(window.plotter, "schedule_render",
                        lambda: (asked.append(len(renders)), schedule()))
    drawing = []
    show_step = window._show_step
    monkeypatch.setattr(window, "_show_step", lambda snapshot: (
        drawing.append(len(renders)), show_step(snapshot), drawing.append(len(renders))))
    try:
        _cap_steps(window.scene, 4)
        _wait_idle(qtbot, window)
        asked.clear()
        drawn = window.runner.drawn
        window.loop_panel.step_button.click()
        _wait_idle(qtbot, window)
        qtbot.waitUntil(lambda: window.runner.drawn - drawn == 1, timeout=10_000)
        assert len(asked) == 1
        assert drawing[-1] - drawing[-2] <= 1  # at most the one it asked for
        asked.clear()
        drawn = window.runner.drawn
        window.actions["finish"].trigger()  # three more steps, some may be coalesced
        _wait_idle(qtbot, window)
        assert window.scene.latest.step == 4
        assert len(asked) == window.runner.drawn - drawn
        # A draw may run the render it asked for when the plots' flush lets the event loop
        # paint, never more than that one.
        assert all(after - before <= 1 for before, after in zip(drawing[::2], drawing[1::2]))
    finally:
        ren_win.RemoveObserver(tag)


def test_run_draws_without_multisampling(qtbot, window):
    # Multisampling doubles a software render: a run draws without it, idle views have it.
    samples = window.plotter.render_window.GetMultiSamples
    assert samples() == IDLE_MULTISAMPLES > RUNNING_MULTISAMPLES
    _cap_steps(window.scene, 3)
    window.actions["finish"].trigger()
    assert window.running and samples() == RUNNING_MULTISAMPLES
    _wait_idle(qtbot, window)
    assert window.scene.latest.step == 3 and samples() == IDLE_MULTISAMPLES


def test_run_draws_with_one_headlight(qtbot, window):
    # Each light shades every fragment of a software render again: a run is lit by one
    # headlight, an idle view by pyvista's light kit (the same lights as before the run).
    renderer = window.plotter.renderer
    kit = list(renderer.lights)
    assert len(kit) > 1
    _cap_steps(window.scene, 3)
    window.actions["finish"].trigger()
    assert window.running
    lights = list(renderer.lights)
    assert len(lights) == 1 and lights[0].is_headlight
    _wait_idle(qtbot, window)
    assert window.scene.latest.step == 3
    assert [id(light) for light in renderer.lights] == [id(light) for light in kit]


def test_steps_run_in_the_engine_process_and_come_back(qtbot, window, known_library,
                                                       settings):
    # The default window steps in the app's engine process: the session the scene holds
    # gets every snapshot and, at the end, the process's state, so that a window stepping
    # in a thread continues it exactly.
    assert window.engine is not None
    _cap_steps(window.scene, 5)
    window.actions["finish"].trigger()
    _wait_idle(qtbot, window)
    session = window.scene.session
    assert session.step_count == 5 and window.engine.holds(session)
    assert window.loop_panel.step_label.text().startswith("step 5")
    threaded = MainWindow(Scene("mug_1", seed=0, library=PriorLibrary(list(known_library))),
                          settings=settings, engine="thread")
    qtbot.addWidget(threaded)
    try:
        assert threaded.engine is None
        _cap_steps(threaded.scene, 5)
        threaded.actions["finish"].trigger()
        qtbot.waitUntil(lambda: not threaded.running, timeout=60_000)
        here = threaded.scene.session
        for a, b in zip(session.snapshots, here.snapshots):
            assert a.map_class == b.map_class and np.array_equal(a.contacts, b.contacts)
        # The state that came back is the thread's session's.
        assert session.rng.bit_generator.state == here.rng.bit_generator.state
        assert (session.simulator.rng.bit_generator.state
                == here.simulator.rng.bit_generator.state)
        assert np.array_equal(session.state.free_space, here.state.free_space)
        assert np.array_equal(session.filter.contact_positions, here.filter.contact_positions)
    finally:
        threaded.wait_for_worker()
        threaded.close()


def test_a_step_failing_in_the_engine_process_is_shown_and_loses_nothing(
        qtbot, window, errors, known_library):
    from tactile_viz.engine.io.observation_file import RecordedStep
    from tactile_viz.engine.session import Session, make_truth

    source = Session.simulated(make_truth(load_bundled("mug_1"), rng=0), known_library, seed=0)
    source.run(max_steps=1)
    good = source.recorded_steps()[0]
    broken = RecordedStep(good.observations, np.array([[np.nan, 0.0, 0.0]]))
    scene = window.scene
    scene.recording, scene.truth = ("a recording", [good, broken, good]), None
    scene.reset()
    window.actions["finish"].trigger()
    _wait_idle(qtbot, window)
    assert len(errors) == 1 and "finite" in errors[0]
    session = scene.session
    assert session.step_count == 1 and window.engine.holds(session)
    assert window.loop_panel.step_label.text().startswith("step 1")


def test_a_run_from_a_new_session_is_blitted_from_its_first_step(qtbot, window):
    # A new session's plots already have the run's axes (the step axis to the cap) and the
    # priors' bars, so no full draw (0.1-0.35 s of the GUI thread) falls inside the run.
    _cap_steps(window.scene, 4)
    plots = window.plots
    assert plots.run_steps == 4 and plots._names == window.scene.active_library().names
    qtbot.waitUntil(lambda: plots._background is not None
                    and plots._layout_key == plots._current_layout(), timeout=10_000)
    full_draws = len(plots.draw_log) - plots.blits
    during = []
    window.runner.finished.connect(lambda: during.append(len(plots.draw_log) - plots.blits))
    window.actions["finish"].trigger()
    _wait_idle(qtbot, window)
    qtbot.waitUntil(lambda: bool(during), timeout=10_000)
    assert during[0] == full_draws and plots.blits > 0
    qtbot.waitUntil(lambda: plots.run_steps is None)  # after the run: fitted to the data


def test_translucent_surfaces_show_only_their_near_side(qtbot, window):
    # Culling the far side halves a software render of the translucent truth and MAP shape.
    window.loop_panel.step_button.click()
    _wait_idle(qtbot, window)
    actors = window.layers.actors
    assert actors["truth"].prop.culling == "back" and actors["map"].prop.culling == "back"
    assert actors["contacts"].prop.culling == "none"
