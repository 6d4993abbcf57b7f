"""The prior sweep of ``bench scaling``: libraries of tens to thousands of priors.

A library of ``count`` priors holds the 20 bundled objects, then variants of them stretched
by a random factor of 0.75-1.33 along each axis and kept at that size: a stretched mug is
a different object once sizes are real, and a different class for the tally. Each library
size runs in its own process (so that its memory is its own): the prior bank is built (or
read from the disk cache, timed), then whole trials at the chosen preset touch objects
drawn from the library. A trial counts as right when its MAP class is the touched prior and
its pose error is under the threshold; a wrong class whose posed shape still lies within the
threshold of the truth (a variant too close to tell apart) is counted on its own.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

VARIANT_STRETCH = (0.75, 4 / 3)  # per-axis stretch factors of the variants


def library_of_size(count, seed=0):
    """A :class:`~tactile_viz.engine.shape.library.PriorLibrary` of ``count`` distinct priors:
    the bundled objects, then variants of them stretched along each axis (real size kept;
    a variant shares its source's faces array)."""
    import trimesh

    from ..engine.shape.library import PriorLibrary
    from ..engine.shape.objects import ObjectModel

    base = list(PriorLibrary.bundled("all"))
    rng = np.random.default_rng(seed)
    models = base[:count]
    for index in range(len(base), count):
        source = base[index % len(base)]
        stretch = np.exp(rng.uniform(*np.log(VARIANT_STRETCH), size=3))
        # The bundled meshes are centred on their boxes, so a stretched one still is.
        mesh = trimesh.Trimesh(source.mesh.vertices * stretch, source.mesh.faces,
                               process=False)
        models.append(ObjectModel(f"{source.name}_variant{index // len(base)}", mesh,
                                  source.params, source.cache,
                                  file_to_object=np.diag([*stretch, 1.0])))
    return PriorLibrary(models)


def growth_exponent(sizes, seconds):
    """Least-squares slope of ``log t`` against ``log n`` (NaN with fewer than 2 points)."""
    sizes, seconds = np.asarray(sizes, float), np.asarray(seconds, float)
    keep = (sizes > 0) & (seconds > 0)
    if keep.sum() < 2:
        return float("nan")
    slope, _ = np.polyfit(np.log(sizes[keep]), np.log(seconds[keep]), 1)
    return float(slope)


def _peak_megabytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3  # Linux: kB


def _resident_megabytes():
    """This process's resident memory now (Linux ``/proc``; None elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def _filter_params(library, preset):
    from ..engine.params import PAPER_SIZE, scaled_lengths
    from ..engine.presets import session_preset

    return scaled_lengths(session_preset(preset).filter, library.reference_size / PAPER_SIZE)


def _trial_row(result):
    from ..engine.shape.metrics import error_threshold

    steps = result["steps"]
    last = steps[-1]
    filter_seconds = [step["timings"].get("filter", 0.0) for step in steps]
    threshold = error_threshold(result["object_size"])
    right_class = last["map_class"] == result["object"]
    return {"object": result["object"], "seed": result["seed"], "map_class": last["map_class"],
            "right_class": right_class, "novel": last["novel"],
            "pose_error": last["pose_error"], "threshold": threshold,
            "right": bool(right_class and not last["novel"]
                          and last["pose_error"] < threshold),
            "indistinct": bool(not right_class and last["pose_error"] < threshold),
            "steps": len(steps), "terminated_at": result["terminated_at"],
            "filter_mean": float(np.mean(filter_seconds)),
            "filter_median": float(np.median(filter_seconds)),
            "first_update": filter_seconds[0],
            "max_particles": int(max(step["n_particles"] for step in steps)),
            "seconds": result["seconds"]}


def measure_size(count, trials=10, seed=0, preset="paper", max_steps=None, progress=False):
    """One library size: build and load times, memory, and ``trials`` whole trials.

    Returns
    -------
    dict
        ``priors``, ``models_seconds`` (making the models), ``built`` (priors whose grids
        the first build made from their meshes: a cold cache), ``build_workers`` (the child
        processes that built them; 0: built in this process), ``bank_seconds`` (first
        build: the bank ready, cold when ``built``), ``build_resident_megabytes`` and
        ``build_peak_megabytes`` (right after it),
        ``bank_cached_seconds`` (again, from the disk cache), ``bank_megabytes``,
        ``resident_megabytes`` (after the trials), ``peak_megabytes``, and ``trials``: one
        row per trial.
    """
    from ..commands.trial import run_trial
    from ..engine.belief import prior_bank
    from ..engine.belief.particle_filter import ParticleFilter
    from ..engine.belief.prior_build import CHILD_MIN, default_workers, missing
    from ..engine.shape.objects import ObjectModel

    bar = None
    if progress:
        from tqdm import tqdm

        bar = lambda items, desc: tqdm(items, desc=desc, file=sys.stderr, delay=2.0)  # noqa: E731
    start = time.perf_counter()
    library = library_of_size(count, seed)
    models_seconds = time.perf_counter() - start
    params = _filter_params(library, preset)
    models = ParticleFilter(library, params).models
    built = len(missing(models, params.distance_step, params.angle_step_deg))
    workers = default_workers(built) if built >= CHILD_MIN else 0
    start = time.perf_counter()
    prior_bank.bank_for(models, params.distance_step, params.angle_step_deg,
                        progress=(lambda m: bar(m, f"{count} priors")) if bar else None)
    bank_seconds = time.perf_counter() - start
    build_resident, build_peak = _resident_megabytes(), _peak_megabytes()
    del models
    prior_bank._RECENT.clear()
    start = time.perf_counter()
    bank = ParticleFilter(library, params).bank
    bank_cached_seconds = time.perf_counter() - start
    # Every prior once before any twice (a small library's objects at several seeds).
    order = np.random.default_rng([seed, count]).permutation(len(library))
    touched = [order[i % len(library)] for i in range(trials)]
    rows = []
    for i, index in enumerate(bar(touched, f"trials, {count} priors") if bar else touched):
        model = list(library)[index]
        # The truth on a copy of the prior: its exact distance (libigl trees, some 10 MB)
        # goes with the trial instead of staying on the library's model.
        truth = ObjectModel(model.name, model.mesh, model.params, model.cache,
                            model.learned, model.file_to_object)
        result = run_trial(truth, library, "gpis-dhd", seed=seed + i, preset=preset,
                           max_steps=max_steps)
        rows.append(_trial_row(result))
    return {"priors": count, "models_seconds": models_seconds, "built": built,
            "build_workers": workers, "bank_seconds": bank_seconds,
            "build_resident_megabytes": build_resident,
            "build_peak_megabytes": build_peak, "bank_cached_seconds": bank_cached_seconds,
            "bank_megabytes": bank.nbytes / 1e6,
            "resident_megabytes": _resident_megabytes(), "peak_megabytes": _peak_megabytes(),
            "trials": rows}


def measure_load(count, seed=0, preset="paper"):
    """The bank of ``count`` priors read from a warm disk cache (in a fresh process, after
    :func:`measure_size` filled it): ``warm_seconds``, ``warm_resident_megabytes`` and
    ``warm_peak_megabytes`` right after it."""
    from ..engine.belief.particle_filter import ParticleFilter

    library = library_of_size(count, seed)
    start = time.perf_counter()
    ParticleFilter(library, _filter_params(library, preset)).bank  # noqa: B018
    return {"warm_seconds": time.perf_counter() - start,
            "warm_resident_megabytes": _resident_megabytes(),
            "warm_peak_megabytes": _peak_megabytes()}


def sweep(counts, trials=10, seed=0, preset="paper", max_steps=None, progress=False,
          cold=False):
    """:func:`measure_size` for each library size, each in a fresh process, then
    :func:`measure_load` in another. With ``cold`` each size has an empty disk cache of its
    own (a temporary folder, removed after), so its first bank is built from the meshes."""
    results = []
    context = multiprocessing.get_context("spawn")
    for count in counts:
        with _own_cache(cold):
            with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool:
                result = pool.submit(measure_size, count, trials, seed, preset, max_steps,
                                     progress).result()
            with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool:
                result.update(pool.submit(measure_load, count, seed, preset).result())
        results.append(result)
    return results


@contextlib.contextmanager
def _own_cache(fresh):
    """With ``fresh``, ``$TACTILE_VIZ_CACHE`` names an empty temporary folder meanwhile (the
    processes started within read it); else nothing changes."""
    from ..engine.io.cache import ENV_VAR

    if not fresh:
        yield
        return
    before = os.environ.get(ENV_VAR)
    with tempfile.TemporaryDirectory(prefix="tactile_viz-cold-") as folder:
        os.environ[ENV_VAR] = folder
        try:
            yield
        finally:
            if before is None:
                os.environ.pop(ENV_VAR, None)
            else:
                os.environ[ENV_VAR] = before


def summary_row(result):
    """The figures of one library size from :func:`measure_size`'s result."""
    rows = result["trials"]
    mean = lambda key: float(np.mean([row[key] for row in rows])) if rows else float("nan")  # noqa: E731
    return {"priors": result["priors"], "trials": len(rows),
            "right": sum(row["right"] for row in rows),
            "right_class": sum(row["right_class"] for row in rows),
            "indistinct": sum(row["indistinct"] for row in rows),
            "pose_error_ratio": float(np.mean([row["pose_error"] / row["threshold"]
                                               for row in rows])) if rows else float("nan"),
            "filter_mean": mean("filter_mean"), "first_update": mean("first_update"),
            "max_particles": max((row["max_particles"] for row in rows), default=0),
            "steps": mean("steps"), "bank_megabytes": result["bank_megabytes"],
            "resident_megabytes": result["resident_megabytes"],
            "peak_megabytes": result["peak_megabytes"],
            "bank_cached_seconds": result["bank_cached_seconds"],
            "models_seconds": result["models_seconds"],
            **{key: result.get(key) for key in MEMORY_KEYS},
            "build_workers": result.get("build_workers")}


MEMORY_KEYS = ["built", "bank_seconds", "build_resident_megabytes", "build_peak_megabytes",
               "warm_seconds", "warm_resident_megabytes", "warm_peak_megabytes"]
START_KEYS = ["built", "build_workers", "bank_seconds", "built_seconds_each", "warm_seconds"]


def start_row(row):
    """Cold and warm start of one library size (a :func:`summary_row`): the priors built,
    by how many children, the first bank's seconds, per prior built, and the warm load's."""
    built = row.get("built") or 0
    return {**{key: row.get(key) for key in START_KEYS},
            "built_seconds_each": row["bank_seconds"] / built if built else None}


def projection(rows, target=10_000):
    """Memory and update time at ``target`` priors from a least-squares line through the
    measured memory and a power law through the mean update times."""
    priors = np.array([row["priors"] for row in rows], float)
    if len(priors) < 2:
        return None
    resident = np.array([row["resident_megabytes"] or np.nan for row in rows], float)
    per_prior, base = np.polyfit(priors, resident, 1)
    bank_per_prior, _ = np.polyfit(priors, [row["bank_megabytes"] for row in rows], 1)
    times = np.array([row["filter_mean"] for row in rows], float)
    exponent = growth_exponent(priors, times)
    update = float(times[-1] * (target / priors[-1]) ** exponent)
    return {"target": target, "resident_megabytes": float(base + per_prior * target),
            "megabytes_per_prior": float(per_prior), "bank_megabytes_per_prior":
            float(bank_per_prior), "update_exponent": exponent, "update_seconds": update}
