"""The Controls dock at common screen sizes: every group shown whole, without scrolling."""

import pytest
from PySide6.QtCore import QPoint, QSettings
from PySide6.QtWidgets import QStyle, QStyleOptionComboBox

from tactile_viz.app.scene import LOADED_PRESET, Scene
from tactile_viz.engine.presets import SESSION_PRESETS
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
    for text in [*SESSION_PRESETS, LOADED_PRESET]:  # "recommended" showed as "recommer"
        assert _combo_text_room(window.exploration_panel.preset_box) >= _text_width(
            window.exploration_panel.preset_box, text), text
    for box in (window.scene_panel.object_box, window.exploration_panel.strategy_box):
        for index in range(box.count()):
            assert _combo_text_room(box) >= _text_width(box, box.itemText(index))
    window.close()


def _text_width(box, text):
    return box.fontMetrics().horizontalAdvance(text)


def _combo_text_room(box):
    """The width of a combo box's text field, pixels (its style's edit field)."""
    option = QStyleOptionComboBox()
    box.initStyleOption(option)
    field = box.style().subControlRect(QStyle.ComplexControl.CC_ComboBox, option,
                                       QStyle.SubControl.SC_ComboBoxEditField, box)
    return field.width()
