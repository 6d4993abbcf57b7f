"""The window draws a scene alike at any size: the paper's 6 units, metres, millimetres."""

import numpy as np
import pytest
from PySide6.QtCore import QSettings
from PySide6.QtTest import QTest

from tactile_viz.app.scene import Scene
from tactile_viz.engine import PriorLibrary, load_bundled
from tactile_viz.engine.shape.objects import ObjectModel
from tactile_viz.gui.main_window import MainWindow

pytestmark = pytest.mark.gui
# The bundled mug (6 units long) as a 0.12 m and as a 120 mm object, with the same priors
# scaled alike: the engine keeps the meshes' sizes, only the numbers differ.
SCALES = {"paper": (1.0, None), "metres": (0.02, "m"), "millimetres": (20.0, "mm")}
PRIORS = ("mug_1", "bottle_1")
STEPS = 3


def _model(name, factor):
    model = load_bundled(name)
    if factor == 1.0:
        return model
    return ObjectModel.from_arrays(model.mesh.vertices, model.mesh.faces, name, scale=factor)


def _gold(image):
    """Pixels of the target's gold, lit or in shade (not the salmon, red or blue layers)."""
    r, g, b = (image[..., k].astype(float) for k in range(3))
    return (r > 100) & (g > 0.65 * r) & (g < 0.95 * r) & (b < 0.3 * r)


def _coloured(image):
    return np.abs(image.astype(int) - 255).sum(axis=-1) > 30  # not the white background


@pytest.fixture(scope="module")
def pictures(qapp, tmp_path_factory, settled_screenshot):
    """Per scale: the viewport after a few steps (legend hidden: its gold marker is not the
    target), the scene's length scale and the truth's longest side."""
    return {key: _picture(qapp, settled_screenshot, tmp_path_factory.mktemp(key), *scale)
            for key, scale in SCALES.items()}


def _picture(qapp, screenshot, folder, factor, units):
    library = PriorLibrary(_model(name, factor) for name in PRIORS)
    scene = Scene(truth_model=_model("mug_1", factor), seed=0, library=library, units=units)
    settings = QSettings(str(folder / "settings.ini"), QSettings.IniFormat)
    window = MainWindow(scene, settings=settings, engine="thread")
    window.resize(1280, 720)
    window.show()
    assert QTest.qWaitForWindowExposed(window)
    for _ in range(STEPS):
        scene.step()
    qapp.processEvents()
    window.frame_truth()
    window.layers.legend.SetVisibility(False)
    image = screenshot(window.plotter)
    picture = (image, window.layers.scene_length, scene.truth.model.length,
               window.plotter.camera.clipping_range, window.layers.bounds())
    window.close()
    qapp.processEvents()
    return picture


def _spread(values):
    return max(values) / min(values)


def test_markers_and_object_take_the_same_share_of_the_view_at_any_size(pictures):
    lengths = {key: (scale, truth) for key, (_, scale, truth, *_) in pictures.items()}
    # The window's length scale is the priors' reference size, in the scene's units.
    for key, (factor, _) in SCALES.items():
        assert lengths[key][0] == pytest.approx(6.0 * factor)
    targets = {key: _gold(image).mean() for key, (image, *_) in pictures.items()}
    coloured = {key: _coloured(image).mean() for key, (image, *_) in pictures.items()}
    # Drawn over everything, the target shows whole: about 0.05% of a 1280x720 window's
    # viewport (it filled a fifth of it in metres, and was not seen in millimetres).
    assert all(share > 1e-4 for share in targets.values()), targets
    assert _spread(targets.values()) < 1.5, targets
    # The object with its markers: a quarter of the view or so, never the whole of it.
    assert all(0.05 < share < 0.6 for share in coloured.values()), coloured
    assert _spread(coloured.values()) < 1.5, coloured


def test_the_clipping_range_holds_the_scene_at_any_size(pictures):
    for key, (_, scale, truth, (near, far), bounds) in pictures.items():
        extent = np.subtract(bounds[1::2], bounds[0::2])
        assert np.all(extent > 0.5 * truth) and np.all(extent < 3 * truth), key
        # Near and far in proportion: the framed scene lies between them.
        assert 0 < near < far and far - near > np.linalg.norm(extent) * 0.9, key
        assert far < 100 * scale, key


def test_a_recording_in_millimetres_is_framed_at_its_first_step(qtbot, tmp_path):
    # No truth to frame: before a step the camera frames a box as long as the priors, at
    # the first step what it shows, and the object box names no object.
    library = PriorLibrary(_model(name, 20.0) for name in PRIORS)
    simulated = Scene(truth_model=_model("mug_1", 20.0), seed=1, library=library, units="mm")
    for _ in range(2):
        simulated.step()
    recording = simulated.export(tmp_path / "out")[0]
    scene = Scene(truth_model=_model("mug_1", 20.0), seed=1,
                  library=PriorLibrary(list(library)), units="mm")
    window = MainWindow(scene, settings=QSettings(str(tmp_path / "s.ini"), QSettings.IniFormat),
                        engine="thread")
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    assert window.open_observations(recording)
    assert window.scene_panel.object_box.currentText() == ""
    assert window.scene_panel.object_box.placeholderText() == "(recording)"
    np.testing.assert_allclose(window.layers.bounds(), [-60, 60] * 3)
    scene.step()
    contacts = scene.latest.contacts
    low, high = np.asarray(window.layers.bounds()).reshape(3, 2).T
    assert np.all(low <= contacts.min(axis=0)) and np.all(contacts.max(axis=0) <= high)
    renderer = window.plotter.renderer
    width, height = renderer.GetSize()
    for point in contacts:  # every contact is in view
        renderer.SetWorldPoint(*point, 1.0)
        renderer.WorldToDisplay()
        x, y, depth = renderer.GetDisplayPoint()
        assert 0 <= x <= width and 0 <= y <= height and 0 < depth < 1, point
    window.close()
