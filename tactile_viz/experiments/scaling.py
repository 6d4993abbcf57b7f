"""``python -m tactile_viz bench scaling``: how a step's cost grows.

1. Against the number of contacts: the parts of a step (filter update, GPIS fit, surface
   extraction with variance, Cholesky) are timed at growing contact counts with
   :func:`~tactile_viz.experiments.step_timing.measure`, and a power law ``t = c n^k`` is
   fitted to each part by least squares on log-log axes (``k`` is the growth exponent).
2. Against the number of priors: the same observation sequence (random touches of one
   object) is fed to particle filters whose libraries hold 10, 20 and 40 priors (the bundled
   sets, and beyond 20 renamed copies of them), and the median filter update is timed.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import ExtendList
from .aggregate import markdown_table
from .paper import machine_description


def growth_exponent(sizes, seconds):
    """Least-squares slope of ``log t`` against ``log n`` (NaN with fewer than 2 points)."""
    sizes, seconds = np.asarray(sizes, float), np.asarray(seconds, float)
    keep = (sizes > 0) & (seconds > 0)
    if keep.sum() < 2:
        return float("nan")
    slope, _ = np.polyfit(np.log(sizes[keep]), np.log(seconds[keep]), 1)
    return float(slope)


def library_of_size(count):
    """A prior library of ``count`` models: the bundled objects, then renamed copies."""
    from ..engine.library import PriorLibrary

    base = list(PriorLibrary.bundled("all"))
    models = [base[i % len(base)] if i < len(base) else
              base[i % len(base)].renamed(f"{base[i % len(base)].name}_copy{i // len(base)}")
              for i in range(count)]
    return PriorLibrary(models)


def time_priors(counts, object_name="mug_1", steps=30, seed=0):
    """Median and mean filter-update seconds over ``steps`` random touches per library size."""
    from ..engine.objects import load_bundled
    from ..engine.particle_filter import ParticleFilter
    from ..engine.session import make_truth
    from ..engine.simulator import ContactSimulator, random_touch

    truth = make_truth(load_bundled(object_name), rng=seed)
    rng = np.random.default_rng(seed)
    simulator = ContactSimulator(truth)
    observations = [simulator.probe(random_touch(truth, rng)) for _ in range(steps)]
    rows = []
    for count in counts:
        particle_filter = ParticleFilter(library_of_size(count), rng=seed)
        particle_filter.update(observations[0])  # builds the tables; not timed
        times = []
        for observation in observations[1:]:
            start = time.perf_counter()
            particle_filter.update(observation)
            times.append(time.perf_counter() - start)
        rows.append({"priors": count, "median": float(np.median(times)),
                     "mean": float(np.mean(times)),
                     "particles": int(particle_filter.state.n_particles)})
    return rows


def build_parser():
    parser = argparse.ArgumentParser(
        prog="python -m tactile_viz bench scaling",
        description="Time per step against the number of contacts (filter, GPIS fit, "
                    "surface, Cholesky; fitted growth exponent of each) and against the "
                    "number of priors (filter update with 10/20/40 priors).")
    parser.add_argument("--object", default="mug_2",
                        help="object touched for the contact sweep (default mug_2, novel)")
    parser.add_argument("--sizes", type=int, action=ExtendList, default=[25, 50, 100, 200, 400],
                        help="contact counts (default 25 50 100 200 400)")
    parser.add_argument("--repeats", type=int, default=3, help="timings per part (median)")
    parser.add_argument("--priors", type=int, action=ExtendList, default=[10, 20, 40],
                        help="library sizes (default 10 20 40)")
    parser.add_argument("--prior-object", default="mug_1",
                        help="object touched for the prior sweep (default mug_1)")
    parser.add_argument("--prior-steps", type=int, default=30,
                        help="touches fed to each filter in the prior sweep (default 30)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="bench_scaling", metavar="DIR", help="output folder")
    return parser


def plot(contact_rows, exponents, prior_rows, path):
    from .plots import _pyplot

    plt = _pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    sizes = [size for size, _ in contact_rows]
    for part in exponents:
        axes[0].loglog(sizes, [timing[part] for _, timing in contact_rows], marker="o",
                       label=f"{part} (k={exponents[part]:.2f})")
    axes[0].set_xlabel("contacts")
    axes[0].set_ylabel("seconds (median)")
    axes[0].legend(fontsize=7)
    axes[0].set_title("time per part vs contacts", fontsize=10)
    axes[1].plot([r["priors"] for r in prior_rows], [r["median"] for r in prior_rows],
                 marker="o")
    axes[1].set_xlabel("priors in the library")
    axes[1].set_ylabel("filter update, seconds (median)")
    axes[1].set_title("filter update vs number of priors", fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def main(argv=None):
    from .step_timing import measure

    args = build_parser().parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    contact_rows = measure(args.object, sorted(args.sizes), args.repeats, args.seed)
    parts = [p for p in contact_rows[0][1] if p in
             ("filter", "gpis fit", "surface", "cholesky full", "target")]
    exponents = {p: growth_exponent([s for s, _ in contact_rows],
                                    [t[p] for _, t in contact_rows]) for p in parts}
    prior_rows = time_priors(args.priors, args.prior_object, args.prior_steps, args.seed)
    plot(contact_rows, exponents, prior_rows, out / "scaling.png")
    prior_exponent = growth_exponent([r["priors"] for r in prior_rows],
                                     [r["median"] for r in prior_rows])
    lines = ["# bench scaling", "", f"Command: `python -m tactile_viz bench scaling "
             f"{' '.join(argv or [])}`", "", f"Machine: {machine_description()}", "",
             f"## Time per part vs contacts ({args.object}, median of {args.repeats})", "",
             markdown_table(["contacts"] + parts,
                            [[s] + [t[p] for p in parts] for s, t in contact_rows]), "",
             markdown_table(["part", "growth exponent k (t ~ n^k)"],
                            [[p, exponents[p]] for p in parts]), "",
             f"## Filter update vs number of priors ({args.prior_object}, "
             f"{args.prior_steps} touches)", "",
             markdown_table(["priors", "median s", "mean s", "particles at the end"],
                            [[r["priors"], r["median"], r["mean"], r["particles"]]
                             for r in prior_rows]), "",
             "Growth exponent against the number of priors: "
             + (f"{prior_exponent:.2f}" if np.isfinite(prior_exponent)
                else "n/a (needs two library sizes)"), "",
             "![scaling](scaling.png)"]
    (out / "scaling.md").write_text("\n".join(lines) + "\n")
    (out / "scaling.json").write_text(json.dumps(
        {"contacts": [{"contacts": s, **t} for s, t in contact_rows], "exponents": exponents,
         "priors": prior_rows, "prior_exponent": prior_exponent}, indent=1))
    print("\n".join(lines), file=sys.stdout)
    return 0
