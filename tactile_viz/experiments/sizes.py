"""Benchmark: the bundled objects at real sizes, mixed in one metric library, against the
same objects at the paper's scale (longest side 6).

``python -m tactile_viz bench sizes [--seeds 3] [--novel-seeds 1] [--objects ...]
[--workers 2] [--out DIR] [--no-progress]`` (``--objects`` takes a comma list)

Each object runs the same trials (object, seed, strategy, paper preset) twice: once at the
paper's scale with the paper's library, once with every object scaled to the plausible size
of :data:`SIZES_M` (5 to 40 cm, metres) and the library made of the known objects at their
sizes. Errors are compared relative to the object's size: the pose and reconstruction
errors (two-way Hausdorff distances) over 10% of the object's longest side (the paper's
0.6 on 6 units), so a relative error below 1 is a success in the paper's sense.

Writes ``sizes.json`` (one row per object and scale), ``sizes.md`` (the table) and
``trials.jsonl.gz`` (the trials' summaries) to ``--out`` and prints the table.
"""

import argparse
import gzip
import json
from pathlib import Path

import numpy as np

from ..assetgen.catalog import SIZES_M
from ..cli import ArgumentParser, count_int, name_list, nonnegative_int, output_dir, workers_int
from ..engine.io.files import write_atomic
from ..engine.shape.metrics import error_threshold
from ..engine.shape.objects import bundled_manifest, bundled_names
from .runner import make_task, run_all

SCALES = ("paper", "metric")


def tasks(objects, seeds, novel_seeds):
    """The trials: every object at both scales; known objects over ``seeds``, novel ones
    over ``novel_seeds``."""
    known = set(bundled_names("known"))
    out = []
    for name in objects:
        for seed in range(seeds if name in known else novel_seeds):
            for scale in SCALES:
                task = make_task(name, seed=seed, sizes=SIZES_M if scale == "metric" else None)
                task["tag"] = scale
                out.append(task)
    return out


def summary(result):
    """What the table needs of one trial result."""
    steps = result["steps"]
    last = steps[-1]
    size = result["object_size"]
    threshold = error_threshold(size)
    known = result["object"] in bundled_names("known")
    recon = last.get("recon_error")
    return {"object": result["object"], "seed": result["seed"],
            "scale": result["task"]["tag"], "size": size, "known_object": known,
            "map_class": last["map_class"], "right_class": last["map_class"] == result["object"],
            "novel": bool(last["novel"]), "terminated_at": result["terminated_at"],
            "steps": len(steps), "seconds": result["seconds"],
            "pose_error": last["pose_error"], "pose_relative": last["pose_error"] / threshold,
            "rotation_error_deg": last.get("rotation_error_deg"),
            "recon_error": recon,
            "recon_relative": None if recon is None else recon / threshold}


def table_rows(summaries):
    """One row per object and scale: means over the seeds."""
    rows = []
    keys = sorted({(s["object"], s["scale"]) for s in summaries},
                  key=lambda k: (list(SIZES_M).index(k[0]), SCALES.index(k[1])))
    for name, scale in keys:
        group = [s for s in summaries if s["object"] == name and s["scale"] == scale]
        recon = [s["recon_relative"] for s in group if s["recon_relative"] is not None]
        rows.append({
            "object": name, "scale": scale, "size": group[0]["size"], "trials": len(group),
            "known_object": group[0]["known_object"],
            "right_class": sum(s["right_class"] for s in group),
            "judged_novel": sum(s["novel"] for s in group),
            "pose_success": sum(s["right_class"] and s["pose_relative"] < 1 for s in group),
            "pose_relative": float(np.mean([s["pose_relative"] for s in group])),
            "recon_relative": float(np.mean(recon)) if recon else None,
            "steps": float(np.mean([s["steps"] for s in group])),
            "seconds": float(np.mean([s["seconds"] for s in group]))})
    return rows


def markdown(rows):
    lines = ["| object | scale | longest side | trials | right class | judged novel | "
             "pose < 10% | pose error / 10% | recon error / 10% | steps | s/trial |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        size = f"{r['size']:g} m" if r["scale"] == "metric" else f"{r['size']:g}"
        recon = "-" if r["recon_relative"] is None else f"{r['recon_relative']:.3f}"
        lines.append(f"| {r['object']} | {r['scale']} | {size} | {r['trials']} | "
                     f"{r['right_class']} | {r['judged_novel']} | {r['pose_success']} | "
                     f"{r['pose_relative']:.3f} | {recon} | {r['steps']:.1f} | "
                     f"{r['seconds']:.1f} |")
    for scale in SCALES:
        mine = [r for r in rows if r["scale"] == scale]
        known = [r for r in mine if r["known_object"]]
        novel = [r for r in mine if not r["known_object"]]
        recon = [r["recon_relative"] for r in novel if r["recon_relative"] is not None]
        lines.append(
            f"\n**{scale}:** known objects right class "
            f"{sum(r['right_class'] for r in known)}/{sum(r['trials'] for r in known)}, "
            f"pose < 10% {sum(r['pose_success'] for r in known)}/"
            f"{sum(r['trials'] for r in known)}, mean pose error / 10% "
            f"{np.mean([r['pose_relative'] for r in known]) if known else float('nan'):.3f}; "
            f"novel objects judged novel {sum(r['judged_novel'] for r in novel)}/"
            f"{sum(r['trials'] for r in novel)}, mean reconstruction error / 10% "
            f"{np.mean(recon) if recon else float('nan'):.3f}")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = ArgumentParser(prog="python -m tactile_viz bench sizes", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=count_int, default=3, help="seeds per known object")
    parser.add_argument("--novel-seeds", type=nonnegative_int, default=1,
                        help="seeds per novel object")
    parser.add_argument("--objects", type=name_list(list(SIZES_M), "an object"), default=None,
                        metavar="NAME[,NAME...]", help="objects to run (default: all twenty)")
    parser.add_argument("--workers", type=workers_int, default=2, help="trials in parallel")
    parser.add_argument("--out", type=output_dir, default="results/sizes",
                        help="folder for sizes.md, sizes.json and trials.jsonl.gz")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    args.out = Path(args.out)
    args.out.mkdir(parents=True, exist_ok=True)
    names = ([n for n in args.objects.split(",") if n] if args.objects
             else [e["name"] for e in bundled_manifest()])
    results, failed = run_all(tasks(names, args.seeds, args.novel_seeds), args.workers,
                              progress=not args.no_progress, description="sizes")
    summaries = [summary(r) for r in results]
    rows = table_rows(summaries)
    write_atomic(args.out / "sizes.json", json.dumps(rows, indent=1).encode())
    with gzip.open(args.out / "trials.jsonl.gz", "wt") as stream:
        for item in summaries:
            stream.write(json.dumps(item) + "\n")
    text = markdown(rows)
    write_atomic(args.out / "sizes.md", text.encode())
    print(text, end="")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
