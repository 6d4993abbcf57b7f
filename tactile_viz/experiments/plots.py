"""The paper's figures as PNG files (matplotlib, non-GUI Agg backend)."""

import numpy as np

from .aggregate import THRESHOLD, curve, estimate_error, group, mean_std, t95

COLOURS = {"gpis-dhd": "tab:orange", "rrt": "tab:blue", "before": "tab:gray",
           "after": "tab:green"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _curve_panel(axis, results_by_label, key, ylabel, title, threshold=THRESHOLD):
    """Mean over trials with a 95% band, one line per label, and the threshold."""
    for label, results in results_by_label.items():
        steps, mean, half = curve(results, key)
        if not len(steps):
            continue
        colour = COLOURS.get(label.split()[0])
        axis.plot(steps, mean, label=f"{label} ({len(results)})", color=colour)
        axis.fill_between(steps, mean - half, mean + half, alpha=0.25, color=colour)
    axis.axhline(threshold, color="red", linestyle="--", linewidth=1)
    axis.set_xlabel("time step")
    axis.set_ylabel(ylabel)
    axis.set_title(title, fontsize=10)
    _legend(axis)


def _legend(axis, fontsize=7):
    """A legend when the axis has labelled artists (no warning otherwise)."""
    if axis.get_legend_handles_labels()[0]:
        axis.legend(fontsize=fontsize)


def _bar_panel(axis, summaries, key, ylabel, title, strategies):
    """Per-object mean with a 95% error bar, one bar per strategy."""
    objects = sorted({s["object"] for s in summaries})
    width = 0.8 / max(len(strategies), 1)
    for index, strategy in enumerate(strategies):
        means, halves = [], []
        for name in objects:
            values = [s["steps"] if s.get(key) is None else s[key] for s in summaries
                      if s["object"] == name and s["strategy"] == strategy and "error" not in s]
            mean, std, n = mean_std(values)
            means.append(mean)
            halves.append(t95(n) * std / np.sqrt(n) if n > 1 else 0.0)
        positions = np.arange(len(objects)) + (index - (len(strategies) - 1) / 2) * width
        axis.bar(positions, means, width, yerr=halves, label=strategy,
                 color=COLOURS.get(strategy), capsize=2)
    axis.set_xticks(np.arange(len(objects)), objects, rotation=60, ha="right", fontsize=7)
    axis.set_ylabel(ylabel)
    axis.set_title(title, fontsize=10)
    _legend(axis)


def overview_figure(results, summaries, path, strategies):
    """The paper's results overview (a)-(h): known objects on top, novel objects below.

    Parameters
    ----------
    results : dict
        ``{"known": [trial dict, ...], "novel": [...]}`` (protocol trials).
    summaries : dict
        The same keys, lists of :func:`~tactile_viz.experiments.aggregate.summarise_trial`.
    path : path-like
        The PNG file.
    strategies : list of str
    """
    plt = _pyplot()
    figure, axes = plt.subplots(2, 4, figsize=(18, 8.5))
    known = {s: [r for r in results["known"] if r["strategy"] == s] for s in strategies}
    novel = {s: [r for r in results["novel"] if r["strategy"] == s] for s in strategies}
    _curve_panel(axes[0, 0], known, "pose_error", "pose error (TWD)", "(a) known: pose error")
    _bar_panel(axes[0, 1], summaries["known"], "steps_to_pose", "steps",
               f"(b) known: steps to pose error < {THRESHOLD:g}", strategies)
    _curve_panel(axes[0, 2], known, "dhd", "DHD", "(c) known: DHD estimate -> contacts")
    _bar_panel(axes[0, 3], summaries["known"], "steps", "steps",
               "(d) known: termination step", strategies)
    _curve_panel(axes[1, 0], novel, estimate_error, "reconstruction error (TWD)",
                 "(e) novel: reconstruction error")
    _bar_panel(axes[1, 1], summaries["novel"], "steps_to_recon", "steps",
               f"(f) novel: steps to error < {THRESHOLD:g}", strategies)
    _curve_panel(axes[1, 2], novel, "dhd", "DHD", "(g) novel: DHD estimate -> contacts")
    _bar_panel(axes[1, 3], summaries["novel"], "steps", "steps",
               "(h) novel: termination step", strategies)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)
    return path


def reconstruction_figure(summaries, path):
    """Per novel object: PF-MAP, PF-MAP-GPIS and Screened Poisson error (GPIS-DHD trials)."""
    plt = _pyplot()
    figure, axis = plt.subplots(figsize=(9, 4))
    items = group([s for s in summaries if s["strategy"] == "gpis-dhd" and "error" not in s],
                  "object")
    names = [key[0] for key in items]
    methods = [("pose_error", "PF-MAP", "tab:gray"), ("recon_error", "PF-MAP-GPIS", "tab:orange"),
               ("poisson_error", "Screened Poisson", "tab:purple")]
    for index, (key, label, colour) in enumerate(methods):
        stats = [mean_std([s[key] for s in group_items]) for group_items in items.values()]
        positions = np.arange(len(names)) + (index - 1) * 0.27
        axis.bar(positions, [m for m, _, _ in stats], 0.27,
                 yerr=[sd for _, sd, _ in stats], label=label, color=colour, capsize=2)
    axis.axhline(THRESHOLD, color="red", linestyle="--", linewidth=1)
    axis.set_xticks(np.arange(len(names)), names, rotation=30, ha="right", fontsize=8)
    axis.set_ylabel("TWD to the truth")
    axis.set_title("novel objects: reconstruction error (mean, std)", fontsize=10)
    axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)
    return path


def learned_figure(before, after, path):
    """Learned prior: pose error and DHD over steps, before and after adding it."""
    plt = _pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    runs = {"before (known priors)": before, "after (+ learned prior)": after}
    _curve_panel(axes[0], runs, "pose_error", "pose error (TWD)", "learned prior: pose error")
    _curve_panel(axes[1], runs, "dhd", "DHD", "learned prior: DHD")
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)
    return path
