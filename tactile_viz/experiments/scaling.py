"""``python -m tactile_viz bench scaling``: how a step's cost grows.

1. Against the number of contacts: the parts of a step (filter update, GPIS fit, surface
   extraction with variance, Cholesky) are timed at growing contact counts with
   :func:`~tactile_viz.experiments.step_timing.measure`, and a power law ``t = c n^k`` is
   fitted to each part by least squares on log-log axes (``k`` is the growth exponent).
2. Against the number of priors: the same observation sequence (random touches of one
   object) is fed to particle filters whose libraries hold 10, 40, 100 and 400 priors (the
   bundled sets, and beyond 20 stretched variants of them, each a distinct shape); the
   filter updates are timed (the growth exponent from their mean) and the memory of the
   priors' arrays (with its exponent) and of the process recorded.
"""

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import (ArgumentParser, ExtendList, bundled_object, count_int, output_dir,
                   seed_int)
from ..engine.files import write_atomic
from ..engine.meshes import LONGEST_SIDE
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


def library_of_size(count, seed=0):
    """A prior library of ``count`` distinct models: the 20 bundled objects, then variants
    of them stretched by a random factor of 0.75-1.33 along each axis (and normalised
    again), so every prior has its own SDF, features and pair table as a learned shape would.
    """
    from ..engine.library import PriorLibrary
    from ..engine.objects import ObjectModel

    base = list(PriorLibrary.bundled("all"))
    rng = np.random.default_rng(seed)
    models = base[:count]
    for index in range(len(base), count):
        source = base[index % len(base)]
        stretch = np.exp(rng.uniform(np.log(0.75), np.log(4 / 3), size=3))
        models.append(ObjectModel.from_arrays(source.mesh.vertices * stretch, source.mesh.faces,
                                              f"{source.name}_variant{index // len(base)}",
                                              source.params, source.cache,
                                              longest_side=LONGEST_SIDE))
    return PriorLibrary(models)


def model_bytes(model, params):
    """Bytes of the arrays a prior holds for the filter: mesh, SDF grid, features and
    point-pair table (built if needed)."""
    sdf = model.sdf
    table = model.pair_table(params.distance_step, params.angle_step_deg)
    arrays = [model.mesh.vertices, model.mesh.faces, sdf.values, sdf.gradients,
              *model.features, table.keys, table.first, table.second]
    return int(sum(np.asarray(a).nbytes for a in arrays))


def resident_bytes():
    """This process's resident memory now (Linux ``/proc``; None elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE")


def time_priors(counts, object_name="mug_1", steps=30, seed=0, progress=False):
    """Per library size: median and mean filter-update seconds over ``steps`` random touches
    (after a first touch that builds the tables), the particle counts, the bytes of the
    priors' arrays and the process's resident memory with the filter alive."""
    from ..engine.objects import load_bundled
    from ..engine.params import FilterParams
    from ..engine.particle_filter import ParticleFilter
    from ..engine.session import make_truth
    from ..engine.simulator import ContactSimulator, random_touch

    truth = make_truth(load_bundled(object_name), rng=seed)
    rng = np.random.default_rng(seed)
    simulator = ContactSimulator(truth)
    observations = [simulator.probe(random_touch(truth, rng)) for _ in range(steps)]
    params = FilterParams()
    rows = []
    for count in counts:
        library = library_of_size(count, seed)
        models = list(library)
        if progress:
            from tqdm import tqdm

            models = tqdm(models, desc=f"priors for {count}", unit="prior", file=sys.stderr,
                          delay=2.0)
        prior_bytes = sum(model_bytes(model, params) for model in models)
        particle_filter = ParticleFilter(library, params, rng=seed)
        particle_filter.update(observations[0])
        times, counts_seen = [], [len(particle_filter.particles)]
        for observation in observations[1:]:
            start = time.perf_counter()
            particle_filter.update(observation)
            times.append(time.perf_counter() - start)
            counts_seen.append(len(particle_filter.particles))
        resident = resident_bytes()
        rows.append({"priors": count, "median": float(np.median(times)),
                     "mean": float(np.mean(times)), "particles": int(counts_seen[-1]),
                     "max_particles": int(max(counts_seen)),
                     "prior_megabytes": prior_bytes / 1e6,
                     "resident_megabytes": None if resident is None else resident / 1e6,
                     "map_class": particle_filter.state.map_class})
        del particle_filter, library, models
    return rows


def build_parser():
    parser = ArgumentParser(
        prog="python -m tactile_viz bench scaling",
        description="Time per step against the number of contacts (filter, GPIS fit, "
                    "surface, Cholesky; fitted growth exponent of each) and against the "
                    "number of priors (filter update and memory with 10/40/100/400 priors; "
                    "a first run builds and caches the variants' SDFs, about 2 s each).")
    parser.add_argument("--object", default="mug_2", type=bundled_object(),
                        help="object touched for the contact sweep (default mug_2, novel)")
    parser.add_argument("--sizes", type=count_int, action=ExtendList, default=[25, 50, 100, 200, 400],
                        help="contact counts (default 25 50 100 200 400)")
    parser.add_argument("--repeats", type=count_int, default=3, help="timings per part (median)")
    parser.add_argument("--priors", type=count_int, action=ExtendList, default=[10, 40, 100, 400],
                        help="library sizes (default 10 40 100 400; beyond the 20 bundled "
                             "objects, stretched variants of them)")
    parser.add_argument("--prior-object", default="mug_1", type=bundled_object(),
                        help="object touched for the prior sweep (default mug_1)")
    parser.add_argument("--prior-steps", type=count_int, default=30,
                        help="touches fed to each filter in the prior sweep (default 30)")
    parser.add_argument("--seed", type=seed_int, default=0)
    parser.add_argument("--out", default="bench_scaling", metavar="DIR", type=output_dir,
                        help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    return parser


def plot(contact_rows, exponents, prior_rows, path):
    from .plots import _pyplot

    plt = _pyplot()
    figure, axes = plt.subplots(1, 3, figsize=(15, 4))
    sizes = [size for size, _ in contact_rows]
    for part in exponents:
        axes[0].loglog(sizes, [timing[part] for _, timing in contact_rows], marker="o",
                       label=f"{part} (k={exponents[part]:.2f})")
    axes[0].set_xlabel("contacts")
    axes[0].set_ylabel("seconds (median)")
    axes[0].legend(fontsize=7)
    axes[0].set_title("time per part vs contacts", fontsize=10)
    priors = [r["priors"] for r in prior_rows]
    axes[1].loglog(priors, [r["mean"] for r in prior_rows], marker="o", label="mean")
    axes[1].loglog(priors, [r["median"] for r in prior_rows], marker="s", label="median")
    axes[1].legend(fontsize=7)
    axes[1].set_xlabel("priors in the library")
    axes[1].set_ylabel("filter update, seconds")
    axes[1].set_title("filter update vs number of priors", fontsize=10)
    axes[2].loglog(priors, [r["prior_megabytes"] for r in prior_rows], marker="o",
                   label="priors' arrays")
    if all(r["resident_megabytes"] for r in prior_rows):
        axes[2].loglog(priors, [r["resident_megabytes"] for r in prior_rows], marker="s",
                       label="process resident")
    axes[2].set_xlabel("priors in the library")
    axes[2].set_ylabel("megabytes")
    axes[2].legend(fontsize=7)
    axes[2].set_title("memory vs number of priors", fontsize=10)
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
    prior_rows = time_priors(sorted(args.priors), args.prior_object, args.prior_steps,
                             args.seed, progress=not args.no_progress)
    plot(contact_rows, exponents, prior_rows, out / "scaling.png")
    priors = [r["priors"] for r in prior_rows]
    # The mean, not the median: a large library's filter can collapse to a few particles
    # late in the sequence, and its cheap late updates would hide the costly early ones.
    prior_exponent = growth_exponent(priors, [r["mean"] for r in prior_rows])
    memory_exponent = growth_exponent(priors, [r["prior_megabytes"] for r in prior_rows])
    lines = ["# bench scaling", "", f"Command: `python -m tactile_viz bench scaling "
             f"{' '.join(argv or [])}`", "", f"Machine: {machine_description()}", "",
             f"## Time per part vs contacts ({args.object}, median of {args.repeats})", "",
             markdown_table(["contacts"] + parts,
                            [[s] + [t[p] for p in parts] for s, t in contact_rows]), "",
             markdown_table(["part", "growth exponent k (t ~ n^k)"],
                            [[p, exponents[p]] for p in parts]), "",
             f"## Filter update vs number of priors ({args.prior_object}, "
             f"{args.prior_steps} touches)", "",
             markdown_table(["priors", "median s", "mean s", "particles at the end",
                             "largest particle count", "MB of the priors' arrays",
                             "MB resident", "MAP class"],
                            [[r["priors"], r["median"], r["mean"], r["particles"],
                              r["max_particles"], r["prior_megabytes"],
                              r["resident_megabytes"], r["map_class"]] for r in prior_rows]), "",
             "Growth exponents against the number of priors (t ~ n^k): mean filter update "
             + (f"{prior_exponent:.2f}" if np.isfinite(prior_exponent)
                else "n/a (needs two library sizes)")
             + ", memory of the priors' arrays "
             + (f"{memory_exponent:.2f}" if np.isfinite(memory_exponent) else "n/a"), "",
             "![scaling](scaling.png)"]
    write_atomic(out / "scaling.md", ("\n".join(lines) + "\n").encode())
    write_atomic(out / "scaling.json", json.dumps(
        {"contacts": [{"contacts": s, **t} for s, t in contact_rows], "exponents": exponents,
         "priors": prior_rows, "prior_exponent": prior_exponent,
         "memory_exponent": memory_exponent}, indent=1).encode())
    print("\n".join(lines), file=sys.stdout)
    return 0
