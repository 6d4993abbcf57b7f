"""The Controls panels: each fills its widgets from the scene without emitting its signals,
and the dock keeps the loop in view at 1280x720."""

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QSettings, Qt, Signal
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QAbstractButton, QWidget

from tactile_viz.app.scene import Scene
from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.shape.gpis_evidence import Superquadric
from tactile_viz.gui.actions import ACTIONS
from tactile_viz.gui.layers import LAYERS
from tactile_viz.gui.main_window import MainWindow
from tactile_viz.gui.panels import ExplorationPanel, LayersPanel, LoopPanel, PriorsPanel, ScenePanel
from tactile_viz.gui.panels.loop_panel import LOOP_ACTIONS

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def known_library():
    return PriorLibrary.bundled("known")


@pytest.fixture
def scene(known_library):
    return Scene("mug_1", seed=0, library=PriorLibrary(list(known_library)))


def _record(panel):
    """Every signal the panel's class declares, connected to one list of (name, args)."""
    emitted = []
    names = [name for name, value in vars(type(panel)).items() if isinstance(value, Signal)]
    assert names
    for name in names:
        getattr(panel, name).connect(lambda *args, n=name: emitted.append((n, args)))
    return emitted


def _panel(qtbot, panel):
    qtbot.addWidget(panel)
    return panel


def test_scene_panel_syncs_silently(qtbot, scene):
    panel = _panel(qtbot, ScenePanel(scene.bundled_objects()))
    emitted = _record(panel)
    scene.randomize_pose(7)
    scene.set_truth_bundled("vase_1")
    panel.sync(scene)
    assert panel.object_box.currentText() == "vase_1" and panel.seed_box.value() == 7
    assert emitted == []
    panel.place_button.click()
    assert emitted == [("pose_requested", (7,))]


def test_priors_panel_syncs_silently(qtbot, scene):
    panel = _panel(qtbot, PriorsPanel())
    emitted = _record(panel)
    scene.set_prior_enabled("mug_1", False)
    panel.sync(scene)
    states = {panel.prior_list.item(i).text(): panel.prior_list.item(i).checkState()
              for i in range(panel.prior_list.count())}
    assert list(states) == scene.library.names
    assert [name for name, state in states.items() if state == Qt.Unchecked] == ["mug_1"]
    assert emitted == []
    panel.prior_list.item(scene.library.names.index("mug_1")).setCheckState(Qt.Checked)
    assert emitted == [("prior_toggled", ("mug_1", True))]


def test_exploration_panel_syncs_silently(qtbot, scene):
    panel = _panel(qtbot, ExplorationPanel())
    emitted = _record(panel)
    scene.set_strategy("rrt")
    scene.set_preset("fast")
    scene.set_parameter("eps", 0.8)
    scene.set_parameter("n_s", 7)
    panel.sync(scene)
    assert panel.strategy_box.currentText() == "rrt"
    assert panel.preset_box.currentText() == "fast"
    for name, box in panel.parameter_boxes.items():
        assert box.value() == pytest.approx(scene.parameter(name), abs=1e-3)
    assert emitted == []
    panel.parameter_boxes["eps"].setValue(0.9)
    assert emitted == [("parameter_changed", ("eps", pytest.approx(0.9)))]


def test_every_length_parameter_shows_its_unit(qtbot):
    # The units come from the parameters' field metadata: every spin box of a length field
    # says "size units" in its label and its tooltip, and no other box does.
    from dataclasses import fields

    from tactile_viz.engine.params import FilterParams, SessionParams, length_fields

    panel = _panel(qtbot, ExplorationPanel())
    grid = panel.layout()
    lengths = {**length_fields(FilterParams), **length_fields(SessionParams)}
    known = {f.name for f in fields(FilterParams)} | {f.name for f in fields(SessionParams)}
    assert {"sigma_d", "eps"} <= set(panel.parameter_boxes)
    for name, box in panel.parameter_boxes.items():
        assert name in known
        row, column, _, _ = grid.getItemPosition(grid.indexOf(box))
        label = grid.itemAtPosition(row, column - 1).widget().text()
        if name in lengths:
            assert label.endswith("[size units]"), (name, label)
            assert "size unit is a sixth of" in box.toolTip() and "10%" in box.toolTip()
        else:
            assert "size unit" not in label and "size unit" not in box.toolTip(), name


def test_the_status_line_gives_errors_in_scene_units_and_shares_of_the_size():
    from types import SimpleNamespace

    from tactile_viz.gui.panels.loop_panel import format_length, status_text

    snapshot = SimpleNamespace(novel=False, map_class="mug_1", dhd=1.18, pose_error=0.25,
                               recon_error=None, n_particles=464, timings={"filter": 0.03},
                               rotation_error_deg=3.5, translation_error=0.07)
    text = status_text(snapshot, 6.0)
    assert ("MAP mug_1 | pose error 0.25 (4.2%) | rot 3.5\u00b0, shift 0.07 | recon error - "
            in text)
    small = SimpleNamespace(**dict(vars(snapshot), dhd=0.0236, pose_error=0.005,
                                   translation_error=0.0014))
    text = status_text(small, 0.12)  # a 12 cm mug in metres: not rounded to zeros
    assert "pose error 0.0050 (4.2%) | rot 3.5\u00b0, shift 0.0014" in text
    other = SimpleNamespace(**dict(vars(snapshot), rotation_error_deg=None,
                                   translation_error=None, pose_error=None))
    assert "rot" not in status_text(other, 6.0) and "pose error - |" in status_text(other, 6.0)
    assert format_length(0.8) == "0.80" and format_length(0.012, 0.12) == "0.0120"


def test_the_status_line_says_whether_a_known_object_is_decided_or_why_novel():
    from types import SimpleNamespace

    from tactile_viz.gui.panels.loop_panel import status_text
    from tactile_viz.gui.step_text import summary_text

    base = dict(map_class="mug_1", dhd=1.0, pose_error=None, recon_error=None, n_particles=9,
                timings={}, rotation_error_deg=None, translation_error=None)
    deciding = SimpleNamespace(**base, novel=False, decided=False, decision_confidence=0.42)
    decided = SimpleNamespace(**base, novel=False, decided=True, decision_confidence=0.9993)
    assert status_text(deciding).startswith("known, deciding (42%) | MAP mug_1")
    assert status_text(decided).startswith("known, decided (99.9%)")
    # Novel: no pose error against the prior (not the object); the novelty test's numbers,
    # the reconstruction's error and size beside the truth's.
    novel = SimpleNamespace(**dict(base, pose_error=1.3, recon_error=0.6), novel=True,
                            log_evidence=-195.43, log_threshold=-184.7,
                            gpis_vertices=np.array([[0, 0, 0], [6.5, 1, 2]]))
    assert status_text(novel, 6.0) == (
        "NOVEL | prior used mug_1 | evidence -195.4, threshold -184.7 | recon error 0.60 "
        "(10.0%) | size 6.50 (truth 6.00) | particles 9")
    assert summary_text(novel, 6.0) == "NOVEL | prior used mug_1 | recon error 0.60 (10.0%)"
    fitted = SimpleNamespace(**vars(novel), gpis_shape=Superquadric(
        np.zeros(3), np.eye(3), np.ones(3), 0.2))
    assert summary_text(fitted, 6.0).startswith("NOVEL | prior used box fitted | recon")
    recorded = SimpleNamespace(**vars(novel) | dict(recon_error=None, gpis_vertices=None))
    assert "recon error - | size - | particles" in status_text(recorded, 6.0)


def test_layers_panel_syncs_silently(qtbot):
    panel = _panel(qtbot, LayersPanel())
    emitted = _record(panel)
    visible = {name: name != "contacts" for name in LAYERS}
    panel.sync(visible)
    assert {name: box.isChecked() for name, box in panel.layer_boxes.items()} == visible
    assert emitted == []
    panel.layer_boxes["contacts"].setChecked(True)
    assert emitted == [("layer_toggled", ("contacts", True))]


def _loop_actions(parent):
    """Stand-ins for the window's actions of the loop panel (Run checkable, as declared)."""
    actions = {name: QAction(name.title(), parent) for name in LOOP_ACTIONS}
    actions["run"].setCheckable(True)
    return actions


def test_loop_panel_syncs_silently(qtbot, scene):
    owner = QWidget()
    qtbot.addWidget(owner)
    actions = _loop_actions(owner)
    panel = _panel(qtbot, LoopPanel(actions))
    emitted = _record(panel)
    scene.step()
    scene.step()
    panel.sync(scene)
    slider = panel.history_slider
    assert panel.step_label.text().startswith("step 2")
    assert (slider.minimum(), slider.maximum(), slider.value()) == (1, 2, 2)
    assert "MAP" in panel.status_label.text()
    panel.set_running(True)
    assert not slider.isEnabled()
    panel.set_running(False)
    scene.reset()
    panel.sync(scene)
    assert panel.step_label.text() == "step 0" and (slider.minimum(), slider.maximum()) == (0, 0)
    assert emitted == []


def test_loop_buttons_are_views_of_their_actions(qtbot):
    owner = QWidget()
    qtbot.addWidget(owner)
    actions = _loop_actions(owner)
    panel = _panel(qtbot, LoopPanel(actions))
    triggered = []
    for name, action in actions.items():
        action.triggered.connect(lambda checked=False, n=name: triggered.append(n))
    panel.step_button.click()
    panel.reset_button.click()
    assert triggered == ["step", "reset"]
    panel.run_button.setChecked(True)  # as on a QPushButton: the action follows
    assert actions["run"].isChecked()
    actions["run"].setChecked(False)
    actions["run"].setText("Pause")
    actions["finish"].setEnabled(False)
    actions["finish"].setToolTip("until the end")
    assert not panel.run_button.isChecked() and panel.run_button.text() == "Pause"
    assert not panel.finish_button.isEnabled()
    assert panel.finish_button.toolTip() == "until the end"


@pytest.fixture
def window(qtbot, scene, tmp_path):
    window = MainWindow(scene, settings=QSettings(str(tmp_path / "s.ini"), QSettings.IniFormat))
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    yield window
    window.wait_for_worker()


def _panels(window):
    return (window.loop_panel, window.scene_panel, window.priors_panel,
            window.exploration_panel, window.layers_panel)


def test_window_panels_follow_the_scene_without_echoing(window):
    scene = window.scene
    recorded = [_record(panel) for panel in _panels(window)]
    changes = []
    scene.settings_changed.connect(lambda: changes.append("settings"))
    scene.set_parameter("eps", 0.8)
    scene.set_prior_enabled("vase_1", False)
    scene.randomize_pose(5)
    assert window.exploration_panel.parameter_boxes["eps"].value() == pytest.approx(0.8)
    assert window.scene_panel.seed_box.value() == 5
    assert all(emitted == [] for emitted in recorded) and changes == ["settings"]


def test_every_loop_button_is_a_declared_action(window):
    """Each button of the Loop panel is a view of the window's action of its name (one
    declaration in ACTIONS gives its text, tooltip, shortcut and states); none is wired by
    hand."""
    declared = {entry.id: entry for entry in ACTIONS}
    buttons = window.loop_panel.findChildren(QAbstractButton)
    assert len(buttons) == len(LOOP_ACTIONS)
    for name, button in window.loop_panel.buttons().items():
        action = window.actions[name]
        assert name in declared and button.defaultAction() is action
        assert button.text() == declared[name].title and button.toolTip() == action.toolTip()
    assert all(button.defaultAction() in window.actions.values() for button in buttons)


def _at_1280_by_720(qtbot, window):
    window.resize(1280, 720)
    qtbot.waitUntil(lambda: window.width() == 1280, timeout=5_000)
    qtbot.wait(50)


def test_loop_stays_in_view_when_the_groups_scroll(qtbot, window):
    window.resize(1100, 520)  # below 1280x720 (where they fit, see test_layout.py)
    qtbot.waitUntil(lambda: window.height() == 520, timeout=5_000)
    qtbot.wait(50)
    dock = window.controls_dock
    bar = window.panel_scroll.verticalScrollBar()
    assert bar.maximum() > 0  # the other groups do scroll at this size
    for position in (bar.minimum(), bar.maximum()):
        bar.setValue(position)
        qtbot.wait(20)
        for button in (window.loop_panel.step_button, window.loop_panel.run_button,
                       window.loop_panel.finish_button, window.loop_panel.reset_button):
            assert not button.visibleRegion().isEmpty()
            corner = button.mapTo(dock, QPoint(button.width() - 1, button.height() - 1))
            assert dock.rect().contains(corner)


def test_no_horizontal_scrolling_at_1280(qtbot, window):
    _at_1280_by_720(qtbot, window)
    scroll = window.panel_scroll
    assert scroll.horizontalScrollBar().maximum() == 0
    assert not scroll.horizontalScrollBar().isVisible()
    assert scroll.widget().width() <= scroll.viewport().width()
    dock = window.controls_dock
    for panel in _panels(window):
        assert panel.width() >= panel.minimumSizeHint().width()  # nothing clipped sideways
        assert panel.mapTo(dock, QPoint(panel.width() - 1, 0)).x() < dock.width()


def test_the_status_line_wraps_between_fields_only(qtbot):
    from PySide6.QtGui import QTextLayout

    from tactile_viz.gui.panels.loop_panel import wrapped_between_fields

    text = wrapped_between_fields("known | MAP mug_1 | DHD 1.18 | pose error 0.45 | "
                                  "recon error - | particles 464 | last step 0.03 s")
    layout = QTextLayout(text)
    layout.beginLayout()
    lines = []
    while (line := layout.createLine()).isValid():
        line.setLineWidth(150)
        lines.append(text[line.textStart():line.textStart() + line.textLength()])
    layout.endLayout()
    assert len(lines) > 2
    for line in lines:  # each line is whole fields: "recon error -" and "| particles" not split
        assert not line.strip(" \u00a0\u2060").startswith("|"), lines
        assert line.strip() == "" or line.rstrip().endswith(("|", "s")), lines


def test_every_parameter_control_is_a_declared_parameter():
    from tactile_viz.engine.params import declarations
    from tactile_viz.gui.panels.exploration_panel import PARAMETERS

    assert set(PARAMETERS) <= set(declarations())
