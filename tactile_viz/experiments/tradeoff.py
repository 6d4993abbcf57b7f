"""``python -m tactile_viz bench tradeoff``: time per trial against pose and reconstruction
error over the presets and one-knob variations of the paper preset, with the Pareto front.

Every configuration runs the same objects and seeds (GPIS-DHD): known objects give the pose
error at termination, novel objects the reconstruction error (PF-MAP-GPIS, or the MAP
shape's when judged known). A configuration is on the Pareto front of a plot when no other
one is both at least as fast and at least as accurate (and strictly better in one).
"""

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..cli import ExtendList
from ..engine.session import SESSION_PRESETS, session_preset
from . import aggregate
from .paper import machine_description, object_sets, recorded_command, split_names
from .runner import make_task, open_pool, run_tasks, task_key
from .trial_files import read_trials, trial_path, write_trial

PRESETS = tuple(SESSION_PRESETS)
# name -> (base preset, session overrides, filter overrides): every preset, then one-knob
# changes of the paper preset.
CONFIGS = {
    **{name: (name, {}, {}) for name in PRESETS},
    "sdf32": ("paper", {}, {"sdf_resolution": 32}),
    "sdf96": ("paper", {}, {"sdf_resolution": 96}),
    "features100": ("paper", {}, {"n_features": 100}),
    "features300": ("paper", {}, {"n_features": 300}),
    "coarse-keys": ("paper", {}, {"distance_step": 0.2, "angle_step_deg": 24.0}),
    "neighbour-bins": ("paper", {}, {"neighbour_bins": 1}),
    "gpis24": ("paper", {"gpis_resolution": 24}, {}),
    "gpis48": ("paper", {"gpis_resolution": 48}, {}),
    "eps0.4": ("paper", {"eps": 0.4}, {}),
    "eps0.8": ("paper", {"eps": 0.8}, {}),
    # Particle budget: keep the heaviest new point-pair particles of a step (issue 18).
    "budget3000": ("paper", {}, {"max_new_particles": 3000}),
    "budget1500": ("paper", {}, {"max_new_particles": 1500}),
    # The GPIS ablation (novel objects): the thin-plate kernel (the paper preset's) at the
    # paper's R and explicitly, the compact Wendland kernel with free space at three
    # supports (c = 4 was the paper preset at ef75223), free space with the thin-plate
    # kernel, the prior's carve off or wider.
    "thin-plate1.0": ("paper", {"gpis_radius_factor": 1.0}, {}),
    "thin-plate1.2": ("paper", {"gpis_kernel": "thin-plate", "gpis_radius_factor": 1.2,
                                "gpis_noncontacts": False}, {}),
    "wendland4": ("paper", {"gpis_kernel": "wendland", "gpis_noncontacts": True}, {}),
    "wendland2.5": ("paper", {"gpis_kernel": "wendland", "gpis_noncontacts": True,
                              "gpis_support": 2.5}, {}),
    "wendland6": ("paper", {"gpis_kernel": "wendland", "gpis_noncontacts": True,
                            "gpis_support": 6.0}, {}),
    "noncontacts": ("paper", {"gpis_noncontacts": True}, {}),
    "no-carve": ("paper", {"gpis_carve_radius": 0.0}, {}),
    "carve1.0": ("paper", {"gpis_carve_radius": 1.0}, {}),
    "target-uncovered": ("paper", {"target_uncovered": True}, {}),
    "check-lines8": ("paper", {"check_lines": 8}, {}),
    "check-lines24": ("paper", {"check_lines": 24}, {}),
    # How far outside a target the approach starts (2.0 in the paper preset; 0.5 before).
    "approach0.5": ("paper", {"approach_clearance": 0.5}, {}),
    "approach1": ("paper", {"approach_clearance": 1.0}, {}),
    "approach4": ("paper", {"approach_clearance": 4.0}, {}),
    "lines-at-contacts": ("paper", {"check_line_aim": "contact"}, {}),
}


def config_params(name):
    """``SessionParams.to_dict()`` of a configuration."""
    base, session_changes, filter_changes = CONFIGS[name]
    params = session_preset(base)
    params = replace(params, filter=replace(params.filter, **filter_changes), **session_changes)
    return params.to_dict()


def describe(name):
    """The knobs a configuration changes, for the table."""
    base, session_changes, filter_changes = CONFIGS[name]
    changes = {**session_changes, **filter_changes}
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
    parser = argparse.ArgumentParser(
        prog="python -m tactile_viz bench tradeoff",
        description="Sweep the presets and one-knob changes of the paper preset (SDF grid, "
                    "feature points, point-pair key resolution and neighbour look-up, GPIS "
                    "grid, eps); plot time per trial against pose error (known objects) and "
                    "reconstruction error (novel objects) with the Pareto front.")
    parser.add_argument("--objects", action=ExtendList, default=["mug_1", "elephant", "vase_2"],
                        metavar="NAME", help="bundled objects (default mug_1 elephant vase_2)")
    parser.add_argument("--seeds", type=int, default=2, help="trials (seeds 0..N-1) per object")
    parser.add_argument("--configs", action=ExtendList, default=list(CONFIGS), metavar="NAME",
                        help="configurations, comma lists work too; repeats add up "
                             f"(default all: {', '.join(CONFIGS)})")
    parser.add_argument("--max-steps", type=int, default=None,
                        help="cap every trial (default: the paper's caps)")
    parser.add_argument("--workers", type=int, default=1, help="local worker processes")
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help="a Dask distributed scheduler to run the trials on")
    parser.add_argument("--out", default="bench_tradeoff", metavar="DIR", help="output folder")
    parser.add_argument("--resume", action="store_true",
                        help="reuse trial files already in DIR/trials")
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
    pool = open_pool(args.workers, args.scheduler)
    try:
        for task, result in run_tasks(todo, pool, progress=not args.no_progress):
            write_trial(out / "trials", task_key(task), result)
    finally:
        pool.close()


def rows_from_results(results, sets):
    """One row per configuration: seconds per trial, errors, steps (means over trials)."""
    by_config = {}
    for result in results:
        summary = aggregate.summarise_trial(result)
        by_config.setdefault(result["task"].get("tag"), []).append(summary)
    rows = []
    for name in [c for c in CONFIGS if c in by_config]:
        items = [s for s in by_config[name] if "error" not in s]
        known = [s for s in items if sets.get(s["object"]) == "known"]
        novel = [s for s in items if sets.get(s["object"]) == "novel"]
        rows.append({"config": name, "changes": describe(name), "trials": len(items),
                     "seconds": aggregate.mean_std([s["seconds"] for s in items])[0],
                     "seconds_known": aggregate.mean_std([s["seconds"] for s in known])[0],
                     "seconds_novel": aggregate.mean_std([s["seconds"] for s in novel])[0],
                     "pose_error": aggregate.mean_std([s["pose_error"] for s in known])[0],
                     "correct": f"{sum(s['correct'] for s in known)}/{len(known)}",
                     "recon_error": aggregate.mean_std([s["recon_error"] for s in novel])[0],
                     "coverage_novel": aggregate.mean_std(
                         [s.get("truth_coverage") for s in novel])[0],
                     "steps_novel": aggregate.mean_std([s["steps"] for s in novel])[0],
                     "steps": aggregate.mean_std([s["steps"] for s in items])[0],
                     "failed": len(by_config[name]) - len(items)})
    for key, seconds in (("pose_error", "seconds_known"), ("recon_error", "seconds_novel")):
        for index in pareto_front([r[seconds] for r in rows], [r[key] for r in rows]):
            rows[index][f"front_{key}"] = True
    return rows


def plot(rows, path):
    """Two scatter plots (time vs pose error, time vs reconstruction error), front marked."""
    from .plots import _pyplot

    plt = _pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for axis, key, seconds_key, label in (
            (axes[0], "pose_error", "seconds_known", "pose error, known objects (TWD)"),
            (axes[1], "recon_error", "seconds_novel", "reconstruction error, novel (TWD)")):
        points = [(r[seconds_key], r[key], r) for r in rows if np.isfinite(r[key])]
        for seconds, error, row in points:
            preset = row["config"] in PRESETS
            axis.scatter(seconds, error, s=60 if preset else 25,
                         color="tab:red" if preset else "tab:blue", zorder=3)
            axis.annotate(row["config"], (seconds, error), fontsize=7,
                          xytext=(3, 3), textcoords="offset points")
        front = sorted((s, e) for s, e, r in points if r.get(f"front_{key}"))
        if front:
            axis.step(*zip(*front), where="post", color="tab:green", linewidth=1,
                      label="Pareto front")
            axis.legend(fontsize=7)
        axis.set_xlabel(f"seconds per trial (mean, {seconds_key.split('_')[1]} objects)")
        axis.set_ylabel(label)
    figure.suptitle("speed/accuracy trade (red: presets)", fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def report(folder, command=None):
    folder = Path(folder)
    results = read_trials(folder / "trials")
    rows = rows_from_results(results, object_sets())
    plot(rows, folder / "tradeoff.png")
    header = ["configuration", "changes", "trials", "s/trial known", "pose error (known)",
              "correct class", "s/trial novel", "recon error (novel)",
              "truth coverage (novel)", "steps (novel)", "steps", "front: pose", "front: recon"]
    table = aggregate.markdown_table(header, [
        [r["config"], r["changes"], r["trials"], r["seconds_known"], r["pose_error"],
         r["correct"], r["seconds_novel"], r["recon_error"], r["coverage_novel"],
         r["steps_novel"], r["steps"], "yes" if r.get("front_pose_error") else "",
         "yes" if r.get("front_recon_error") else ""] for r in rows])
    lines = [f"# bench tradeoff: {folder}", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    objects = sorted({r["object"] for r in results})
    lines += [f"Machine: {machine_description()}", "",
              f"Objects: {', '.join(objects)}; GPIS-DHD; means over trials.", "", table, ""]
    for row in rows:
        if row["config"] in PRESETS:
            where = [name for key, name in (("front_pose_error", "pose"),
                                            ("front_recon_error", "reconstruction"))
                     if row.get(key)]
            lines.append(f"- preset {row['config']}: "
                         + (f"on the {' and '.join(where)} front" if where else "off the front"))
    lines += ["", "![tradeoff](tradeoff.png)"]
    (folder / "tradeoff.md").write_text("\n".join(lines) + "\n")
    (folder / "tradeoff.json").write_text(json.dumps(rows, indent=1))
    return folder / "tradeoff.md"


def main(argv=None):
    args = build_parser().parse_args(argv)
    start = time.perf_counter()
    if not args.report_only:
        run(args)
    command = "python -m tactile_viz bench tradeoff " + " ".join(argv or [])
    if args.report_only:
        command = recorded_command(Path(args.out) / "tradeoff.md") or command
    path = report(args.out, command)
    print(f"wrote {path} ({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    return 0
