"""From trial result dicts to the paper's numbers: per-trial summaries, per-object
statistics, curves over steps with a 95% band, and Markdown tables.

Everything here works on plain dicts (the ``trial`` JSON plus the ``task``, ``poisson`` and
``final`` keys that :func:`~tactile_viz.experiments.runner.run_task` adds), so it can be
tested on synthetic trials.
"""

import math

import numpy as np
from scipy import stats

from ..engine.shape.metrics import ERROR_THRESHOLD as THRESHOLD

# The paper's Table "Comparison of shape reconstruction methods": per novel object, mean and
# std of the TWD to the truth of the PF-MAP shape, the GPIS reconstruction and a Poisson
# reconstruction from the contacts; the tables print our runs beside these numbers.
PAPER_RECONSTRUCTION = {
    "bottle_2": {"pf_map": (0.994, 0.088), "gpis": (0.259, 0.036), "poisson": (0.416, 0.063)},
    "dragon": {"pf_map": (2.952, 0.133), "gpis": (0.478, 0.057), "poisson": (0.582, 0.122)},
    "guitar_2": {"pf_map": (0.412, 0.062), "gpis": (0.412, 0.062), "poisson": (1.092, 0.673)},
    "home_chair": {"pf_map": (1.771, 0.085), "gpis": (0.505, 0.402), "poisson": (1.054, 0.360)},
    "ice_cream_2": {"pf_map": (0.432, 0.046), "gpis": (0.432, 0.046), "poisson": (0.546, 0.126)},
    "mug_2": {"pf_map": (0.580, 0.129), "gpis": (0.526, 0.335), "poisson": (1.703, 0.282)},
    "neptune": {"pf_map": (1.735, 0.801), "gpis": (0.505, 0.125), "poisson": (0.655, 0.201)},
    "noisy_dino": {"pf_map": (1.053, 0.106), "gpis": (0.519, 0.089), "poisson": (0.518, 0.152)},
    "sofa_2": {"pf_map": (0.611, 0.049), "gpis": (0.483, 0.043), "poisson": (0.604, 0.045)},
    "vase_2": {"pf_map": (1.453, 0.221), "gpis": (0.335, 0.060), "poisson": (0.658, 0.081)},
}


def first_step_below(records, key, threshold=THRESHOLD):
    """The first step ``t`` whose ``key`` is below ``threshold`` (None if never)."""
    for record in records:
        value = record.get(key)
        if value is not None and value < threshold:
            return record["t"]
    return None


def estimate_error(record):
    """Error of the current shape estimate: the GPIS surface's when there is one, else the
    MAP shape's (the paper's PF-MAP-GPIS = PF-MAP for objects judged known)."""
    value = record.get("recon_error")
    return record["pose_error"] if value is None else value


def summarise_trial(result):
    """The numbers of one trial.

    Returns
    -------
    dict
        object, strategy, seed, kind, library, map_class, novel (judged novel at the end),
        correct (the MAP class is the object and judged known), pose_error (PF-MAP TWD at the
        end), recon_error (PF-MAP-GPIS: the GPIS surface's TWD, or the MAP shape's when
        judged known), poisson_error, terminated_at, steps, steps_to_pose (first step with
        pose error < 0.6), steps_to_recon (same with the estimate's error), max_particles,
        decided_at (the first step judged decided, beyond the paper; None if never),
        seconds, truth_coverage (distance from the farthest point of the true surface to its
        nearest contact at the end; None in trials made before it was recorded). ``error`` is
        set for a failed trial.
    """
    task = result.get("task", {})
    summary = {"object": result["object"], "strategy": result["strategy"],
               "seed": result["seed"], "kind": task.get("kind", "protocol"),
               "library": task.get("library_label", "known"), "preset": result.get("preset"),
               "tag": task.get("tag")}
    if "error" in result or not result.get("steps"):
        summary["error"] = result.get("error", "no steps")
        return summary
    steps = result["steps"]
    last = steps[-1]
    poisson = result.get("poisson") or {}
    summary.update({
        "map_class": last["map_class"], "novel": bool(last["novel"]),
        "correct": last["map_class"] == result["object"] and not last["novel"],
        "pose_error": last["pose_error"], "recon_error": estimate_error(last),
        "gpis_error": last.get("recon_error"), "poisson_error": poisson.get("recon_error"),
        "terminated_at": result.get("terminated_at"), "steps": last["t"],
        "steps_to_pose": first_step_below(steps, "pose_error"),
        "steps_to_recon": first_step_below(
            [dict(r, estimate=estimate_error(r)) for r in steps], "estimate"),
        "max_particles": max(r["n_particles"] for r in steps),
        "decided_at": next((r["t"] for r in steps if r.get("decided")), None),
        "seconds": result.get("seconds"), "dhd": last["dhd"],
        "truth_coverage": last.get("truth_coverage")})
    return summary


def mean_std(values):
    """``(mean, std, n)`` of the non-None values (NaN when there are none)."""
    values = [v for v in values if v is not None]
    if not values:
        return math.nan, math.nan, 0
    array = np.asarray(values, dtype=float)
    return float(array.mean()), float(array.std(ddof=1)) if len(array) > 1 else 0.0, len(array)


def t95(count):
    """Student's t quantile of a two-sided 95% interval of a mean of ``count`` values
    (2.26 for 10; 1.96 only as the count grows), 0 where ``count`` < 2. Scalar or array."""
    count = np.asarray(count, dtype=float)
    quantile = stats.t.ppf(0.975, np.maximum(count - 1, 1))
    return np.where(count > 1, quantile, 0.0) if quantile.ndim else (
        float(quantile) if count > 1 else 0.0)


def ci95(values):
    """Half-width of the t-based 95% confidence interval of the mean."""
    mean, std, n = mean_std(values)
    return t95(n) * std / math.sqrt(n) if n > 1 else 0.0


def curve(results, key, length=None):
    """Mean and 95% half-band over trials of a per-step quantity.

    A trial that ended earlier holds its last value (its estimate no longer changes).

    Parameters
    ----------
    results : list of dict
    key : str or callable
        A record key, or a function of the record.
    length : int, optional
        Number of steps (default: the longest trial).

    Returns
    -------
    steps, mean, half : ndarray
    """
    get = key if callable(key) else (lambda record: record[key])
    series = [[get(r) for r in result["steps"]] for result in results if result.get("steps")]
    if not series:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    length = length or max(len(s) for s in series)
    table = np.full((len(series), length), np.nan)
    for row, values in enumerate(series):
        values = np.asarray([np.nan if v is None else v for v in values], dtype=float)[:length]
        table[row, :len(values)] = values
        table[row, len(values):] = values[-1]
    mean = np.nanmean(table, axis=0)
    count = np.sum(np.isfinite(table), axis=0)
    std = np.nanstd(table, axis=0, ddof=1) if len(series) > 1 else np.zeros(length)
    half = t95(count) * np.nan_to_num(std) / np.sqrt(np.maximum(count, 1))
    return np.arange(1, length + 1), mean, half


def group(summaries, *keys):
    """Summaries grouped by the given keys, sorted: ``{(k1, k2, ...): [summary, ...]}``."""
    groups = {}
    for summary in summaries:
        groups.setdefault(tuple(summary[k] for k in keys), []).append(summary)
    return dict(sorted(groups.items(), key=lambda item: [str(v) for v in item[0]]))


def _fmt(value, digits=3):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float):
        size = abs(value)
        if size >= 100:
            return f"{value:.1f}"
        if size >= 1 or size == 0:
            return f"{value:.{digits - 1}f}"
        return f"{value:.{digits}g}"
    return str(value)


def markdown_table(header, rows):
    """A GitHub Markdown table from a header list and rows of values."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def _steps(summary, key):
    """A step count, with trials that never got there counted at their last step."""
    value = summary.get(key)
    return summary["steps"] if value is None else value


def known_rows(summaries):
    """Per known object and strategy: accuracy, pose < 0.6 at the end, steps, particles."""
    rows = []
    for (name, strategy), items in group(summaries, "object", "strategy").items():
        ok = [s for s in items if "error" not in s]
        n = len(ok)
        rows.append([
            name, strategy, n,
            f"{sum(s['correct'] for s in ok)}/{n}",
            f"{sum(s['pose_error'] < THRESHOLD for s in ok)}/{n}",
            mean_std([s["pose_error"] for s in ok])[0],
            mean_std([_steps(s, "steps_to_pose") for s in ok])[0],
            sum(s["steps_to_pose"] is None for s in ok),
            mean_std([s["steps"] for s in ok])[0],
            f"{sum(s.get('decided_at') is not None for s in ok)}/{n}",
            _median([s.get("decided_at") for s in ok]),
            max((s["max_particles"] for s in ok), default=None),
            mean_std([s["seconds"] for s in ok])[0]])
    return rows


def _median(values):
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


KNOWN_HEADER = ["object", "strategy", "trials", "correct class", f"pose < {THRESHOLD:g} at end",
                "final pose error", f"steps to pose < {THRESHOLD:g}", f"never < {THRESHOLD:g}",
                "termination step", "decided", "decided at (median)", "max particles",
                "seconds"]


def novel_rows(summaries):
    """Per novel object and strategy: judged novel, the three reconstruction errors and the
    truth coverage at the end (which tells an untouched object from a bad reconstruction)."""
    rows = []
    for (name, strategy), items in group(summaries, "object", "strategy").items():
        ok = [s for s in items if "error" not in s]
        row = [name, strategy, len(ok), f"{sum(s['novel'] for s in ok)}/{len(ok)}"]
        for key in ("pose_error", "recon_error", "poisson_error"):
            mean, std, _ = mean_std([s[key] for s in ok])
            row += [mean, std]
        row += [mean_std([s.get("truth_coverage") for s in ok])[0]]
        row += [mean_std([_steps(s, "steps_to_recon") for s in ok])[0],
                mean_std([s["steps"] for s in ok])[0], mean_std([s["seconds"] for s in ok])[0]]
        rows.append(row)
    return rows


NOVEL_HEADER = ["object", "strategy", "trials", "judged novel", "PF-MAP mean", "PF-MAP std",
                "PF-MAP-GPIS mean", "PF-MAP-GPIS std", "Poisson mean", "Poisson std",
                "truth coverage", f"steps to error < {THRESHOLD:g}", "termination step", "seconds"]


def reconstruction_comparison(summaries):
    """Rows of ours vs the paper's means (GPIS-DHD trials) and the two checks of the issue.

    Returns
    -------
    rows : list of list
    checks : dict
        ``gpis_beats_poisson`` (objects where PF-MAP-GPIS < Poisson, out of how many) and
        ``gpis_beats_map_when_novel`` (among objects judged novel in every trial).
    """
    rows, beats_poisson, beats_map = [], [0, 0], [0, 0]
    for (name,), items in group([s for s in summaries if s["strategy"] == "gpis-dhd"],
                                "object").items():
        ok = [s for s in items if "error" not in s]
        ours = {k: mean_std([s[k] for s in ok])[0]
                for k in ("pose_error", "recon_error", "poisson_error")}
        paper = PAPER_RECONSTRUCTION.get(name, {})
        rows.append([name, ours["pose_error"], paper.get("pf_map", (None,))[0],
                     ours["recon_error"], paper.get("gpis", (None,))[0],
                     ours["poisson_error"], paper.get("poisson", (None,))[0],
                     f"{sum(s['novel'] for s in ok)}/{len(ok)}"])
        if not math.isnan(ours["poisson_error"]):
            beats_poisson[1] += 1
            beats_poisson[0] += ours["recon_error"] < ours["poisson_error"]
        if ok and all(s["novel"] for s in ok):
            beats_map[1] += 1
            beats_map[0] += ours["recon_error"] < ours["pose_error"]
    return rows, {"gpis_beats_poisson": tuple(beats_poisson),
                  "gpis_beats_map_when_novel": tuple(beats_map)}


COMPARISON_HEADER = ["object", "PF-MAP ours", "PF-MAP paper", "PF-MAP-GPIS ours",
                     "PF-MAP-GPIS paper", "Poisson ours", "Poisson paper", "judged novel"]


def learned_rows(before, after):
    """Learned-prior experiment: recognition, steps to pose < 0.6, termination, before/after.

    ``before``: trials of the object with the bundled priors; ``after``: with the learned
    prior added (recognised = the learned prior is the MAP class and judged known; the
    paper's "recognised the chair as the learned model" may mean the MAP class alone, which
    is counted separately).
    """
    rows = []

    def learned_map(s):
        return s["map_class"].endswith("_learned")

    for label, items, recognised in (
            ("before (known priors)", before, lambda s: s["correct"]),
            ("after (+ learned prior)", after,
             lambda s: not s["novel"] and learned_map(s))):
        ok = [s for s in items if "error" not in s]
        n = len(ok)
        posed = sum(s["steps_to_pose"] is not None and s["steps_to_pose"] <= 50 for s in ok)
        rows.append([label, n, f"{sum(learned_map(s) for s in ok)}/{n}",
                     f"{sum(recognised(s) for s in ok)}/{n}",
                     f"{sum(s['novel'] for s in ok)}/{n}",
                     f"{posed}/{n}",
                     mean_std([_steps(s, "steps_to_pose") for s in ok])[0],
                     mean_std([s["pose_error"] for s in ok])[0],
                     mean_std([s["steps"] for s in ok])[0]])
    return rows


LEARNED_HEADER = ["library", "trials", "MAP class = learned prior", "recognised", "judged novel",
                  f"pose < {THRESHOLD:g} within 50",
                  f"steps to pose < {THRESHOLD:g}", "final pose error", "termination step"]
