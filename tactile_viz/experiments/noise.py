"""Benchmark: recognition rate and pose error on the known set against sensor noise.

``python -m tactile_viz bench noise [--levels 0:0 0.01:5 0.025:10 0.05:15] [--seeds 2]
[--contacts 40] [--configs paper matched] [--out DIR] [--no-progress]``

Each known object is placed at a random pose (one per object and seed) and touched
``--contacts`` times at random surface points (as in the particle-filter tests); the
simulator adds Gaussian noise of the given standard deviation to each reported position
(object units; the objects are 6 long) and tilts each reported normal by a Gaussian angle
(degrees). Two filter configurations are compared:

- ``paper``: the paper's parameters, whatever the noise;
- ``matched``: :func:`~tactile_viz.engine.presets.noise_matched`, which widens ``sigma_d``
  and ``sigma_n`` with the noise and turns on the neighbour-bin look-up of the point-pair
  keys once the noise reaches a quarter of a key bin.

A trial counts as recognised when the MAP class is the true object, and as a success when
also the pose error (two-way Hausdorff distance of the MAP shape at its pose to the truth)
is below 0.6. Writes ``noise.md`` (a Markdown table), ``noise.json`` (the same rows) and
``noise.png`` (the plot) to ``--out`` and prints the table.
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ..cli import ArgumentParser, ExtendList, bundled_object, count_int, finite_float, output_dir
from ..engine.belief.particle_filter import ParticleFilter
from ..engine.explore.simulator import ContactSimulator, GroundTruth, random_touch
from ..engine.io.files import write_atomic
from ..engine.presets import noise_matched, preset
from ..engine.shape.library import PriorLibrary
from ..engine.shape.metrics import ERROR_THRESHOLD as THRESHOLD, pose_error
from ..engine.transforms import random_pose

DEFAULT_LEVELS = ((0.0, 0.0), (0.01, 5.0), (0.025, 10.0), (0.05, 15.0))
CONFIGS = ("paper", "matched")


def filter_params(config, position_noise, normal_noise_deg):
    """The :class:`FilterParams` of a configuration at a noise level."""
    base = preset("paper")
    if config == "paper":
        return base
    if config == "matched":
        return noise_matched(base, position_noise, normal_noise_deg)
    raise ValueError(f"unknown configuration {config!r}; choose from {', '.join(CONFIGS)}")


def run_trial(library, name, params, noise, seed, contacts):
    """One trial: ``contacts`` random noisy touches of ``name`` at a seeded random pose.

    Returns
    -------
    dict
        ``recognised`` (bool), ``pose_error`` (float), ``particles`` (int), ``seconds``.
    """
    index = library.names.index(name)
    pose_rng = np.random.default_rng([seed, index, 7])
    truth = GroundTruth(library[name], *random_pose(pose_rng, max_translation=1.0))
    simulator = ContactSimulator(truth, position_noise=noise[0], normal_noise_deg=noise[1],
                                 rng=np.random.default_rng([seed, index, 2]))
    belief = ParticleFilter(library, params, rng=np.random.default_rng([seed, index, 3]))
    touches = np.random.default_rng([seed, index, 1])
    clock = time.perf_counter()
    for _ in range(contacts):
        state = belief.update(simulator.probe(random_touch(truth, touches)))
    seconds = time.perf_counter() - clock
    error = pose_error(library[state.map_class], state.map_rotation, state.map_translation,
                       truth)
    return {"recognised": state.map_class == name, "pose_error": float(error),
            "particles": int(state.n_particles), "seconds": seconds}


def measure(levels=DEFAULT_LEVELS, seeds=2, contacts=40, configs=CONFIGS, names=None,
            progress=True):
    """Run every (level, configuration, seed, object) trial.

    Returns
    -------
    list of dict
        One row per level and configuration: ``position_noise``, ``normal_noise_deg``,
        ``config``, ``trials``, ``recognised`` and ``success`` (fractions),
        ``median_pose_error``, ``mean_pose_error``, ``mean_particles``, ``seconds``
        (mean per trial).
    """
    library = PriorLibrary.bundled("known")
    names = list(names or library.names)
    jobs = [(level, config, seed, name) for level in levels for config in configs
            for seed in range(seeds) for name in names]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), desc="noise trials", unit="trial")
    results, done = {}, {}
    for level, config, seed, name in jobs:
        params = filter_params(config, *level)
        # Configurations that coincide at a level (no noise) share their trials.
        key = (params, level, seed, name)
        if key not in done:
            done[key] = run_trial(library, name, params, level, seed, contacts)
        outcome = done[key]
        results.setdefault((level, config), []).append(outcome)
        if bar is not None:
            bar.set_postfix_str(f"{level[0]:g}/{level[1]:g}deg {config} {name}")
            bar.update()
    if bar is not None:
        bar.close()
    rows = []
    for (level, config), outcomes in results.items():
        errors = np.array([o["pose_error"] for o in outcomes])
        recognised = np.array([o["recognised"] for o in outcomes])
        rows.append({
            "position_noise": level[0], "normal_noise_deg": level[1], "config": config,
            "trials": len(outcomes), "recognised": float(recognised.mean()),
            "success": float(np.mean(recognised & (errors < THRESHOLD))),
            "median_pose_error": float(np.median(errors)),
            "mean_pose_error": float(np.mean(errors)),
            "mean_particles": float(np.mean([o["particles"] for o in outcomes])),
            "seconds": float(np.mean([o["seconds"] for o in outcomes]))})
    return rows


def markdown_table(rows):
    """The rows as a Markdown table."""
    lines = ["| position noise | normal noise (deg) | filter | trials | recognised | "
             f"pose < {THRESHOLD} | median pose error | mean pose error | particles | s/trial |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(
            f"| {row['position_noise']:g} | {row['normal_noise_deg']:g} | {row['config']} | "
            f"{row['trials']} | {100 * row['recognised']:.0f}% | {100 * row['success']:.0f}% | "
            f"{row['median_pose_error']:.3f} | {row['mean_pose_error']:.3f} | "
            f"{row['mean_particles']:.0f} | {row['seconds']:.1f} |")
    return "\n".join(lines) + "\n"


def plot(rows, path):
    """Recognition rate and pose error against the noise level, one line per filter."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = sorted({(r["position_noise"], r["normal_noise_deg"]) for r in rows})
    labels = [f"{p:g} / {n:g}°" for p, n in levels]
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    configs = sorted({r["config"] for r in rows}, reverse=True)  # paper first
    for number, config in enumerate(configs):
        chosen = {(r["position_noise"], r["normal_noise_deg"]): r for r in rows
                  if r["config"] == config}
        # One colour per filter; offset a little so equal values stay visible.
        x = np.arange(len(levels)) + 0.04 * (number - (len(configs) - 1) / 2)
        style = dict(color=f"C{number}", marker="os^v"[number % 4])
        left.plot(x, [100 * chosen[level]["recognised"] for level in levels], **style,
                  label=f"{config}: class right")
        left.plot(x, [100 * chosen[level]["success"] for level in levels], **style,
                  linestyle="--", label=f"{config}: class right and pose < {THRESHOLD}")
        right.plot(x, [chosen[level]["median_pose_error"] for level in levels], **style,
                   label=f"{config}: median")
        right.plot(x, [chosen[level]["mean_pose_error"] for level in levels], **style,
                   linestyle="--", label=f"{config}: mean")
    for axis in (left, right):
        axis.set_xticks(np.arange(len(levels)), labels)
        axis.set_xlabel("sensor noise: position std / normal tilt std")
        axis.grid(alpha=0.3)
        axis.legend(fontsize=8)
    left.set_ylabel("trials (%)")
    left.set_ylim(50, 102)
    right.set_ylabel("pose error (TWD, units)")
    right.axhline(THRESHOLD, color="grey", linewidth=0.8)
    trials = rows[0]["trials"]
    figure.suptitle(f"Known set, random touches, {trials} trials per point")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def _level(text):
    try:
        position, normal = (finite_float(part) for part in text.split(":"))
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(
            f"a noise level is POSITION:DEGREES, two finite numbers, got {text!r}") from None
    if position < 0 or normal < 0:
        raise argparse.ArgumentTypeError(f"noise levels must not be negative, got {text!r}")
    return position, normal


def main(argv=None):
    parser = ArgumentParser(prog="python -m tactile_viz bench noise", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--levels", type=_level, action=ExtendList, default=list(DEFAULT_LEVELS),
                        metavar="POSITION:DEGREES")
    parser.add_argument("--seeds", type=count_int, default=2, help="random poses per object")
    parser.add_argument("--contacts", type=count_int, default=40, help="random touches per trial")
    parser.add_argument("--configs", action=ExtendList, choices=CONFIGS, default=list(CONFIGS))
    parser.add_argument("--objects", action=ExtendList, default=None,
                        type=bundled_object("known"),
                        help="known objects to test (default: all ten)")
    parser.add_argument("--out", type=output_dir, default=".",
                        help="folder for noise.md, noise.json and noise.png")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    out = Path(args.out)
    rows = measure(args.levels, args.seeds, args.contacts, args.configs, args.objects,
                   progress=not args.no_progress)
    table = markdown_table(rows)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "noise.md", table.encode())
    write_atomic(out / "noise.json", json.dumps(rows, indent=1).encode())
    plot(rows, out / "noise.png")
    print(table, end="")
    print(f"wrote noise.md, noise.json and noise.png to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
