"""Smoke test of the minimal viewer window: opens, renders, closes cleanly."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from tactile_viz.gui.viewer import ViewerWindow

pytestmark = pytest.mark.gui

REPO_ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def mesh() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=3)


def _non_background_fraction(img: np.ndarray, window: ViewerWindow) -> float:
    bg = np.asarray(window.plotter.background_color.int_rgb, dtype=int)
    diff = np.abs(img[..., :3].astype(int) - bg).sum(axis=-1)
    return float((diff > 30).mean())


def test_viewer_opens_renders_and_closes(qtbot, mesh):
    window = ViewerWindow(mesh, name="icosphere")
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)

    assert window.statusBar().currentMessage().startswith("icosphere")
    assert "icosphere" in window.windowTitle()

    actors = window.plotter.renderer.actors
    assert list(actors) == ["object"]
    dataset = actors["object"].mapper.dataset
    assert dataset.n_cells == len(mesh.faces)
    assert dataset.n_points == len(mesh.vertices)

    img = window.screenshot()
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    assert tuple(window.plotter.background_color.int_rgb) == (255, 255, 255)
    # The sphere fills a good part of the viewport, and is not all one colour.
    frac = _non_background_fraction(img, window)
    assert 0.05 < frac < 0.95, frac
    assert img[..., :3].reshape(-1, 3).std(axis=0).max() > 5

    window.close()
    qtbot.waitUntil(lambda: not window.isVisible())
    assert window.plotter._closed
    assert not window.plotter.render_timer.isActive()


def test_quit_action_closes_window(qtbot, mesh):
    window = ViewerWindow(mesh, name="icosphere")
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    window.quit_action.trigger()
    qtbot.waitUntil(lambda: not window.isVisible())
    assert window.plotter._closed


def test_app_screenshot_of_bundled_object(qapp, tmp_path):
    pytest.importorskip("tactile_viz.engine.objects")
    spec = importlib.util.spec_from_file_location("app", REPO_ROOT / "app.py")
    app = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(app)

    out = tmp_path / "shot.png"
    assert app.main(["--screenshot", str(out)]) == 0
    assert out.stat().st_size > 1000
