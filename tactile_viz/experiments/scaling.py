"""``python -m tactile_viz bench scaling``: how a step's cost grows.

1. Against the number of contacts: the parts of a step (filter update, GPIS fit, surface
   extraction with variance, Cholesky) are timed at growing contact counts with
   :func:`~tactile_viz.experiments.step_timing.measure`, and a power law ``t = c n^k`` is
   fitted to each part by least squares on log-log axes (``k`` is the growth exponent).
2. Against the number of priors (:mod:`.prior_scaling`): libraries of 10 to thousands of
   priors (the bundled objects, then stretched variants of them at their real size), each
   in its own process: the prior bank's load time and memory, the process's memory, and
   whole trials on objects drawn from the library (class and pose, filter update times),
   with a projection to 10,000 priors.
"""

import json
import sys
from pathlib import Path

import numpy as np

from ..cli import (
    ArgumentParser,
    ExtendList,
    add_preset_argument,
    bundled_object,
    count_int,
    output_dir,
    seed_int,
)
from ..engine.io.files import write_atomic
from . import prior_scaling
from .aggregate import markdown_table
from .paper import machine_description
from .prior_scaling import growth_exponent


def build_parser():
    parser = ArgumentParser(
        prog="python -m tactile_viz bench scaling",
        description="Time per step against the number of contacts (filter, GPIS fit, "
                    "surface, Cholesky; fitted growth exponent of each) and against the "
                    "number of priors (prior bank memory and load time, filter update, "
                    "class and pose over whole trials; the first bank of a size is built "
                    "from the meshes where the disk cache lacks them, in child processes, "
                    "one a core; its time and memory are given cold and warm).")
    parser.add_argument("--object", default="mug_2", type=bundled_object(),
                        help="object touched for the contact sweep (default mug_2, novel)")
    parser.add_argument("--sizes", type=count_int, action=ExtendList,
                        default=[25, 50, 100, 200, 400],
                        help="contact counts (default 25 50 100 200 400)")
    parser.add_argument("--repeats", type=count_int, default=3, help="timings per part (median)")
    parser.add_argument("--priors", type=count_int, action=ExtendList, default=[10, 100, 1000],
                        help="library sizes (default 10 100 1000; beyond the 20 bundled "
                             "objects, stretched variants of them)")
    parser.add_argument("--prior-trials", type=count_int, default=10,
                        help="trials per library size, on objects drawn from it (default 10)")
    parser.add_argument("--prior-max-steps", type=count_int, default=None,
                        help="cap on the steps of those trials (default: the paper's 300)")
    parser.add_argument("--no-contacts", action="store_true",
                        help="skip the sweep against the number of contacts")
    parser.add_argument("--cold", action="store_true",
                        help="give each library size an empty disk cache of its own (a "
                             "temporary folder), so its first bank is always built cold")
    add_preset_argument(parser, default="paper")
    parser.add_argument("--seed", type=seed_int, default=0)
    parser.add_argument("--out", default="bench_scaling", metavar="DIR", type=output_dir,
                        help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    return parser


PRIOR_HEADER = ["priors", "trials", "right class and pose", "right class",
                "wrong but indistinct", "pose error / threshold", "mean filter update s",
                "first update s", "largest particle count", "steps", "bank MB", "resident MB",
                "peak MB", "bank load s (cached)"]
PRIOR_KEYS = ["priors", "trials", "right", "right_class", "indistinct", "pose_error_ratio",
              "filter_mean", "first_update", "max_particles", "steps", "bank_megabytes",
              "resident_megabytes", "peak_megabytes", "bank_cached_seconds"]

MEMORY_HEADER = ["priors", "built from meshes", "build s", "resident after the build MB",
                 "peak by then MB", "warm load s", "warm load resident MB",
                 "warm load peak MB"]
MEMORY_ROW = ["priors", *prior_scaling.MEMORY_KEYS]
START_HEADER = ["priors", "built from meshes", "build workers", "first bank s (cold if built)",
                "s a prior built", "warm load s"]
START_ROW = ["priors", *prior_scaling.START_KEYS]


def plot(contact_rows, exponents, prior_rows, path):
    from .plots import _pyplot

    plt = _pyplot()
    panels = (1 if contact_rows else 0) + (3 if prior_rows else 0)
    figure, axes = plt.subplots(1, max(panels, 1), figsize=(5 * max(panels, 1), 4),
                                squeeze=False)
    axes = list(axes[0])
    if contact_rows:
        axis = axes.pop(0)
        sizes = [size for size, _ in contact_rows]
        for part in exponents:
            axis.loglog(sizes, [timing[part] for _, timing in contact_rows], marker="o",
                        label=f"{part} (k={exponents[part]:.2f})")
        axis.set_xlabel("contacts")
        axis.set_ylabel("seconds (median)")
        axis.legend(fontsize=7)
        axis.set_title("time per part vs contacts", fontsize=10)
    if prior_rows:
        priors = [r["priors"] for r in prior_rows]
        axis = axes.pop(0)
        axis.loglog(priors, [r["filter_mean"] for r in prior_rows], marker="o",
                    label="mean filter update")
        axis.loglog(priors, [r["first_update"] for r in prior_rows], marker="s",
                    label="first update")
        axis.legend(fontsize=7)
        axis.set_xlabel("priors in the library")
        axis.set_ylabel("seconds")
        axis.set_title("filter update vs number of priors", fontsize=10)
        axis = axes.pop(0)
        axis.loglog(priors, [r["bank_megabytes"] for r in prior_rows], marker="o",
                    label="prior bank")
        if all(r["resident_megabytes"] for r in prior_rows):
            axis.loglog(priors, [r["resident_megabytes"] for r in prior_rows], marker="s",
                        label="process resident")
            axis.loglog(priors, [r["peak_megabytes"] for r in prior_rows], marker="^",
                        label="process peak")
        axis.set_xlabel("priors in the library")
        axis.set_ylabel("megabytes")
        axis.legend(fontsize=7)
        axis.set_title("memory vs number of priors", fontsize=10)
        axis = axes.pop(0)
        _plot_outcomes(axis, prior_rows)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def _plot_outcomes(axis, prior_rows):
    """Stacked bars: the share of trials right, wrong but indistinct, and wrong, per size."""
    labels = [f"{row['priors']:,}" for row in prior_rows]
    right = np.array([row["right"] / row["trials"] for row in prior_rows])
    indistinct = np.array([row["indistinct"] / row["trials"] for row in prior_rows])
    axis.bar(labels, right, color="tab:green", label="right class and pose")
    axis.bar(labels, indistinct, bottom=right, color="tab:orange",
             label="wrong but indistinct")
    axis.bar(labels, 1 - right - indistinct, bottom=right + indistinct, color="tab:red",
             label="wrong")
    axis.set_ylim(0, 1)
    axis.set_xlabel("priors in the library")
    axis.set_ylabel(f"share of trials ({prior_rows[0]['trials']} a size)")
    axis.legend(fontsize=7, loc="lower left")
    axis.set_title("outcome vs number of priors", fontsize=10)


def contact_section(args):
    from .step_timing import measure

    contact_rows = measure(args.object, sorted(args.sizes), args.repeats, args.seed)
    parts = [p for p in contact_rows[0][1] if p in
             ("filter", "gpis fit", "surface", "cholesky full", "target")]
    exponents = {p: growth_exponent([s for s, _ in contact_rows],
                                    [t[p] for _, t in contact_rows]) for p in parts}
    lines = [f"## Time per part vs contacts ({args.object}, median of {args.repeats})", "",
             markdown_table(["contacts"] + parts,
                            [[s] + [t[p] for p in parts] for s, t in contact_rows]), "",
             markdown_table(["part", "growth exponent k (t ~ n^k)"],
                            [[p, exponents[p]] for p in parts]), ""]
    return contact_rows, exponents, lines


def prior_section(args):
    results = prior_scaling.sweep(sorted(args.priors), args.prior_trials, args.seed,
                                  args.preset, args.prior_max_steps,
                                  progress=not args.no_progress, cold=args.cold)
    rows = [prior_scaling.summary_row(result) for result in results]
    lines = [f"## Against the number of priors ({args.preset} preset, {args.prior_trials} "
             "trials per size on objects drawn from the library)", "",
             markdown_table(PRIOR_HEADER, [[row[key] for key in PRIOR_KEYS] for row in rows]),
             "", "Right: the touched prior is the MAP class, judged known, with the pose "
             "error under 10% of its size. Wrong but indistinct: another prior whose posed "
             "shape lies within that threshold of the truth. Memory in MB (10^6 bytes).", ""]
    lines += [f"Cold and warm start{' (each size on an empty disk cache)' if args.cold else ''}"
              ": the first bank of the trials' process, built from the meshes where the "
              "disk cache lacked them (by child processes, 0: in the process) and then read, "
              "and the same bank read from the warm cache in a fresh process.", "",
              markdown_table(START_HEADER, [[{"priors": row["priors"],
                                              **prior_scaling.start_row(row)}[key]
                                             for key in START_ROW] for row in rows]), ""]
    lines += ["Memory right after building the prior bank: in the trials' process (from the "
              "meshes when the disk cache lacked their grids: \"built\" priors), and in a "
              "fresh process reading it from the warm cache.", "",
              markdown_table(MEMORY_HEADER, [[row[key] for key in MEMORY_ROW]
                                             for row in rows]), ""]
    projected = prior_scaling.projection(rows)
    if projected:
        lines += [f"Projected to {projected['target']:,} priors: "
                  f"{projected['resident_megabytes']:,.0f} MB resident "
                  f"({projected['megabytes_per_prior']:.2f} MB a prior, of which the bank "
                  f"{projected['bank_megabytes_per_prior']:.2f}), mean filter update "
                  f"{projected['update_seconds']:.3f} s (t ~ n^"
                  f"{projected['update_exponent']:.2f}).", ""]
    return results, rows, projected, lines


def main(argv=None):
    args = build_parser().parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# bench scaling", "", f"Command: `python -m tactile_viz bench scaling "
             f"{' '.join(argv or [])}`", "", f"Machine: {machine_description()}", ""]
    contact_rows, exponents = [], {}
    if not args.no_contacts:
        contact_rows, exponents, section = contact_section(args)
        lines += section
    results, prior_rows, projected, section = prior_section(args)
    lines += section + ["![scaling](scaling.png)"]
    plot(contact_rows, exponents, prior_rows, out / "scaling.png")
    write_atomic(out / "scaling.md", ("\n".join(lines) + "\n").encode())
    write_atomic(out / "scaling.json", json.dumps(
        {"contacts": [{"contacts": s, **t} for s, t in contact_rows], "exponents": exponents,
         "priors": prior_rows, "projection": projected}, indent=1).encode())
    write_atomic(out / "trials.json", json.dumps(results, indent=1).encode())
    print("\n".join(lines), file=sys.stdout)
    return 0
