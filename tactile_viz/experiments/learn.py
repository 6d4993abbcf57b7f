"""Benchmark: novel objects at real sizes, learned, and met again (leave one out).

``python -m tactile_viz bench learn [--objects NAME ...] [--libraries few many]
[--noise 0:0 0.002:2] [--seeds 1] [--first-seed 0] [--set NAME=VALUE ...] [--max-steps N]
[--known] [--workers 2] [--out DIR] [--no-progress]``

The objects are the project's own at real sizes in metres: the bundled known objects at
:data:`~tactile_viz.assetgen.catalog.SIZES_M` (12 to 40 cm) and the hard objects of
:mod:`~tactile_viz.assetgen.hard_objects` (a 2 cm block to a 33 cm plank, in families of
look-alikes: two screwdrivers, two balls, two mugs, two nested cups, the utensils). Each
object on test is left out of its library and explored with the ``recommended`` preset
until the session stops (or ``--max-steps``); its reconstruction is learned as a prior, and
the object is met again at another pose (seed + 1000) with that prior added, with the
``recognise`` preset. Two libraries:

- ``few``: three priors unlike the object (the first three of :data:`FEW` outside its
  family): what a lab with a handful of scans has;
- ``many``: every other object, look-alikes of its family included.

Per trial: judged novel at the end, the reconstruction error (two-way Hausdorff distance)
as a share of the object's longest side, the paper's on samples and from samples to the
other surface (without the samples' floor: 5-10% of a compact object's size), the learned
shape's own error (how far a touch may miss it, which the decision grants it met again)
as a share of the size, touches,
whether the session stopped by itself, seconds; met again: whether the learned prior was
the MAP at the decision, the touch of the decision, the pose error there as a share of the
size, seconds. With ``--known``, each object is also explored as a known one (its own mesh
added to the library, the same seed, preset and sensor) to time the novel session against:
touches, seconds and their ratio. Writes ``learn.md`` (tables) and ``learn.json`` (every
trial's summary) to ``--out`` and prints the tables.
"""

import argparse
import json
from pathlib import Path

import numpy as np

from ..assetgen.catalog import SIZES_M
from ..assetgen.hard_objects import HARD_SIZES_M, hard_meshes
from ..cli import (
    ArgumentParser,
    ExtendList,
    add_set_argument,
    count_int,
    nonnegative_int,
    output_dir,
    positive_int,
    with_settings,
    workers_int,
)
from ..engine.presets import session_preset
from .decide import _median, noise_level, write_tables
from .runner import make_task, open_pool, run_tasks

OBJECTS = ("block", "cup", "ball_bumpy", "mug_1", "elephant", "screwdriver_cross", "fork",
           "bottle_1", "sofa_1", "guitar_1")
FEW = ("mug_1", "screwdriver_flat", "knife", "elephant", "vase_1")
FAMILIES = ({"screwdriver_flat", "screwdriver_cross"}, {"ball_smooth", "ball_bumpy"},
            {"mug_1", "mug_1_large"}, {"cup", "cup_nested"},
            {"knife", "fork", "spatula", "pencil"}, {"block", "plank"})
DEFAULT_NOISE = ((0.0, 0.0), (0.002, 2.0))
AGAIN_SEED = 1000  # the met-again trial's seed offset: another pose than the one learned


def family(name):
    """The names of ``name``'s look-alikes, itself included."""
    return next((f for f in FAMILIES if name in f), {name})


def sizes():
    """Every object of the pool and its longest side, metres."""
    return {**SIZES_M, **HARD_SIZES_M}


def library_names(name, which):
    """The priors of library ``which`` (``few`` or ``many``) for the object ``name``."""
    if which == "few":
        return [n for n in FEW if n not in family(name)][:3]
    return [n for n in sizes() if n != name]


def _prior(name, files):
    size = sizes()[name]
    if name in files:
        return {"name": name, "file": str(files[name]), "longest_side": size, "learned": False}
    return {"name": name, "bundled": name, "longest_side": size}


def _object_task(name, files, **kwargs):
    return make_task(name, library="none", object_file=files.get(name),
                     longest_side=sizes()[name] if name in files else None,
                     sizes={name: sizes()[name]} if name not in files else None, **kwargs)


def phase_params(preset, settings):
    """A phase's parameters (a dict) with ``--set``'s changes, or None without any."""
    return with_settings(session_preset(preset), settings).to_dict() if settings else None


def learn_tasks(objects, libraries, noises, seeds, first_seed, files, max_steps, settings=(),
                known=False):
    """The leave-one-out trials that learn (their met-again trials follow each one), with
    ``settings`` (``--set`` pairs) changed in both phases' presets; with ``known``, each
    followed by the same trial with the object in its library (:func:`known_task`)."""
    out = []
    for (position, degrees), which, name in (
            (n, w, o) for n in noises for w in libraries for o in objects):
        for seed in range(first_seed, first_seed + seeds):
            task = _object_task(
                name, files, seed=seed, preset="recommended", kind="learn",
                extra_priors=[_prior(p, files) for p in library_names(name, which)],
                max_steps=max_steps, learn_as=f"{name}_learned",
                params=phase_params("recommended", settings),
                sensor={"position_noise": position, "normal_noise_deg": degrees})
            task["tag"], task["settings"] = which, list(settings or ())
            out.append(task)
            if known:
                out.append(known_task(task, _prior(name, files)))
    return out


def known_task(task, prior):
    """The learning ``task`` with the object's own ``prior`` added to its library: the same
    object, seed, preset and sensor, explored as a known object (what the novel session's
    time is measured against)."""
    return dict(task, kind="known", learn_as=None,
                extra_priors=task["extra_priors"] + [prior])


def again_task(task, result, max_steps):
    """The trial that meets the learned object again, or None (nothing learned)."""
    from ..engine.shape.objects import OWN_ERRORS

    learned = result.get("learned")
    if "error" in result or not learned or "vertices" not in learned:
        return None
    again = dict(task, kind="again", seed=task["seed"] + AGAIN_SEED, preset="recognise",
                 learn_as=None, max_steps=max_steps,
                 params=phase_params("recognise", task.get("settings")),
                 extra_priors=task["extra_priors"] + [
                     {"name": learned["name"], "vertices": learned["vertices"],
                      "faces": learned["faces"], "learned": True,
                      **{name: learned[name] for name in OWN_ERRORS if name in learned}}])
    return again


def learn_summary(result):
    """What the tables need of a trial that learns."""
    steps, size = result["steps"], result["object_size"]
    last = steps[-1]
    recon, surface = last.get("recon_error"), last.get("recon_surface_error")
    params, cap = result["params"], result["task"].get("max_steps")
    cap = cap or (params["max_steps_novel"] if last["novel"] else params["max_steps_known"])
    return {"object": result["object"], "library": result["task"]["tag"], "seed": result["seed"],
            "noise": [result["sensor"]["position_noise"], result["sensor"]["normal_noise_deg"]],
            "size": size, "judged_novel": bool(last["novel"]),
            "recon_share": None if recon is None or not last["novel"] else recon / size,
            "surface_share": None if surface is None or not last["novel"] else surface / size,
            "own_share": _own_share(result.get("learned"), size),
            "touches": len(steps),
            "stopped": result["terminated_at"] is not None and len(steps) < cap,
            "seconds": result["seconds"], "slowest_touch": _slowest(steps),
            "median_touch": _median_touch(steps),
            "learned": "vertices" in (result.get("learned") or {})}


def _own_share(learned, size):
    """A learned shape's own error (``shape_error``: how far a touch may miss it, which
    the decision grants it met again) as a share of the size; None when nothing was
    learned."""
    if not isinstance(learned, dict) or learned.get("shape_error") is None:
        return None
    return learned["shape_error"] / size


def again_summary(result):
    """What the tables need of a trial that meets a learned object again."""
    steps, size = result["steps"], result["object_size"]
    learned = f"{result['object']}_learned"
    decided = next((s for s in steps if s.get("decided")), None)
    at = decided or steps[-1]
    return {"map_learned": at["map_class"] == learned,
            "decided_at": None if decided is None else decided["t"],
            "decided_class": None if decided is None else decided["map_class"],
            "decided_learned": bool(decided is not None and decided["map_class"] == learned),
            "pose_share": None if at["pose_error"] is None else at["pose_error"] / size,
            "again_touches": len(steps), "again_seconds": result["seconds"],
            "again_slowest_touch": _slowest(steps)}


def known_summary(result):
    """What the tables need of the trial that explores the object as a known one."""
    steps = result["steps"]
    last, cap = steps[-1], result["task"].get("max_steps") or result["params"]["max_steps_known"]
    return {"known_right": last["map_class"] == result["object"] and not last["novel"],
            "known_touches": len(steps),
            "known_stopped": result["terminated_at"] is not None and len(steps) < cap,
            "known_seconds": result["seconds"], "known_slowest_touch": _slowest(steps),
            "known_median_touch": _median_touch(steps)}


def _ratio(row, novel, known):
    """``row[novel] / row[known]`` (None without both)."""
    if row.get(known) is None or row.get(novel) is None:
        return None
    return row[novel] / max(row[known], 1e-9)


def _median_touch(steps):
    """The median step of a trial, seconds (None without step timings)."""
    return _median([s.get("step_seconds") for s in steps])


def _slowest(steps):
    """The longest step of a trial, seconds (None without step timings)."""
    return _largest(s.get("step_seconds") for s in steps)


def _mean(values):
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _largest(values):
    return max((v for v in values if v is not None), default=None)


def _fmt(value, spec=".1f", scale=1.0):
    return "-" if value is None else format(value * scale, spec)


def _mean_max(shares):
    """``mean (max)`` of the shares given, in percent (``-`` for none)."""
    present = [s for s in shares if s is not None]
    return (f"{_fmt(_mean(present), scale=100)} "
            f"({_fmt(max(present, default=None), scale=100)})")


def _pose_within(row):
    """Whether a met-again pose error is within the reconstruction error plus 10% of the
    size (what a learned shape can be posed to)."""
    return (row.get("pose_share") is not None and row.get("recon_share") is not None
            and row["pose_share"] <= row["recon_share"] + 0.10)


def markdown(rows):
    """A table per library and noise level, then one row per trial."""
    lines = ["| library | noise (m, deg) | judged novel | recon. error, mean (max) % of "
             "size | to surface, mean (max) % | stopped by itself | learned, MAP met again | "
             "decided met again | median touches to it | pose error at it, mean % of size | "
             "pose within recon. + 10% | median s (learn, again) | slowest touch s (learn, "
             "again) |", "|" + "---|" * 13]
    for which in sorted({r["library"] for r in rows}):
        for noise in sorted({tuple(r["noise"]) for r in rows}):
            mine = [r for r in rows if r["library"] == which and tuple(r["noise"]) == noise]
            n = len(mine)
            again = [r for r in mine if "decided_at" in r]
            right = [r["decided_at"] for r in again if r["decided_learned"]]
            lines.append(
                f"| {which} | {noise[0]:g}, {noise[1]:g} | "
                f"{sum(r['judged_novel'] for r in mine)}/{n} | "
                f"{_mean_max([r['recon_share'] for r in mine])} | "
                f"{_mean_max([r.get('surface_share') for r in mine])} | "
                f"{sum(r['stopped'] for r in mine)}/{n} | "
                f"{sum(r['map_learned'] for r in again)}/{len(again)} | "
                f"{sum(r['decided_learned'] for r in again)}/{len(again)} | "
                f"{_fmt(_median(right), '.0f')} | "
                f"{_fmt(_mean([r['pose_share'] for r in again]), scale=100)} | "
                f"{sum(_pose_within(r) for r in again)}/{len(again)} | "
                f"{_fmt(_median([r['seconds'] for r in mine]), '.0f')}, "
                f"{_fmt(_median([r['again_seconds'] for r in again]), '.0f')} | "
                f"{_fmt(_largest([r.get('slowest_touch') for r in mine]), '.2f')}, "
                f"{_fmt(_largest([r.get('again_slowest_touch') for r in again]), '.2f')} |")
    lines += ["", "| object | size (cm) | library | noise | novel | recon. % | to surface % | "
              "own error % | touches | stopped | MAP again | decided at | pose % | s | "
              "slowest touch s |", "|" + "---|" * 15]
    for r in rows:
        lines.append(
            f"| {r['object']} | {100 * r['size']:.0f} | {r['library']} | "
            f"{r['noise'][0]:g}, {r['noise'][1]:g} | {'yes' if r['judged_novel'] else 'no'} | "
            f"{_fmt(r['recon_share'], scale=100)} | {_fmt(r.get('surface_share'), scale=100)} | "
            f"{_fmt(r.get('own_share'), scale=100)} | {r['touches']} | "
            f"{'yes' if r['stopped'] else 'cap'} | "
            f"{'-' if 'map_learned' not in r else 'yes' if r['map_learned'] else 'no'} | "
            f"{_decided(r)} | {_fmt(r.get('pose_share'), scale=100)} | "
            f"{_fmt(r.get('seconds'), '.0f')} | {_fmt(r.get('slowest_touch'), '.2f')} |")
    return "\n".join(lines + _known_lines(rows)) + "\n"


def _decided(row):
    """The touch a met-again trial was decided at, and the class when it is not the
    learned one (a wrong decision is no decision of the learned object)."""
    at = _fmt(row.get("decided_at"), ".0f")
    wrong = row.get("decided_at") is not None and not row.get("decided_learned")
    return f"{at}, as {row.get('decided_class')}" if wrong else at


def _known_lines(rows):
    """The novel sessions against the same objects explored as known ones (``--known``)."""
    rows = [r for r in rows if "known_seconds" in r]
    if not rows:
        return []
    lines = ["", "| object | library | noise | known: right, touches, stopped, s, median "
             "touch ms | novel: touches, s, median touch ms | novel / known: session, "
             "median touch |", "|" + "---|" * 6]
    for r in rows:
        lines.append(
            f"| {r['object']} | {r['library']} | {r['noise'][0]:g}, {r['noise'][1]:g} | "
            f"{'yes' if r['known_right'] else 'no'}, {r['known_touches']}, "
            f"{'yes' if r['known_stopped'] else 'cap'}, {_fmt(r['known_seconds'])}, "
            f"{_fmt(r.get('known_median_touch'), '.0f', 1000)} | "
            f"{r.get('touches', '-')}, {_fmt(r.get('seconds'))}, "
            f"{_fmt(r.get('median_touch'), '.0f', 1000)} | "
            f"{_fmt(_ratio(r, 'seconds', 'known_seconds'), '.2f')}, "
            f"{_fmt(_ratio(r, 'median_touch', 'known_median_touch'), '.2f')} |")
    for what, novel, known in (("session", "seconds", "known_seconds"),
                               ("median touch", "median_touch", "known_median_touch")):
        ratios = [x for x in (_ratio(r, novel, known) for r in rows) if x is not None]
        if ratios:
            lines += ["", f"Novel / known {what}: median {np.median(ratios):.2f}, largest "
                      f"{max(ratios):.2f} ({len(ratios)} trial{'s' * (len(ratios) != 1)})."]
    return lines


def run(tasks, workers, max_steps, progress=True):
    """Run the learning trials and their met-again trials; returns the summary rows and the
    failed trials' tracebacks."""
    rows, failed = {}, []

    def follow_up(task, result):
        again = again_task(task, result, max_steps) if task["kind"] == "learn" else None
        return [] if again is None else [again]

    pool = open_pool(workers)
    try:
        for task, result in run_tasks(tasks, pool, follow_up, progress, "learn"):
            if "error" in result:
                failed.append(result)
                continue
            key = (task["object"], task["tag"], task["seed"] - (
                AGAIN_SEED if task["kind"] == "again" else 0), json.dumps(result["sensor"]))
            row = rows.setdefault(key, {})
            summary = {"learn": learn_summary, "again": again_summary,
                       "known": known_summary}[task["kind"]]
            row.update(summary(result))
    finally:
        pool.close()
    return [row for row in rows.values() if "object" in row], failed


def main(argv=None):
    parser = ArgumentParser(prog="python -m tactile_viz bench learn", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", action=ExtendList, default=None, metavar="NAME",
                        choices=sorted(sizes()), help="objects to leave out in turn "
                        f"(default: {' '.join(OBJECTS)})")
    parser.add_argument("--libraries", action=ExtendList, default=None,
                        choices=["few", "many"], help="libraries (default: few many)")
    parser.add_argument("--noise", type=noise_level, action=ExtendList, default=None,
                        metavar="M:DEG", help="sensor noise levels: position std in metres, "
                        "normal std in degrees (default 0:0 0.002:2)")
    parser.add_argument("--seeds", type=count_int, default=1, help="seeds per object")
    add_set_argument(parser)
    parser.add_argument("--first-seed", type=nonnegative_int, default=0,
                        help="the first seed (seeds run from it up)")
    parser.add_argument("--max-steps", type=positive_int, default=None, metavar="N",
                        help="cap every trial at N touches (default: the presets' caps)")
    parser.add_argument("--known", action="store_true", help="also explore each object as a "
                        "known one (its mesh in the library, the same seed) and report the novel "
                        "session's time against it")
    parser.add_argument("--workers", type=workers_int, default=2, help="trials in parallel")
    parser.add_argument("--out", type=output_dir, default="results/learn",
                        help="folder for learn.md and learn.json")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    files = hard_meshes(out / "objects")
    tasks = learn_tasks(args.objects or list(OBJECTS), args.libraries or ["few", "many"],
                        args.noise or DEFAULT_NOISE, args.seeds, args.first_seed, files,
                        args.max_steps, args.set, args.known)
    rows, failed = run(tasks, args.workers, args.max_steps, not args.no_progress)
    for result in failed:
        print(f"trial {result['object']} s{result['seed']} failed:\n{result['error']}")
    rows.sort(key=lambda r: (r["library"], r["noise"], r["object"], r["seed"]))
    write_tables(out / "learn", rows, markdown(rows))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
