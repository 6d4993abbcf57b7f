"""Plots beside the viewport: class posterior bars and errors over the steps.

A novel step shows no class posterior and no pose error (both are of priors the object is
none of): a note with its novelty evidence and the prior its reconstruction starts from.

The artists are made once per session and updated in place (bar heights, line data); the
layout is computed once and again only when the widget is resized. The axes' limits move in
steps (the step axis by 50, the error axis by decades), so most updates change only the bars
and the lines: those are blitted onto a saved background (a few milliseconds) instead of
redrawing the axes, ticks and text (over 100 ms, which would block the event loop). A full
draw is left to ``draw_idle`` so that it happens in its own pass of the event loop.

Errors are in scene units: the threshold line is 10% of the truth's longest side and the DHD
stop is eps (size units) times a sixth of the MAP object's longest side, both given by the
window (:meth:`PlotsWidget.set_stop_lines`, from the scene); the axis names the unit.
"""

import math
import time
from collections import deque

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullFormatter

from ..app.scene import SCENE_UNITS
from ..engine.params import SessionParams
from ..engine.shape.metrics import ERROR_THRESHOLD as THRESHOLD
from .step_text import novelty_note

# The error axis of a run spans at least these decades (errors and the DHD of a run on
# objects 6 units long stay within them: a known mug's pose error falls below 0.01, and the
# axis widened by a decade in a full draw of 0.25 s mid-run), so that it does not change
# while the run is drawn; scaled with the threshold for objects of other sizes.
RUN_ERROR_RANGE = (0.001, 10.0)
POSTERIOR_TITLE = "class posterior"
NOVELTY_TITLE = "novelty (no class posterior)"
ERROR_SERIES = (("pose_error", "pose error"), ("dhd", "DHD"),
                ("recon_error", "reconstruction error"))


class PlotsWidget(FigureCanvasQTAgg):
    """Two axes: the class posterior (bars; for a novel step its novelty evidence instead)
    and pose error (known steps), reconstruction error and DHD against the step, with the
    error threshold and the DHD stop (eps) drawn."""

    def __init__(self, parent=None):
        self.figure = Figure(figsize=(4.2, 5.0))
        super().__init__(self.figure)
        self.setParent(parent)
        self.posterior_axes = self.figure.add_subplot(2, 1, 1)
        self.error_axes = self.figure.add_subplot(2, 1, 2)
        self._names = None
        self._bars = None
        self._map_class = None
        self._lines = {}
        self._series = {key: [] for key, _ in ERROR_SERIES}
        self._steps = []
        self._last_snapshots = []
        self.last_draw_seconds = 0.0
        self.draw_log = deque(maxlen=10_000)  # (perf_counter at the start, seconds) per draw
        self.eps = SessionParams().eps  # the DHD stop, scene units
        self.threshold = THRESHOLD  # the error threshold, scene units
        self.unit_name = SCENE_UNITS
        self.run_steps = None  # the step axis' fixed end while a run is drawn
        self.blits = 0  # updates drawn by blitting (the rest are full draws)
        self._background = None  # the figure without the bars and lines, after a full draw
        self._layout_key = None
        self._legend_series = None  # the error series the legend names (those with data)
        self._pixels = {}  # (artist, its text) -> its rendered pixels, for a blit (see below)
        self._setup_errors()
        self.update_plots([])
        self._relayout()

    # ------------------------------------------------------------------ layout
    def _setup_errors(self):
        axes = self.error_axes
        axes.set_title("errors over steps", fontsize=9)
        axes.set_xlabel("step", fontsize=8)
        axes.set_ylabel(f"error [{self.unit_name}]", fontsize=8)
        self.threshold_line = axes.axhline(self.threshold, color="tab:red", linestyle="--",
                                           linewidth=1)
        self.eps_line = axes.axhline(self.eps, color="tab:green", linestyle=":", linewidth=1)
        for key, label in ERROR_SERIES:
            # Small dots on the line: a value between gaps (one step judged novel, say) shows.
            (self._lines[key],) = axes.plot([], [], label=label, animated=True, marker=".",
                                            markersize=3)
        axes.set_yscale("log")
        # Plain labels on the decades only: the log axis' default mathtext labels on minor
        # ticks were most of the text of a full draw (about half its 0.15 s).
        axes.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        axes.yaxis.set_minor_formatter(NullFormatter())
        axes.set_xlim(0, 10)
        axes.set_ylim(0.05, 10)
        axes.tick_params(labelsize=7)
        self._label_stop_lines()
        posterior = self.posterior_axes
        # Both change with the step (a novel step shows its novelty instead of the bars):
        # drawn with the bars, over the saved background.
        self._posterior_title = posterior.set_title(POSTERIOR_TITLE, fontsize=9, animated=True)
        self._novelty_note = posterior.text(0.5, 0.55, "", transform=posterior.transAxes,
                                            ha="center", va="center", fontsize=7,
                                            animated=True, visible=False, linespacing=1.4,
                                            bbox={"facecolor": "white", "edgecolor": "0.6"})
        posterior.set_ylim(0, 1)
        posterior.tick_params(axis="y", labelsize=7)

    def _label_stop_lines(self):
        """One line when eps is the error threshold (two would lie on top of each other and
        blend into one of neither colour), else one each."""
        same = math.isclose(self.eps, self.threshold, rel_tol=1e-9)
        threshold = f"{self.threshold:.3g}"
        self.threshold_line.set_label(f"{threshold}: threshold and DHD stop (eps)" if same
                                      else f"{threshold} threshold")
        self.eps_line.set_label(f"DHD stop (eps {self.eps:.3g})")
        self.eps_line.set_visible(not same)
        self._legend_series = None
        self._update_legend()

    def _series_with_data(self):
        return tuple(key for key, _ in ERROR_SERIES
                     if np.isfinite(np.asarray(self._series[key], dtype=float)).any())

    def _update_legend(self):
        """The stop lines and the error series that have data (a known object has no
        reconstruction error, a recording no pose error). The legend is drawn with the
        lines, over the saved background, so that a new entry is no full draw. The series
        are named by proxies: an entry copies its line's visibility (none before data)."""
        series = self._series_with_data()
        if series == self._legend_series:
            return
        self._legend_series = series
        handles = [self.threshold_line] + ([self.eps_line] if self.eps_line.get_visible()
                                           else [])
        labels = [line.get_label() for line in handles]
        for key, label in ERROR_SERIES:
            if key in series:
                line = self._lines[key]
                handles.append(Line2D([], [], color=line.get_color(),
                                      linewidth=line.get_linewidth()))
                labels.append(label)
        # Opaque: its pixels are kept and put back at each blit, not drawn again.
        legend = self.error_axes.legend(handles, labels, fontsize=7, loc="upper right",
                                        framealpha=1.0)
        legend.set_animated(True)
        self._pixels.clear()

    def _relayout(self):
        try:
            self.figure.tight_layout(pad=0.6)
        except (ValueError, np.linalg.LinAlgError):  # a widget too small to lay out
            pass

    def draw(self):
        """Full draw: axes, ticks, text, then the bars and lines over a saved copy."""
        began = time.perf_counter()
        super().draw()
        self._background = self.copy_from_bbox(self.figure.bbox)
        self._pixels.clear()
        self._layout_key = self._current_layout()
        self._draw_dynamic()
        self._log(began)

    def _log(self, began):
        self.last_draw_seconds = time.perf_counter() - began
        self.draw_log.append((began, self.last_draw_seconds))

    def _dynamic_artists(self):
        return (list(self._bars or []) + [self._novelty_note] + list(self._lines.values()))

    def _draw_dynamic(self):
        for artist in self._dynamic_artists():
            self.figure.draw_artist(artist)
        for artist in (self._posterior_title, self.error_axes.get_legend()):
            self._draw_kept(artist)

    def _draw_kept(self, artist):
        """Draw ``artist`` (the title, or the legend, opaque and over the lines) from its
        kept pixels: rendering its text took 7 and 19 ms of a 50 ms blit. They are kept
        per text until the layout changes (a full draw) or the legend is made again."""
        key = (id(artist), artist.get_text() if hasattr(artist, "get_text") else None)
        kept = self._pixels.get(key)
        if kept is not None:
            self.restore_region(kept)
            return
        self.figure.draw_artist(artist)
        self._pixels[key] = self.copy_from_bbox(artist.get_window_extent())

    def _current_layout(self):
        return (self.error_axes.get_xlim(), self.error_axes.get_ylim(), self._names, self.eps,
                self.threshold, self.unit_name, self.width(), self.height())

    def _refresh(self):
        """Blit the bars and lines when nothing else changed, else ask for a full draw."""
        if self._background is None or self._layout_key != self._current_layout():
            self.draw_idle()
            return
        began = time.perf_counter()
        self.restore_region(self._background)
        self._draw_dynamic()
        self.blit(self.figure.bbox)
        self.blits += 1
        self._log(began)

    def resizeEvent(self, event):
        super().resizeEvent(event)
        self._background = None
        self._relayout()
        self.draw_idle()

    # ------------------------------------------------------------------ updates
    def set_eps(self, eps):
        """Move the DHD stop line to ``eps`` (the session's termination threshold, scene
        units)."""
        self.set_stop_lines(self.threshold, eps)

    def set_stop_lines(self, threshold, eps):
        """Draw the error threshold at ``threshold`` and the DHD stop at ``eps`` (scene
        units: 10% of the truth's size, eps times a sixth of the MAP object's size)."""
        threshold, eps = float(threshold), float(eps)
        if (threshold, eps) != (self.threshold, self.eps):
            self.threshold, self.eps = threshold, eps
            self.threshold_line.set_ydata([threshold, threshold])
            self.eps_line.set_ydata([eps, eps])
            self._label_stop_lines()
            self._show_errors(self._last_snapshots)  # the axis spans both lines
            self.draw_idle()

    def set_unit_name(self, name):
        """Name the errors' length unit on the axis ("scene units", "m", ...)."""
        name = name or SCENE_UNITS
        if name != self.unit_name:
            self.unit_name = name
            self.error_axes.set_ylabel(f"error [{name}]", fontsize=8)
            self._relayout()
            self.draw_idle()

    def set_run_steps(self, steps, now=False):
        """While a run is drawn (``steps``: its step cap) the step axis spans the cap and
        the error axis only widens, so that the run's updates are blitted and never wait
        for a full draw; None fits both axes to the data again. The new layout is drawn
        at once with ``now``, else in a later pass of the event loop."""
        if steps == self.run_steps:
            return
        self.run_steps = steps
        self._show_errors(self._last_snapshots)
        if now:
            self.draw()
        else:
            self.draw_idle()

    def update_plots(self, snapshots):
        """Show a list of snapshots (empty clears); the artists are updated in place."""
        self._last_snapshots = snapshots
        self._show_posterior(snapshots[-1] if snapshots else None)
        self._show_errors(snapshots)
        self._refresh()

    def set_classes(self, names):
        """Lay the posterior's bars out for the classes ``names`` (at 0) before the first
        step, so that the first step of a run only moves them."""
        self._set_names(list(names) or None)
        self.draw_idle()

    def _show_posterior(self, snapshot):
        novel = snapshot is not None and snapshot.novel
        self._show_novelty(snapshot if novel else None)
        if snapshot is not None:
            self._set_names(list(snapshot.class_posterior))
        for bar in self._bars or []:
            bar.set_visible(not novel)
        if snapshot is None:  # no step yet: the classes' bars (if laid out) at 0
            self._map_class = None
            for bar in self._bars or []:
                bar.set_height(0.0)
                bar.set_color("tab:blue")
            return
        names = list(snapshot.class_posterior)
        for bar, name in zip(self._bars or [], names):
            bar.set_height(snapshot.class_posterior[name])
        if snapshot.map_class != self._map_class:
            self._map_class = snapshot.map_class
            for bar, name in zip(self._bars, names):
                bar.set_color("tab:red" if name == snapshot.map_class else "tab:blue")

    def _show_novelty(self, snapshot):
        """A novel step (None: a known one or none) shows its novelty evidence and the prior
        its reconstruction starts from instead of the priors' posterior, which is not the
        object's."""
        self._posterior_title.set_text(NOVELTY_TITLE if snapshot else POSTERIOR_TITLE)
        self._novelty_note.set_visible(snapshot is not None)
        if snapshot is not None:
            self._novelty_note.set_text(novelty_note(snapshot))

    def _set_names(self, names):
        axes = self.posterior_axes
        if names != self._names:
            if self._bars is not None:
                self._bars.remove()
                self._bars = None
            self._names = names
            self._map_class = None
            if names:
                self._bars = axes.bar(range(len(names)), np.zeros(len(names)), color="tab:blue")
                for bar in self._bars:
                    bar.set_animated(True)
                axes.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
                axes.set_xlim(-0.6, len(names) - 0.4)
                self._relayout()
            else:
                axes.set_xticks([])

    def _show_errors(self, snapshots):
        # Append only the steps not seen yet; a shorter or different history starts over.
        if not snapshots or (self._steps and (len(snapshots) < len(self._steps)
                                              or snapshots[len(self._steps) - 1].step
                                              != self._steps[-1])):
            self._steps = []
            self._series = {key: [] for key, _ in ERROR_SERIES}
        for snapshot in snapshots[len(self._steps):]:
            self._steps.append(snapshot.step)
            for key, _ in ERROR_SERIES:
                value = getattr(snapshot, key)
                if key == "pose_error" and snapshot.novel:
                    value = None  # against a prior the object is not: not drawn
                self._series[key].append(np.nan if value is None else float(value))
        values = []
        for key, _ in ERROR_SERIES:
            series = np.asarray(self._series[key], dtype=float)
            self._lines[key].set_data(self._steps, series)
            self._lines[key].set_visible(bool(len(series)) and not np.all(np.isnan(series)))
            values.append(series[np.isfinite(series) & (series > 0)])
        self._update_legend()
        axes = self.error_axes
        last = self._steps[-1] if self._steps else 0
        values = np.concatenate(values + [np.array([self.threshold, self.eps])])
        scale = self.threshold / THRESHOLD  # the object's size against the paper's 6
        low = max(1e-3 * scale, 10.0 ** math.floor(math.log10(values.min() / 1.5)))
        high = 10.0 ** math.ceil(math.log10(values.max() * 1.5))
        if self.run_steps is not None:
            axes.set_xlim(0, max(self.run_steps, last))
            current = axes.get_ylim()
            low = min(low, current[0], RUN_ERROR_RANGE[0] * scale)
            high = max(high, current[1], RUN_ERROR_RANGE[1] * scale)
        else:
            axes.set_xlim(0, 10 if last < 10 else 50 * math.ceil((last + 1) / 50))
        axes.set_ylim(low, high)
