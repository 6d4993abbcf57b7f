"""The Controls dock at common screen sizes: every group shown whole, without scrolling."""

import pytest
from PySide6.QtCore import QPoint, QSettings

from tactile_viz.app.scene import Scene
from tactile_viz.gui.main_window import MainWindow

pytestmark = pytest.mark.gui


@pytest.mark.parametrize("size", [(1280, 720), (1500, 900), (1920, 1080)])
def test_controls_fit_without_scrolling(qtbot, tmp_path, size):
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat)
    window = MainWindow(Scene("mug_1"), settings=settings, engine="thread")
    qtbot.addWidget(window)
    window.resize(*size)
    window.show()
    qtbot.waitExposed(window)
    qtbot.waitUntil(lambda: (window.width(), window.height()) == size, timeout=5_000)
    qtbot.wait(50)
    scroll = window.panel_scroll
    assert scroll.verticalScrollBar().maximum() == 0
    assert scroll.horizontalScrollBar().maximum() == 0
    area = scroll.viewport().rect()
    for group in (window.scene_panel, window.priors_panel, window.exploration_panel,
                  window.layers_panel):
        top_left = group.mapTo(scroll.viewport(), QPoint(0, 0))
        assert area.contains(top_left) and area.contains(
            top_left + QPoint(group.width() - 1, group.height() - 1)), group.title()
        assert group.height() >= group.minimumSizeHint().height(), group.title()
    dock = window.controls_dock.widget()
    loop = window.loop_panel.mapTo(dock, QPoint(0, 0))
    assert loop.y() >= 0 and loop.y() + window.loop_panel.height() <= dock.height()
    assert window.priors_panel.prior_list.height() >= 70
    for box in window.layers_panel.layer_boxes.values():  # no label cut off
        assert box.width() >= box.sizeHint().width(), box.text()
    window.close()
