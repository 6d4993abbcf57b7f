"""``python -m tactile_viz bench tradeoff``: time per trial against pose error,
reconstruction error, truth coverage and termination step over the presets and one-knob
variations of the paper preset, with t-based 95% intervals and the Pareto fronts.

Every configuration runs the same objects and seeds (GPIS-DHD): known objects give the pose
error at termination, novel objects the reconstruction error (PF-MAP-GPIS, or the MAP
shape's when judged known), every object the truth coverage and the termination step. A
configuration is on the Pareto front of a plot when no other one is both at least as fast
and at least as accurate (and strictly better in one), and on it within its interval when
no other one is at least as fast with a mean error below its interval's lower end.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import (
    ArgumentParser,
    ExtendList,
    bundled_objects,
    count_int,
    existing_dir,
    name_list,
    output_dir,
    positive_int,
    workers_int,
)
from ..engine.io.files import write_atomic
from ..engine.params import with_changes
from ..engine.session import SESSION_PRESETS, session_preset
from . import aggregate
from .paper import (
    machine_description,
    object_sets,
    recorded_command,
    require_trials,
    split_names,
    write_json,
)
from .runner import make_task, open_pool, run_tasks, task_key
from .trial_files import read_trials, rounded, trial_path, write_trial

PRESETS = tuple(SESSION_PRESETS)
# name -> (base preset, changes of declared parameters, which with_changes puts in the filter
# or the session): every preset, then one-knob changes of the recommended preset.
CONFIGS = {
    **{name: (name, {}) for name in PRESETS},
    "sdf32": ("recommended", {"sdf_resolution": 32}),
    "sdf96": ("recommended", {"sdf_resolution": 96}),
    "features100": ("recommended", {"n_features": 100}),
    "features300": ("recommended", {"n_features": 300}),
    "coarse-keys": ("recommended", {"distance_step": 0.2, "angle_step_deg": 24.0}),
    "neighbour-bins": ("recommended", {"neighbour_bins": 1}),
    "gpis24": ("recommended", {"gpis_resolution": 24}),
    "gpis48": ("recommended", {"gpis_resolution": 48}),
    "eps0.4": ("recommended", {"eps": 0.4}),
    "eps0.8": ("recommended", {"eps": 0.8}),
    # Particle budget: keep the heaviest new point-pair particles of a step (issue 18).
    "budget3000": ("recommended", {"max_new_particles": 3000}),
    "budget1500": ("recommended", {"max_new_particles": 1500}),
    # Both caps: at most 3,000 draws survive resampling and 1,500 new particles join a step.
    "particles3000": ("recommended", {"max_particles": 3000, "max_new_particles": 1500}),
    # Poses within 0.05 and 1 degree of each other merged into one particle.
    "merge0.05": ("recommended", {"merge_distance": 0.05, "merge_angle_deg": 1.0}),
    # The GPIS ablation (novel objects): the thin-plate kernel (the paper preset's) at the
    # paper's R and explicitly, the compact Wendland kernel with free space at three
    # supports (c = 4 was the paper preset at ef75223), free space with the thin-plate
    # kernel, the prior's carve off or wider.
    "thin-plate1.0": ("recommended", {"gpis_radius_factor": 1.0}),
    "thin-plate1.2": ("recommended", {"gpis_kernel": "thin-plate", "gpis_radius_factor": 1.2,
                                      "gpis_noncontacts": False}),
    "wendland4": ("recommended", {"gpis_kernel": "wendland", "gpis_noncontacts": True}),
    "wendland2.5": ("recommended", {"gpis_kernel": "wendland", "gpis_noncontacts": True,
                                    "gpis_support": 2.5}),
    "wendland6": ("recommended", {"gpis_kernel": "wendland", "gpis_noncontacts": True,
                                  "gpis_support": 6.0}),
    "noncontacts": ("recommended", {"gpis_noncontacts": True}),
    "no-carve": ("recommended", {"gpis_carve_radius": 0.0}),
    "carve1.0": ("recommended", {"gpis_carve_radius": 1.0}),
    "target-uncovered": ("recommended", {"target_uncovered": True}),
    "check-lines8": ("recommended", {"check_lines": 8}),
    "check-lines24": ("recommended", {"check_lines": 24}),
    "check-lines72": ("recommended", {"check_lines": 72}),
    # How far outside a target the approach starts (2.0 in the paper preset; 0.5 before).
    "approach0.5": ("recommended", {"approach_clearance": 0.5}),
    "approach1": ("recommended", {"approach_clearance": 1.0}),
    "approach4": ("recommended", {"approach_clearance": 4.0}),
    "lines-at-contacts": ("recommended", {"check_line_aim": "contact"}),
    # The full fit's scale Newton step every fit (the paper's; every 10 in the default) and
    # the variance at 1,500 vertices (the paper's; 400 in the default); docs/gpis.md.
    "newton-every-fit": ("recommended", {"gpis_refit_every": 1}),
    "variance1500": ("recommended", {"variance_points": 1500}),
    # The GPIS kept from step to step (issue 39, docs/gpis.md; off in the default): on, with
    # the scale refitted every 10 fits, every fit, or only every 30 fits.
    "gpis-incremental": ("recommended", {"gpis_incremental": True}),
    "gpis-refit1": ("recommended", {"gpis_incremental": True, "gpis_refit_every": 1}),
    "gpis-refit30": ("recommended", {"gpis_incremental": True, "gpis_refit_every": 30,
                                     "gpis_refit_score": 100.0}),
}


def config_params(name):
    """``SessionParams.to_dict()`` of a configuration (its changes are declared parameters,
    each put in its component by :func:`~tactile_viz.engine.params.with_changes`)."""
    base, changes = CONFIGS[name]
    return with_changes(session_preset(base), **changes).to_dict()


def describe(name):
    """The knobs a configuration changes, for the table."""
    base, changes = CONFIGS[name]
    if not changes:
        return f"preset {base}"
    return ", ".join(f"{key}={value}" for key, value in changes.items())


def pareto_front(times, errors):
    """Indices of the points no other point dominates (both coordinates minimised)."""
    times, errors = np.asarray(times, float), np.asarray(errors, float)
    front = []
    for i in range(len(times)):
        if not (np.isfinite(times[i]) and np.isfinite(errors[i])):
            continue
        dominated = ((times <= times[i]) & (errors <= errors[i])
                     & ((times < times[i]) | (errors < errors[i])))
        if not dominated.any():
            front.append(i)
    return front


def build_parser():
    parser = ArgumentParser(
        prog="python -m tactile_viz bench tradeoff",
        description="Sweep the presets and one-knob changes of the paper preset (SDF grid, "
                    "feature points, point-pair key resolution and neighbour look-up, GPIS "
                    "grid, eps); plot time per trial against pose error (known objects) and "
                    "reconstruction error (novel objects) with the Pareto front.")
    parser.add_argument("--objects", action=ExtendList, default=["mug_1", "elephant", "vase_2"],
                        type=bundled_objects,
                        metavar="NAME", help="bundled objects (default mug_1 elephant vase_2)")
    parser.add_argument("--seeds", type=count_int, default=2,
                        help="trials (seeds 0..N-1) per object")
    parser.add_argument("--configs", action=ExtendList, default=list(CONFIGS), metavar="NAME",
                        type=name_list(list(CONFIGS), "a configuration"),
                        help="configurations, comma lists work too; repeats add up "
                             f"(default all: {', '.join(CONFIGS)})")
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="cap every trial (default: the paper's caps)")
    parser.add_argument("--workers", type=workers_int, default=1, help="local worker processes")
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help="a Dask distributed scheduler to run the trials on")
    parser.add_argument("--out", default="bench_tradeoff", metavar="DIR", type=output_dir,
                        help="output folder")
    parser.add_argument("--resume", action="store_true",
                        help="reuse trial files already in DIR/trials")
    parser.add_argument("--reuse", metavar="RUN", action="append", default=[], type=existing_dir,
                        help="take trials from another run's RUN/trials (a bench paper run) "
                             "that ran the same object, seed, library and parameters, instead "
                             "of running them again (repeatable)")
    parser.add_argument("--report-only", action="store_true",
                        help="run nothing; rebuild the table and plot from DIR/trials")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def plan(objects, seeds, configs, max_steps):
    """One task per configuration, object and seed (tagged with the configuration)."""
    tasks = []
    for name in configs:
        for object_name in objects:
            for seed in range(seeds):
                task = make_task(object_name, "gpis-dhd", seed, CONFIGS[name][0],
                                 kind="tradeoff", params=config_params(name),
                                 max_steps=max_steps)
                task["tag"] = name
                tasks.append(task)
    # Cheap trials first: known objects before novel ones, the accurate preset last.
    sets = object_sets()
    return sorted(tasks, key=lambda t: (sets.get(t["object"]) == "novel", t["tag"] == "accurate"))


def run(args):
    out = Path(args.out)
    (out / "trials").mkdir(parents=True, exist_ok=True)
    configs = split_names(args.configs)
    unknown = [c for c in configs if c not in CONFIGS]
    if unknown:
        raise SystemExit(f"unknown configuration(s): {', '.join(unknown)}")
    tasks = plan(split_names(args.objects), args.seeds, configs, args.max_steps)
    todo = [t for t in tasks
            if not (args.resume and trial_path(out / "trials", task_key(t)).exists())]
    todo = reuse_trials(todo, args.reuse, out / "trials")
    pool = open_pool(args.workers, args.scheduler)
    try:
        for task, result in run_tasks(todo, pool, progress=not args.no_progress):
            write_trial(out / "trials", task_key(task), result)
    finally:
        pool.close()


# (row key, trials it is measured on, axis label): each is plotted against the seconds per
# trial of the same trials, every one smaller-is-better.
METRICS = (("pose_error", "known", "pose error at termination, known objects"),
           ("recon_error", "novel", "reconstruction error (TWD), novel objects"),
           ("truth_coverage", "all", "truth coverage at termination, all objects"),
           ("steps", "all", "termination step, all objects"))


def reuse_trials(tasks, runs, folder):
    """Copy into ``folder`` the trials of earlier ``runs`` that match a task (object, seed,
    strategy, the bundled known library, parameters, no step cap); returns the tasks left.

    A trial is the same computation whichever benchmark ran it, and its seconds were
    measured the same way (one trial per core). The code version is not matched (an engine
    change need not change a parameter): the report lists the versions of its trials."""
    from ..engine.shape.library import PriorLibrary

    if not runs:
        return tasks
    known = PriorLibrary.bundled("known").names
    def key(item, params):
        return (item["object"], item["seed"], item["strategy"], json.dumps(params, sort_keys=True))

    found = {}
    for run_folder in runs:
        for result in read_trials(Path(run_folder) / "trials"):
            if result.get("library") == known and result["task"].get("max_steps") is None:
                found.setdefault(key(result, result["params"]), result)
    left = []
    for task in tasks:
        match = key(task, rounded(task["params"]))
        if (task["library"] == "known" and not task["extra_priors"]
                and task["max_steps"] is None and match in found):
            result = dict(found[match], task={**found[match]["task"], **task, "reused": True})
            write_trial(folder, task_key(task), result)
        else:
            left.append(task)
    print(f"reused {len(tasks) - len(left)} of {len(tasks)} trials", file=sys.stderr)
    return left


def rows_from_results(results, sets):
    """One row per configuration: for each metric its mean, the half-width of its t-based
    95% interval and the mean seconds per trial of the same trials; the largest particle
    counts; and whether the configuration is on each metric's Pareto front (of the means)
    and on it within its interval (no configuration is as fast and better than the
    interval's lower end)."""
    by_config = {}
    for result in results:
        summary = aggregate.summarise_trial(result)
        by_config.setdefault(result["task"].get("tag"), []).append(summary)
    rows = []
    for name in [c for c in CONFIGS if c in by_config]:
        items = [s for s in by_config[name] if "error" not in s]
        subsets = {"all": items, "known": [s for s in items if sets.get(s["object"]) == "known"],
                   "novel": [s for s in items if sets.get(s["object"]) == "novel"]}
        row = {"config": name, "changes": describe(name), "trials": len(items),
               "failed": len(by_config[name]) - len(items),
               "correct": f"{sum(s['correct'] for s in subsets['known'])}/{len(subsets['known'])}",
               "pose_ok": f"{sum(s['pose_error'] < aggregate.THRESHOLD for s in subsets['known'])}"
                          f"/{len(subsets['known'])}",
               "judged_novel": f"{sum(s['novel'] for s in subsets['novel'])}"
                               f"/{len(subsets['novel'])}",
               "max_particles": max((s["max_particles"] for s in items), default=0),
               "mean_max_particles": aggregate.mean_std([s["max_particles"] for s in items])[0]}
        for subset, trials in subsets.items():
            seconds = [s["seconds"] for s in trials]
            row[f"seconds_{subset}"] = aggregate.mean_std(seconds)[0]
            row[f"seconds_{subset}_ci"] = aggregate.ci95(seconds)
        for key, subset, _ in METRICS:
            values = [s.get(key) for s in subsets[subset]]
            row[key], row[f"{key}_ci"] = aggregate.mean_std(values)[0], aggregate.ci95(values)
        rows.append(row)
    # A configuration run on fewer objects (e.g. only the known ones) is left out of the
    # fronts and plots over all objects: its means are over another set.
    full = max((r["trials"] for r in rows), default=0)
    for row in rows:
        row["all_objects"] = row["trials"] == full
    for key, subset, _ in METRICS:
        times = [r[f"seconds_{subset}"] if subset != "all" or r["all_objects"] else np.nan
                 for r in rows]
        errors = [r[key] for r in rows]
        for index in pareto_front(times, errors):
            rows[index][f"front_{key}"] = True
        lower = [r[key] - r[f"{key}_ci"] for r in rows]
        for index in front_within_interval(times, errors, lower):
            rows[index][f"near_front_{key}"] = True
    return rows


def front_within_interval(times, errors, lower):
    """Indices of the points that no other point beats beyond their interval: none is at
    least as fast with a mean error below the point's interval's lower end ``lower``."""
    times, errors, lower = (np.asarray(a, float) for a in (times, errors, lower))
    kept = []
    for i in range(len(times)):
        if not (np.isfinite(times[i]) and np.isfinite(errors[i])):
            continue
        others = np.arange(len(times)) != i
        if not (others & (times <= times[i]) & (errors < lower[i])).any():
            kept.append(i)
    return kept


def plot(rows, path):
    """Time against each metric (mean with its 95% interval), the Pareto front marked; the
    all-object panels leave out configurations run on fewer objects."""
    from .plots import _pyplot

    plt = _pyplot()
    figure, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    for axis, (key, subset, label) in zip(axes.ravel(), METRICS):
        points = [r for r in rows if np.isfinite(r[key]) and np.isfinite(r[f"seconds_{subset}"])
                  and (subset != "all" or r["all_objects"])]
        for row in points:
            preset = row["config"] in PRESETS
            axis.errorbar(row[f"seconds_{subset}"], row[key], yerr=row[f"{key}_ci"],
                          xerr=row[f"seconds_{subset}_ci"], fmt="o",
                          markersize=7 if preset else 4, capsize=2, linewidth=0.8,
                          color="tab:red" if preset else "tab:blue", zorder=3)
            axis.annotate(row["config"], (row[f"seconds_{subset}"], row[key]), fontsize=7,
                          xytext=(4, 3), textcoords="offset points")
        front = sorted((r[f"seconds_{subset}"], r[key]) for r in points if r.get(f"front_{key}"))
        if front:
            axis.step(*zip(*front), where="post", color="tab:green", linewidth=1,
                      label="Pareto front of the means")
            axis.legend(fontsize=7)
        axis.set_xlabel(f"seconds per trial, {subset} objects (mean, 95% interval)")
        axis.set_ylabel(label, fontsize=9)
    figure.suptitle("speed/accuracy trade (red: presets; bars: t-based 95% intervals)",
                    fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def _with_ci(row, key):
    value, half = row[key], row[f"{key}_ci"]
    if not np.isfinite(value):
        return "-"
    digits = 1 if abs(value) >= 10 else 3
    return f"{value:.{digits}f} ± {half:.{digits}f}"


def report(folder, command=None):
    folder = Path(folder)
    results = read_trials(folder / "trials")
    rows = rows_from_results(results, object_sets())
    plot(rows, folder / "tradeoff.png")
    header = ["configuration", "changes", "trials", "s/trial known", "pose error (known)",
              "correct class", "pose < 0.6", "s/trial novel", "recon error (novel)",
              "judged novel", "truth coverage (all)", "s/trial", "termination step",
              "largest particle count", "fronts"]
    fronts = lambda r: ", ".join(  # noqa: E731
        name + ("" if r.get(f"front_{key}") else " (within interval)")
        for key, name in (("pose_error", "pose"), ("recon_error", "recon"),
                          ("truth_coverage", "coverage"), ("steps", "steps"))
        if r.get(f"near_front_{key}")) or "none"
    table = aggregate.markdown_table(header, [
        [r["config"], r["changes"], r["trials"], _with_ci(r, "seconds_known"),
         _with_ci(r, "pose_error"), r["correct"], r["pose_ok"], _with_ci(r, "seconds_novel"),
         _with_ci(r, "recon_error"), r["judged_novel"], _with_ci(r, "truth_coverage"),
         _with_ci(r, "seconds_all"), _with_ci(r, "steps"), r["max_particles"], fronts(r)]
        for r in rows])
    lines = [f"# bench tradeoff: {folder}", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    objects = sorted({r["object"] for r in results})
    seeds = sorted({r["seed"] for r in results})
    versions = {}
    for result in results:
        label = result.get("code_version", "unknown") + (
            " (reused)" if result["task"].get("reused") else "")
        versions[label] = versions.get(label, 0) + 1
    lines += [f"Machine: {machine_description()}", "",
              "Code version(s) of the trials (number of trials): "
              + ", ".join(f"{v} ({n})" for v, n in sorted(versions.items())), "",
              f"Objects: {', '.join(objects)}; seeds {', '.join(map(str, seeds))}; GPIS-DHD. "
              "Means ± the half-width of a t-based 95% interval over the trials. A "
              "configuration is on a front when no other is at least as fast and at least "
              "as good (and better in one); on it within its interval when no other is at "
              "least as fast with a mean below the lower end of its interval.", "", table, ""]
    for row in rows:
        if row["config"] in PRESETS:
            lines.append(f"- preset {row['config']}: {fronts(row)}")
    lines += ["", "![tradeoff](tradeoff.png)"]
    write_atomic(folder / "tradeoff.md", ("\n".join(lines) + "\n").encode())
    write_json(folder / "tradeoff.json", rows)
    return folder / "tradeoff.md"


def main(argv=None):
    args = build_parser().parse_args(argv)
    start = time.perf_counter()
    if args.report_only:
        require_trials(args.out)
    else:
        run(args)
    command = "python -m tactile_viz bench tradeoff " + " ".join(argv or [])
    if args.report_only:
        command = recorded_command(Path(args.out) / "tradeoff.md") or command
    path = report(args.out, command)
    print(f"wrote {path} ({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    return 0
