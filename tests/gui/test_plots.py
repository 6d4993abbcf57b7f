"""The plots: most updates are blitted over a saved background, a changed layout is drawn
in full."""

from types import SimpleNamespace

import numpy as np
import pytest

from tactile_viz.gui.plots import PlotsWidget

pytestmark = pytest.mark.gui
NAMES = ["mug_1", "vase_1", "bottle_1"]


def _snapshots(count, rng):
    snapshots = []
    for step in range(1, count + 1):
        posterior = dict(zip(NAMES, rng.dirichlet(np.ones(len(NAMES)))))
        snapshots.append(SimpleNamespace(step=step, class_posterior=posterior,
                                         map_class=max(posterior, key=posterior.get),
                                         pose_error=1.0 / step + 0.3, dhd=2.0 / step ** 0.5,
                                         recon_error=None, novel=False))
    return snapshots


def _shown_plots(qtbot):
    plots = PlotsWidget()
    qtbot.addWidget(plots)
    plots.resize(320, 600)
    plots.show()
    qtbot.waitExposed(plots)
    return plots


def test_updates_blit_until_the_layout_changes(qtbot):
    plots = _shown_plots(qtbot)
    snapshots = _snapshots(120, np.random.default_rng(0))
    plots.update_plots(snapshots[:12])
    qtbot.waitUntil(lambda: plots._background is not None)  # the first, full draw
    full_draws = len(plots.draw_log) - plots.blits
    for count in range(13, 40):  # the step axis stays at 0-50, the error axis' decades too
        plots.update_plots(snapshots[:count])
    assert plots.blits == 27 and len(plots.draw_log) - plots.blits == full_draws
    np.testing.assert_array_equal(plots._lines["dhd"].get_xdata(), np.arange(1, 40))
    plots.update_plots(snapshots[:60])  # past 50: the step axis grows, a full draw follows
    assert plots.error_axes.get_xlim() == (0, 100) and plots.blits == 27
    qtbot.waitUntil(lambda: len(plots.draw_log) - plots.blits == full_draws + 1)
    plots.set_eps(0.8)  # the stop line moves: drawn in full again
    plots.update_plots(snapshots[:61])
    assert plots.blits == 27


def test_a_novel_step_shows_its_novelty_instead_of_the_posterior(qtbot):
    # The priors' posterior and a pose error against a prior are not the novel object's.
    from tactile_viz.gui.plots import NOVELTY_TITLE, POSTERIOR_TITLE

    plots = _shown_plots(qtbot)
    known = _snapshots(3, np.random.default_rng(2))
    novel = [SimpleNamespace(**vars(s) | dict(step=s.step + 3, novel=True, recon_error=0.5,
                                              log_evidence=-195.4, log_threshold=-184.7))
             for s in known]
    plots.update_plots(known + novel)
    note = plots._novelty_note
    assert plots._posterior_title.get_text() == NOVELTY_TITLE and note.get_visible()
    assert not any(bar.get_visible() for bar in plots._bars)
    assert "judged NOVEL" in note.get_text() and "evidence -195.4, threshold -184.7" in (
        note.get_text()) and note.get_text().endswith(f": {novel[-1].map_class}")
    pose = np.asarray(plots._lines["pose_error"].get_ydata(), dtype=float)
    assert np.isfinite(pose[:3]).all() and np.isnan(pose[3:]).all()
    assert np.isfinite(plots._lines["recon_error"].get_ydata()[3:]).all()
    plots.update_plots(known)  # a known step again
    assert plots._posterior_title.get_text() == POSTERIOR_TITLE and not note.get_visible()
    assert all(bar.get_visible() for bar in plots._bars)


def test_a_run_is_drawn_without_full_draws(qtbot):
    # While a run is drawn the step axis spans the cap and the error axis only widens:
    # every update is blitted (a full draw blocks the event loop for over 0.1 s).
    plots = _shown_plots(qtbot)
    snapshots = _snapshots(300, np.random.default_rng(1))
    plots.update_plots(snapshots[:5])
    plots.set_run_steps(400, now=True)
    assert plots.error_axes.get_xlim() == (0, 400)
    full_draws, blits = len(plots.draw_log) - plots.blits, plots.blits
    for count in range(6, 300):
        plots.update_plots(snapshots[:count])
    assert plots.blits - blits == 294 and len(plots.draw_log) - plots.blits == full_draws
    plots.set_run_steps(None)  # the run ended: fitted to the data again, in a later pass
    assert plots.error_axes.get_xlim() == (0, 300)
    qtbot.waitUntil(lambda: len(plots.draw_log) - plots.blits == full_draws + 1)


def test_classes_laid_out_before_the_first_step_make_it_a_blit(qtbot):
    plots = _shown_plots(qtbot)
    plots.set_classes(NAMES)
    qtbot.waitUntil(lambda: plots._background is not None)
    assert [bar.get_height() for bar in plots._bars] == [0.0] * len(NAMES)
    plots.set_run_steps(300, now=True)
    blits = plots.blits
    first = _snapshots(1, np.random.default_rng(1))
    plots.update_plots(first)
    assert plots.blits == blits + 1  # the bars moved; the layout did not change
    plots.update_plots([])  # a reset: the same classes, back at 0
    assert [bar.get_height() for bar in plots._bars] == [0.0] * len(NAMES)
    assert plots._names == NAMES


def test_the_stop_line_on_the_threshold_is_one_line_named_for_both(qtbot):
    plots = _shown_plots(qtbot)

    def legend():
        return [text.get_text() for text in plots.error_axes.get_legend().get_texts()]

    plots.update_plots(_snapshots(3, np.random.default_rng(0)))  # pose error and DHD
    plots.set_eps(0.6)  # the paper's eps is the error threshold
    assert not plots.eps_line.get_visible()
    assert legend() == ["0.6: threshold and DHD stop (eps)", "pose error", "DHD"]
    plots.set_eps(0.8)
    assert plots.eps_line.get_visible()
    assert legend() == ["0.6 threshold", "DHD stop (eps 0.8)", "pose error", "DHD"]


def test_the_legend_names_only_the_series_with_data(qtbot):
    plots = _shown_plots(qtbot)

    def legend():
        return [text.get_text() for text in plots.error_axes.get_legend().get_texts()]

    plots.set_classes(NAMES)
    plots.set_run_steps(300, now=True)
    assert legend() == ["0.6: threshold and DHD stop (eps)"]  # nothing measured yet
    snapshots = _snapshots(6, np.random.default_rng(3))
    recording = [SimpleNamespace(**dict(vars(s), pose_error=None)) for s in snapshots]
    blits = plots.blits
    plots.update_plots(recording[:1])  # a recording: no truth, no pose error
    assert legend()[1:] == ["DHD"] and plots.blits == blits + 1  # a new entry, still a blit
    novel = snapshots[:3] + [SimpleNamespace(**dict(vars(s), recon_error=0.4))
                             for s in snapshots[3:]]
    plots.update_plots(novel[:3])
    assert legend()[1:] == ["pose error", "DHD"]
    plots.update_plots(novel)  # judged novel: a reconstruction error from step 4
    assert legend()[1:] == ["pose error", "DHD", "reconstruction error"]
    colours = [handle.get_color() for handle in plots.error_axes.get_legend().legend_handles]
    assert colours[1:] == [plots._lines[key].get_color()
                           for key in ("pose_error", "dhd", "recon_error")]
    plots.update_plots([])
    assert legend() == ["0.6: threshold and DHD stop (eps)"]


def test_a_blit_draws_the_legend_and_title_once_then_puts_their_pixels_back(qtbot,
                                                                           monkeypatch):
    plots = _shown_plots(qtbot)
    plots.set_classes(NAMES)
    plots.set_run_steps(300, now=True)
    snapshots = _snapshots(8, np.random.default_rng(4))
    plots.update_plots(snapshots[:1])  # the legend gains its series: made again
    drawn = []
    original = plots.figure.draw_artist
    monkeypatch.setattr(plots.figure, "draw_artist",
                        lambda artist: (drawn.append(artist), original(artist)))
    blits = plots.blits
    for count in range(2, 9):
        plots.update_plots(snapshots[:count])
    assert plots.blits == blits + 7
    legend, title = plots.error_axes.get_legend(), plots._posterior_title
    assert drawn.count(legend) == 0 and drawn.count(title) == 0  # kept from the first
    assert drawn.count(plots._lines["dhd"]) == 7  # the lines are drawn at every blit
    image = np.asarray(plots.buffer_rgba())
    box = legend.get_window_extent()
    height = image.shape[0]
    inside = image[int(height - box.y1) + 2:int(height - box.y0) - 2,
                   int(box.x0) + 2:int(box.x1) - 2, :3]
    assert (inside < 128).any()  # its text is on the canvas


def test_stop_lines_and_axis_in_scene_units(qtbot):
    # A 12 cm object in metres: threshold 10% of it, the paper's eps 0.6 size units is the
    # same length (one line), the axis names the unit and spans the object's scale.
    plots = _shown_plots(qtbot)
    size = 0.12
    plots.set_unit_name("m")
    plots.set_stop_lines(0.1 * size, 0.6 * size / 6)
    assert plots.error_axes.get_ylabel() == "error [m]"
    assert not plots.eps_line.get_visible()
    assert plots.threshold_line.get_ydata()[0] == pytest.approx(0.012)
    assert plots.error_axes.get_legend().get_texts()[0].get_text() == (
        "0.012: threshold and DHD stop (eps)")
    snapshots = [SimpleNamespace(**dict(vars(s), pose_error=s.pose_error * size / 6,
                                        dhd=s.dhd * size / 6))
                 for s in _snapshots(20, np.random.default_rng(2))]
    plots.set_run_steps(300)
    plots.update_plots(snapshots)
    low, high = plots.error_axes.get_ylim()
    assert low <= 1.001 * 0.01 * size / 6 and 0.1 * size < high <= 1.001 * 10 * size / 6
    plots.set_stop_lines(0.012, 0.016)  # eps 0.8 size units: two lines
    assert plots.eps_line.get_visible() and plots.eps_line.get_ydata()[0] == 0.016
    plots.set_unit_name(None)
    assert plots.error_axes.get_ylabel() == "error [scene units]"
