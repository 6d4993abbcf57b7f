"""The window in a robot's scene (app.py --table, --tip-radius): the table under the object
and the fingertip at the latest contact, drawn as layers with their check boxes."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings

from tactile_viz.app.scene import Scene
from tactile_viz.engine import PriorLibrary, load_bundled
from tactile_viz.engine.scene import FREE
from tactile_viz.gui.layers import LAYERS, TABLE_DROP, TABLE_SIZE
from tactile_viz.gui.main_window import MainWindow

pytestmark = pytest.mark.gui
REPO_ROOT = Path(__file__).resolve().parents[2]
HEIGHT, RADIUS = -2.0, 0.3


@pytest.fixture(scope="module")
def models():
    # Loaded once: a model keeps its stable poses on the table once found.
    return {name: load_bundled(name) for name in ["mug_1", "vase_1", "bottle_1"]}


@pytest.fixture(scope="module")
def launcher():
    spec = importlib.util.spec_from_file_location("app_launcher", REPO_ROOT / "app.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _window(qtbot, tmp_path, models, robot_scene):
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat)
    scene = Scene(truth_model=models["mug_1"], seed=0, robot_scene=robot_scene,
                  library=PriorLibrary(list(models.values())))
    window = MainWindow(scene, settings=settings, engine="thread")
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    return window


def _step(qtbot, window):
    window.loop_panel.step_button.click()
    qtbot.waitUntil(lambda: not window.running and window.scene.latest is not None,
                    timeout=30_000)


def _bounds(layers, name):
    return np.asarray(layers.actors[name].GetBounds()).reshape(3, 2)


def _legend(layers):
    return [label for label, *_ in layers.legend_entries()]


def test_a_table_and_a_tip_radius_draw_the_table_and_the_tip(qtbot, tmp_path, models,
                                                              launcher):
    args = launcher.parse_args(["--log-file", "", "--table-height", str(HEIGHT),
                                "--tip-radius", str(RADIUS)])
    window = _window(qtbot, tmp_path, models, launcher.scene_from_args(args))
    layers, truth = window.layers, window.scene.truth
    try:
        # The table is there from the start, under the object; the tip waits for a contact.
        assert layers.shown("table") and not layers.shown("tip")
        table = _bounds(layers, "table")
        size = TABLE_SIZE * truth.model.length
        np.testing.assert_allclose(table[2], HEIGHT - TABLE_DROP * size, atol=1e-5 * size)
        np.testing.assert_allclose(table[:2, 1] - table[:2, 0], [size, size], rtol=1e-6)
        world = truth.to_world(truth.model.mesh.vertices)
        middle = 0.5 * (world.min(axis=0) + world.max(axis=0))
        np.testing.assert_allclose(table[:2].mean(axis=1), middle[:2], atol=1e-5 * size)
        # The camera frames the object, not the table.
        np.testing.assert_allclose(layers.bounds(), layers.actors["truth"].GetBounds())

        _step(qtbot, window)
        latest = window.scene.latest
        assert len(latest.contacts) and layers.shown("tip") and layers.shown("table")
        tip = _bounds(layers, "tip")
        centre = latest.contacts[-1] + RADIUS * latest.normals[-1]
        np.testing.assert_allclose(tip.mean(axis=1), centre, atol=1e-3 * RADIUS)
        np.testing.assert_allclose(tip[:, 1] - tip[:, 0], 2 * RADIUS, rtol=0.02)
        assert LAYERS["table"][0] in _legend(layers) and LAYERS["tip"][0] in _legend(layers)

        # Each has its check box.
        box = window.layers_panel.layer_boxes["table"]
        box.setChecked(False)
        assert not layers.actors["table"].GetVisibility()
        assert LAYERS["table"][0] not in _legend(layers)
        box.setChecked(True)
        assert layers.actors["table"].GetVisibility()
        window.layers_panel.layer_boxes["tip"].setChecked(False)
        assert not layers.actors["tip"].GetVisibility()
        window.layers_panel.layer_boxes["tip"].setChecked(True)
        assert layers.actors["tip"].GetVisibility()

        # A reset keeps the table (the scene's) and drops the tip (a step's).
        window.actions["reset"].trigger()
        assert layers.shown("table") and not layers.actors["tip"].GetVisibility()
        # Free space: neither.
        window.scene.set_robot_scene(FREE)
        assert not layers.shown("table") and not layers.actors["table"].GetVisibility()
    finally:
        window.wait_for_worker()


def test_free_space_draws_neither(qtbot, tmp_path, models):
    window = _window(qtbot, tmp_path, models, None)
    try:
        _step(qtbot, window)
        layers = window.layers
        assert layers.shown("contacts")
        assert not layers.shown("table") and not layers.shown("tip")
        assert "table" not in layers.actors and "tip" not in layers.actors
        assert LAYERS["table"][0] not in _legend(layers)
    finally:
        window.wait_for_worker()
