"""``python -m tactile_viz bench paper``: the paper's experimental protocol.

N trials per object at random seeded poses (seed = ``--seed`` + trial index), every chosen
bundled object and strategy; the learned-prior experiment on the home chair (the GPIS
surface of its first GPIS-DHD trial becomes a prior ``home_chair_learned``, then N new
trials, seeds ``--seed`` + 1000 + i, run with the known priors plus it); the Screened
Poisson baseline (depth 9) on each novel trial's final oriented contacts.

The scene options (``--table``, ``--table-height``, ``--reach-angle``, ``--tip-radius``;
off by default: the paper's free space) put every object of every trial at rest on a
table, probed with a tip of that radius within the reach cone; trial files then carry the
scene in their key (``__scene-table0-reach60-tip0.1``) and their ``scene`` record.

Writes to ``--out``: ``trials/*.json`` (the ``trial`` JSON plus ``task``, ``final``
contacts/normals, ``poisson``), ``learned/home_chair_learned.ply``, ``summary.md`` (the
tables), ``summary.json`` (one summary per trial) and the plots ``overview.png``,
``reconstruction.png``, ``learned_prior.png``.
"""

import json
import os
import platform
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from ..cli import (
    ArgumentParser,
    ExtendList,
    add_preset_argument,
    add_scene_arguments,
    add_sensor_arguments,
    add_set_argument,
    bundled_objects,
    count_int,
    existing_file,
    name_list,
    output_dir,
    positive_int,
    scene_from_args,
    seed_int,
    with_settings,
    workers_int,
)
from ..commands.trial import sensor_settings
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.files import write_atomic
from ..engine.presets import session_preset
from ..engine.shape.metrics import ERROR_THRESHOLD as THRESHOLD
from . import aggregate
from .runner import make_task, open_pool, run_tasks, scene_label, task_key, with_scene
from .trial_files import read_trial, read_trials, trial_files, trial_path, write_trial

LEARN_OBJECT = "home_chair"
LEARNED_NAME = "home_chair_learned"
LEARNED_SEED_OFFSET = 1000
# Run order: GPIS-DHD before RRT (the paper's main results come first when a run is cut
# short), within a strategy the long novel trials first (better load balance), and within
# those trial 0 of every object before trial 1 of any (a cut run covers every object).
COST_ORDER = {("novel", "gpis-dhd"): 0, ("known", "gpis-dhd"): 1, ("novel", "rrt"): 2,
              ("known", "rrt"): 3}


def build_parser():
    parser = ArgumentParser(
        prog="python -m tactile_viz bench paper",
        description="The paper's protocol: trials per object at random seeded poses, both "
                    "exploration strategies, the Screened Poisson baseline on novel objects "
                    "and the learned-prior experiment on the home chair; writes per-trial "
                    "JSON, a Markdown summary and the paper's plots.")
    parser.add_argument("--trials", type=count_int, default=10,
                        help="trials per object and strategy (paper 10; 1 = quick version)")
    parser.add_argument("--objects", action=ExtendList, default=None, metavar="NAME",
                        type=bundled_objects,
                        help="bundled objects to run (default all 20); comma lists work too")
    parser.add_argument("--strategies", action=ExtendList, default=list(STRATEGIES),
                        type=name_list(STRATEGIES, "a strategy"),
                        metavar="NAME", help="exploration strategies, comma lists work too; "
                        f"repeats add up (default {','.join(STRATEGIES)})")
    parser.add_argument("--workers", type=workers_int, default=1,
                        help="local worker processes (default 1 = serial in this process, "
                             "with a per-step progress bar)")
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help="run the trials on a Dask distributed cluster at this address "
                             "(e.g. tcp://10.0.0.5:8786) instead of locally")
    add_preset_argument(parser)
    add_set_argument(parser)
    parser.add_argument("--seed", type=seed_int, default=0,
                        help="first seed; trial i uses seed + i (learned-prior trials seed + "
                             "1000 + i, so at other poses than the one learned from)")
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="cap every trial at this many steps (default: the paper's caps "
                             "300 known / 400 novel); for smoke tests")
    parser.add_argument("--out", default="bench_paper", metavar="DIR", type=output_dir,
                        help="output folder (default ./bench_paper)")
    parser.add_argument("--no-learned", action="store_true",
                        help="skip the learned-prior experiment on the home chair")
    parser.add_argument("--learned-from", metavar="MESH", default=None, type=existing_file,
                        help="run the learned-prior trials with this mesh as the learned "
                             "home chair (e.g. DIR/learned/home_chair_learned.ply of an earlier "
                             "run) instead of learning it from this run's first trial")
    parser.add_argument("--no-poisson", action="store_true",
                        help="skip the Screened Poisson baseline (needs pymeshlab otherwise)")
    parser.add_argument("--resume", action="store_true",
                        help="reuse trial files already in DIR/trials (same task key) instead "
                             "of running them again")
    parser.add_argument("--report-only", action="store_true",
                        help="run nothing; rebuild summary.md and the plots from DIR/trials")
    add_sensor_arguments(parser)
    add_scene_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    return parser


def object_sets():
    """``{name: "known" | "novel"}`` of the bundled objects."""
    from ..engine.shape.objects import bundled_manifest

    return {entry["name"]: entry["set"] for entry in bundled_manifest()}


def split_names(values):
    """Names given as separate arguments and/or comma lists."""
    return [name for value in values for name in value.split(",") if name]


def protocol_tasks(objects, strategies, trials, seed, preset, max_steps, poisson, sets):
    """Tasks of the main protocol in :data:`COST_ORDER`."""
    tasks = [make_task(name, strategy, seed + index, preset, max_steps=max_steps,
                       poisson=poisson and sets[name] == "novel")
             for name in objects for strategy in strategies for index in range(trials)]
    return sorted(tasks, key=lambda t: (COST_ORDER.get((sets[t["object"]], t["strategy"]), 9),
                                        t["seed"], t["object"]))


def learn_task(tasks, seed, preset, max_steps, poisson):
    """Mark (or add) the trial whose GPIS surface becomes the learned prior; returns tasks
    with that trial first."""
    for task in tasks:
        if (task["object"], task["strategy"], task["seed"]) == (LEARN_OBJECT, "gpis-dhd", seed):
            task["learn_as"] = LEARNED_NAME
            return [task] + [t for t in tasks if t is not task]
    task = make_task(LEARN_OBJECT, "gpis-dhd", seed, preset, kind="learn", max_steps=max_steps,
                     poisson=poisson, learn_as=LEARNED_NAME)
    return [task] + tasks


def learned_tasks(prior, trials, seed, preset, max_steps):
    """The trials with the learned prior added to the known set."""
    return [make_task(LEARN_OBJECT, "gpis-dhd", seed + LEARNED_SEED_OFFSET + index, preset,
                      kind="learned", extra_priors=[prior], max_steps=max_steps)
            for index in range(trials)]


def save_learned(result, folder):
    """Write the learned surface of a result to ``folder/NAME.ply``, marked learned with
    its own errors; returns the prior dict (name, vertices, faces, own errors) or None, and
    leaves only a short note in the result."""
    import trimesh

    from ..engine.shape.objects import OWN_ERRORS, mark_learned

    learned = result.get("learned")
    if not learned or "vertices" not in learned:
        return None
    vertices, faces = np.asarray(learned["vertices"]), np.asarray(learned["faces"])
    errors = {name: float(learned[name]) for name in OWN_ERRORS if name in learned}
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{learned['name']}.ply"
    write_atomic(path, mark_learned(trimesh.Trimesh(vertices, faces, process=False).export(
        file_type="ply"), errors))
    result["learned"] = {"name": learned["name"], "file": str(path),
                         "n_vertices": len(vertices), "n_faces": len(faces), **errors}
    return {"name": learned["name"], "vertices": vertices, "faces": faces, **errors}


def load_learned(folder):
    """The learned prior saved by an earlier run, or None."""
    path = folder / f"{LEARNED_NAME}.ply"
    return load_learned_file(path) if path.exists() else None


def load_learned_file(path):
    """A mesh file as the learned prior (name ``home_chair_learned``), with the own errors
    its header keeps (:func:`~..engine.shape.objects.file_own_errors`)."""
    import trimesh

    from ..engine.errors import MeshError
    from ..engine.shape.objects import file_own_errors

    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except (OSError, ValueError) as error:
        raise SystemExit(f"cannot read the learned prior {path}: {error}") from None
    if len(mesh.faces) == 0:
        raise SystemExit(f"the learned prior {path} has no faces")
    try:
        errors = file_own_errors(path)
    except MeshError as error:
        raise SystemExit(f"cannot read the learned prior {path}: {error}") from None
    return {"name": LEARNED_NAME, "vertices": np.asarray(mesh.vertices),
            "faces": np.asarray(mesh.faces), **errors}


def write_json(path, value):
    """Write JSON atomically (a killed run leaves no half file)."""
    write_atomic(path, json.dumps(value, indent=1).encode())


def with_setting(tasks, sensor, scene=None, settings=()):
    """Give every task the sensor settings (:func:`with_sensor`), the robot's ``scene``
    (None: the paper's free space) and ``settings`` (``--set`` pairs) changed in its
    preset; returns a function that does the same to later tasks."""
    noisy = with_sensor(tasks, sensor)

    def placed(more):
        for task in noisy(more):
            with_scene(task, scene)
            if settings:
                task["params"] = with_settings(session_preset(task["preset"]),
                                               settings).to_dict()
        return more

    placed(tasks)
    return placed


def with_sensor(tasks, sensor):
    """Give every task the sensor settings (noise, outliers) unless they are the noiseless
    defaults; returns a function that does the same to later tasks."""
    def noisy(more):
        if any(value for value in sensor.values()):
            for task in more:
                task["sensor"] = dict(sensor)
        return more

    noisy(tasks)
    return noisy


def run(args):
    """Run (or resume) the trials of the protocol; returns nothing, files are in ``out``."""
    out = Path(args.out)
    trials_dir, learned_dir = out / "trials", out / "learned"
    trials_dir.mkdir(parents=True, exist_ok=True)
    sets = object_sets()
    objects = split_names(args.objects) if args.objects else list(sets)
    unknown = [name for name in objects if name not in sets]
    if unknown:
        raise SystemExit(f"unknown object(s): {', '.join(unknown)}; "
                         "see `python -m tactile_viz objects`")
    strategies = split_names(args.strategies)
    if set(strategies) - set(STRATEGIES):
        raise SystemExit(f"unknown strategy in {args.strategies!r}; choose from "
                         f"{', '.join(STRATEGIES)}")
    poisson = not args.no_poisson
    if poisson and any(sets[name] == "novel" for name in objects):
        from .poisson import require_poisson

        require_poisson()
    tasks = protocol_tasks(objects, strategies, args.trials, args.seed, args.preset,
                           args.max_steps, poisson, sets)
    if args.learned_from:
        tasks += learned_tasks(load_learned_file(args.learned_from), args.trials, args.seed,
                               args.preset, args.max_steps)
    elif not args.no_learned:
        tasks = learn_task(tasks, args.seed, args.preset, args.max_steps, poisson)
    noisy = with_setting(tasks, sensor_settings(args), scene_from_args(args), args.set)

    def follow_up(task, result):
        if not task["learn_as"]:
            return []
        prior = save_learned(result, learned_dir)
        if prior is None:
            note = result.get("learned", {}).get("error", "no GPIS surface")
            print(f"learned-prior experiment skipped: the {LEARN_OBJECT} trial gave no prior "
                  f"({note})", file=sys.stderr)
            return []
        pending = noisy(learned_tasks(prior, args.trials, args.seed, args.preset,
                                      args.max_steps))
        return [t for t in pending if not _reuse(t)]

    def _reuse(task):
        path = trial_path(trials_dir, task_key(task))
        if not (args.resume and path.exists()):
            return False
        return "error" not in read_trial(path)

    todo, followed = [t for t in tasks if not _reuse(t)], []
    learning = [t for t in tasks if t["learn_as"]]
    if learning and learning[0] not in todo:
        prior = load_learned(learned_dir)
        if prior is not None:
            followed = [t for t in noisy(learned_tasks(prior, args.trials, args.seed,
                                                       args.preset, args.max_steps))
                        if not _reuse(t)]
    pool = open_pool(args.workers, args.scheduler, progress=not args.no_progress)
    try:
        for task, result in run_tasks(followed + todo, pool, follow_up,
                                      progress=not args.no_progress):
            write_trial(trials_dir, task_key(task), result)
    finally:
        pool.close()


def load_results(folder):
    """Every trial result in ``folder/trials``."""
    return read_trials(Path(folder, "trials"))


def machine_description():
    """One line about this machine (CPU model, cores, Python)."""
    model = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}")


def report(folder, command=None):
    """Write ``summary.md``, ``summary.json`` and the plots from the trial files."""
    from .plots import learned_figure, overview_figure, reconstruction_figure

    folder = Path(folder)
    results = load_results(folder)
    sets = object_sets()
    summaries = [aggregate.summarise_trial(r) for r in results]
    for summary in summaries:
        summary["set"] = sets.get(summary["object"], "other")
    write_json(folder / "summary.json", summaries)
    protocol = [(r, s) for r, s in zip(results, summaries) if s["kind"] == "protocol"]
    by_set = {name: [s for _, s in protocol if s["set"] == name] for name in ("known", "novel")}
    results_by_set = {name: [r for r, s in protocol if s["set"] == name and "error" not in s]
                      for name in ("known", "novel")}
    strategies = sorted({s["strategy"] for s in summaries}, key=lambda s: s != "gpis-dhd")
    lines = [f"# bench paper: {folder}", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    lines += [f"Machine: {machine_description()}", "",
              f"Trials: {len(results)} ({sum('error' in s for s in summaries)} failed)", ""]
    versions = Counter(str(r.get("code_version")) for r in results)
    if versions:
        # Trials are reproducible per seed only within one version of the code.
        counts = ", ".join(f"{v} ({n})" for v, n in sorted(versions.items()))
        lines += [f"Code version(s) of the trials (number of trials): {counts}", ""]
    scenes = Counter(scene_label(r["scene"]) if r.get("scene") else "free space (the paper's)"
                     for r in results if "steps" in r)
    if any(label != "free space (the paper's)" for label in scenes):
        counts = ", ".join(f"{label} ({n})" for label, n in sorted(scenes.items()))
        lines += [f"Robot's scene of the trials (number of trials): {counts}", ""]
    failed = [s for s in summaries if "error" in s]
    for summary in failed:
        lines.append(f"- FAILED {summary['object']} {summary['strategy']} seed {summary['seed']}: "
                     f"{summary['error'].strip().splitlines()[-1]}")
    lines += _known_section(by_set["known"])
    lines += _novel_section(by_set["novel"])
    lines += _step_time_section([r for r, _ in protocol if "steps" in r])
    before = [s for s in summaries if s["object"] == LEARN_OBJECT and s["strategy"] == "gpis-dhd"
              and s["kind"] in ("protocol", "learn")]
    after = [s for s in summaries if s["kind"] == "learned"]
    lines += _learned_section(before, after, results)
    if results_by_set["known"] or results_by_set["novel"]:
        overview_figure(results_by_set, by_set, folder / "overview.png", strategies)
        lines += ["", "![overview](overview.png)"]
    if by_set["novel"]:
        reconstruction_figure(by_set["novel"], folder / "reconstruction.png")
        lines += ["", "![reconstruction](reconstruction.png)"]
    if after:
        before_results = [r for r, s in zip(results, summaries) if s in before and "error" not in s]
        after_results = [r for r, s in zip(results, summaries) if s in after and "error" not in s]
        learned_figure(before_results, after_results, folder / "learned_prior.png")
        lines += ["", "![learned prior](learned_prior.png)"]
    write_atomic(folder / "summary.md", ("\n".join(lines) + "\n").encode())
    return folder / "summary.md"


def _known_section(summaries):
    if not summaries:
        return []
    ok = [s for s in summaries if "error" not in s]
    lines = ["", "## Known objects", "",
             aggregate.markdown_table(aggregate.KNOWN_HEADER, aggregate.known_rows(summaries)),
             ""]
    for strategy, items in aggregate.group(ok, "strategy").items():
        n = len(items)
        lines.append(f"- {strategy[0]}: classification {sum(s['correct'] for s in items)}/{n}, "
                     f"pose error < {THRESHOLD} at termination "
                     f"{sum(s['pose_error'] < THRESHOLD for s in items)}/{n}, "
                     f"largest particle count {max(s['max_particles'] for s in items)}")
    return lines


def _novel_section(summaries):
    if not summaries:
        return []
    rows, checks = aggregate.reconstruction_comparison(summaries)
    beats_poisson, beats_map = checks["gpis_beats_poisson"], checks["gpis_beats_map_when_novel"]
    return ["", "## Novel objects", "",
            aggregate.markdown_table(aggregate.NOVEL_HEADER, aggregate.novel_rows(summaries)),
            "", "Reconstruction error (TWD, mean over GPIS-DHD trials) next to the paper's:", "",
            aggregate.markdown_table(aggregate.COMPARISON_HEADER, rows), "",
            f"- PF-MAP-GPIS better than Screened Poisson on {beats_poisson[0]} of "
            f"{beats_poisson[1]} novel objects",
            f"- PF-MAP-GPIS better than PF-MAP on {beats_map[0]} of {beats_map[1]} novel objects "
            "judged novel in every trial"]


def _step_time_section(results):
    """Median (and 90th percentile) seconds of the protocol's steps, while judged novel and
    while known (each step's ``step_seconds``)."""
    seconds = {True: [], False: []}
    for result in results:
        for step in result["steps"]:
            seconds[bool(step["novel"])].append(step["step_seconds"])
    lines = []
    for novel, label in ((True, "novel"), (False, "known")):
        if seconds[novel]:
            values = np.asarray(seconds[novel])
            lines.append(f"- step time while {label}: median {np.median(values):.3f} s, 90th "
                         f"percentile {np.percentile(values, 90):.3f} s ({len(values)} steps)")
    return ["", "## Step time", "", *lines] if lines else []


def _learned_section(before, after, results):
    if not after:
        notes = [r.get("learned") for r in results if r.get("learned")]
        if not notes:
            return []
        return ["", "## Learned prior", "", f"Not run: {notes[0].get('error', notes[0])}"]
    return ["", "## Learned prior (home chair)", "",
            aggregate.markdown_table(aggregate.LEARNED_HEADER,
                                     aggregate.learned_rows(before, after)),
            *_learned_source(before, results)]


def _learned_source(before, results):
    """The sentence that names the trial the learned prior came from and its reconstruction
    error: the pose error of the learned shape held where it was learned (empty for a
    prior passed with ``--learned-from``)."""
    source = next((r for r in results if (r.get("learned") or {}).get("file")), None)
    summary = source and next((s for s in before if s["seed"] == source["seed"]), None)
    if summary is None or summary.get("gpis_error") is None:
        return []
    return ["", f"Learned from the reconstruction of the trial at seed {summary['seed']}, "
            f"{summary['gpis_error']:.3g} off the {LEARN_OBJECT} (two-way Hausdorff distance); "
            "the learned shape at the very pose it was learned at scores that pose error, so a "
            f"pose error under {aggregate.THRESHOLD:g} needs a reconstruction about that close."]


def require_trials(folder):
    """Stop with a one-line message when ``folder/trials`` has no trial file to report on."""
    trials = Path(folder) / "trials"
    if not trial_files(trials):
        raise SystemExit(f"no trial files in {trials}; run without --report-only first")


def recorded_command(report_path):
    """The ``Command:`` of an earlier report (the run that made its trials), or None."""
    report_path = Path(report_path)
    if not report_path.exists():
        return None
    for line in report_path.read_text().splitlines():
        if line.startswith("Command: `") and line.endswith("`"):
            return line[len("Command: `"):-1]
    return None


def main(argv=None):
    args = build_parser().parse_args(argv)
    start = time.perf_counter()
    if args.report_only:
        require_trials(args.out)
    else:
        run(args)
    command = "python -m tactile_viz bench paper " + " ".join(argv or sys.argv[3:])
    if args.report_only:  # the table still comes from the run that made the trials
        command = recorded_command(Path(args.out) / "summary.md") or command
    path = report(args.out, command)
    print(f"wrote {path} ({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    return 0
