"""Plots beside the viewport: class posterior bars and errors over the steps."""

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure

from ..engine.metrics import ERROR_THRESHOLD as THRESHOLD


class PlotsWidget(FigureCanvasQTAgg):
    """Two axes: the class posterior (bars) and pose error, reconstruction error and DHD
    against the step, with the 0.6 thresholds drawn."""

    def __init__(self, parent=None):
        self.figure = Figure(figsize=(4.2, 5.0), tight_layout=True)
        super().__init__(self.figure)
        self.setParent(parent)
        self.posterior_axes = self.figure.add_subplot(2, 1, 1)
        self.error_axes = self.figure.add_subplot(2, 1, 2)
        self.update_plots([])

    def update_plots(self, snapshots):
        """Redraw from a list of snapshots (empty clears)."""
        self._draw_posterior(snapshots[-1] if snapshots else None)
        self._draw_errors(snapshots)
        self.draw_idle()

    def _draw_posterior(self, snapshot):
        axes = self.posterior_axes
        axes.clear()
        axes.set_title("class posterior", fontsize=9)
        axes.set_ylim(0, 1)
        if snapshot is None:
            return
        names = list(snapshot.class_posterior)
        values = [snapshot.class_posterior[name] for name in names]
        colours = ["tab:red" if name == snapshot.map_class else "tab:blue" for name in names]
        axes.bar(range(len(names)), values, color=colours)
        axes.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
        axes.tick_params(axis="y", labelsize=7)

    def _draw_errors(self, snapshots):
        axes = self.error_axes
        axes.clear()
        axes.set_title("errors over steps", fontsize=9)
        axes.set_xlabel("step", fontsize=8)
        axes.axhline(THRESHOLD, color="tab:red", linestyle="--", linewidth=1,
                     label="0.6 threshold")
        if snapshots:
            steps = [s.step for s in snapshots]
            axes.plot(steps, [s.pose_error for s in snapshots], label="pose error")
            axes.plot(steps, [s.dhd for s in snapshots], label="DHD")
            recon = [np.nan if s.recon_error is None else s.recon_error for s in snapshots]
            if not np.all(np.isnan(recon)):
                axes.plot(steps, recon, label="reconstruction error")
        axes.set_yscale("log")
        axes.tick_params(labelsize=7)
        axes.legend(fontsize=7, loc="upper right")
