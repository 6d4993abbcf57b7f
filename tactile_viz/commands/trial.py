"""One headless trial: ``python -m tactile_viz trial ...``.

Its JSON is what scripts and the benchmarks read, so its keys only grow: the set-up
(``object``, ``seed``, ``strategy``, ``preset``, ``params``, ``library``, ``truth_pose``,
``code_version``), ``terminated_at``, ``seconds`` and ``steps``, one
:meth:`~tactile_viz.engine.Snapshot.record` per step (``t``, ``map_class``, ``pose_error``,
``dhd``, ``novel``, ``recon_error``, ``recon_surface_error``, ...).
``tests/engine/session/test_session.py`` checks the keys.
"""

import functools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import (
    add_output_arguments,
    add_preset_argument,
    add_scene_arguments,
    add_sensor_arguments,
    add_set_argument,
    bundled_object,
    positive_int,
    scene_from_args,
    seed_int,
    with_settings,
)
from ..engine.belief.prior_bank import bank_for
from ..engine.errors import ParameterError
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.bag_export import export_bag
from ..engine.io.export import export_session
from ..engine.io.files import write_atomic
from ..engine.params import with_changes
from ..engine.session import Session, make_truth, session_preset
from ..engine.shape.objects import load_bundled
from .inputs import (
    add_prior_arguments,
    add_unit_arguments,
    check_learning,
    learn,
    load_mesh,
    load_priors,
    mesh_file,
    say,
    scene_units,
    size_warnings,
    write_scene_line,
)
from .library import prior_bar
from .summary import result_summary

NOISELESS = {"position_noise": 0.0, "normal_noise_deg": 0.0, "outliers": 0.0,
             "outlier_probability": None}


def sensor_settings(args):
    """``{"position_noise", "normal_noise_deg", "outliers", "outlier_probability"}`` of the
    command line (a task's ``sensor``)."""
    return {"position_noise": args.position_noise, "normal_noise_deg": args.normal_noise,
            "outliers": getattr(args, "outliers", 0.0),
            "outlier_probability": args.outlier_probability}


def with_outliers(params, probability):
    """``params`` with the filter's ``outlier_probability`` (None: unchanged)."""
    if probability is None:
        return params
    return with_changes(params, outlier_probability=probability)


def add_trial_arguments(parser):
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--object", metavar="NAME", type=bundled_object(),
                      help="a bundled object (see `objects`)")
    what.add_argument("--object-file", metavar="MESH[:UNIT]", type=mesh_file,
                      help="any mesh file trimesh reads; a suffix :mm, :m, ... or :FACTOR "
                           "gives its unit")
    parser.add_argument("--object-name", metavar="NAME",
                        help="the --object-file object's name in the summary and the JSON "
                             "(default: the file's; a scan set's textured.obj is better named "
                             "by its folder)")
    add_prior_arguments(parser)
    parser.add_argument("--strategy", choices=STRATEGIES, default="gpis-dhd")
    parser.add_argument("--seed", type=seed_int, default=0,
                        help="pose, exploration and filter seed")
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="stop after this many steps (default: the paper's caps 300/400)")
    add_preset_argument(parser)
    add_set_argument(parser)
    add_unit_arguments(parser)
    add_sensor_arguments(parser)
    add_scene_arguments(parser)
    add_output_arguments(parser, "write observations.csv, map_shape.ply, reconstruction.ply "
                                 "(when novel) and estimate.json of the last step to DIR")


def run_steps(session, progress=False, total=None, label="steps", max_steps=None,
              records=None):
    """Step ``session`` until it terminates or has taken ``max_steps`` steps (None: no
    cap), with a progress bar on stderr when ``progress`` (``total`` steps expected, the
    bar named ``label``); the list of :meth:`~tactile_viz.engine.Snapshot.record` dicts,
    one per step, appended to ``records`` when given (so an interrupted caller keeps the
    steps done). The one run loop of the ``trial`` and ``replay`` commands."""
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=label, unit="step", file=sys.stderr, delay=2.0)
    records = [] if records is None else records
    try:
        while not session.terminated and (max_steps is None or len(records) < max_steps):
            snapshot = session.step()
            records.append(snapshot.record())
            if bar is not None:
                bar.update(1)
                bar.set_postfix(cls=snapshot.map_class, novel=snapshot.novel,
                                dhd=f"{snapshot.dhd:.2f}")
    finally:
        if bar is not None:
            bar.close()
    return records


class Steps(list):
    """The step records of a run, and whether Ctrl-C ended it (``interrupted``)."""

    interrupted = False


def run_until_interrupted(session, progress=False, total=None, label="steps",
                          max_steps=None):
    """:func:`run_steps`, but Ctrl-C after the first step ends the run there: the
    :class:`Steps` done, ``interrupted`` set (before the first step it is raised)."""
    records = Steps()
    try:
        run_steps(session, progress, total, label, max_steps, records=records)
    except KeyboardInterrupt:
        if not records:
            raise
        records.interrupted = True
    return records


def write_output(text, path):
    """Write ``text`` to the file ``path`` atomically, or print it when ``path`` is None."""
    if path:
        write_atomic(path, text.encode())
    else:
        print(text)


@functools.cache
def code_version():
    """The commit this package runs from (``git describe``), ``-dirty`` if the package's own
    files differ from it; None outside a git checkout.

    Trials are deterministic per seed for one version of the code; recording it tells which
    trial files belong together. Changes outside the package (results, docs) do not count.
    """
    package = Path(__file__).resolve().parents[1]

    def git(*args):
        out = subprocess.run(["git", *args], capture_output=True, text=True, timeout=10,
                             cwd=package)
        return out.stdout.strip() if out.returncode == 0 else None

    try:
        commit = git("describe", "--always")
        changed = git("status", "--porcelain", "--", ".")
    except (OSError, subprocess.SubprocessError):
        return None
    if not commit:
        return None
    return commit + ("-dirty" if changed else "")


def run_trial(truth_model, library, strategy="gpis-dhd", seed=0, preset="recommended",
              max_steps=None, progress=False, params=None, finish=None, sensor=None,
              scene=None, keep_interrupted=False):
    """Run one trial and return its JSON-ready result dict.

    ``params`` (a ``SessionParams``) replaces the preset's parameters when given (``preset``
    is then only a label). ``finish(session)`` is called after the last step; the dict it
    returns is merged into the result (benchmarks add final contacts, baselines, ...).
    ``sensor`` holds the simulated sensor's noise and outliers (:func:`sensor_settings`).
    ``scene`` (a :class:`~tactile_viz.engine.scene.Scene`) puts the object at rest on its
    table, probed with its tip within its reach cone.
    With ``keep_interrupted`` a Ctrl-C after the first step ends the run there: the result
    says ``"interrupted": true`` and ``finish(session, True)`` is called.
    """
    sensor = {**NOISELESS, **(sensor or {})}
    if max_steps is not None and max_steps < 1:
        raise ParameterError(f"max_steps must be at least 1, got {max_steps}")
    params = with_outliers(params or session_preset(preset), sensor["outlier_probability"])
    truth = make_truth(truth_model, rng=[seed, 0], scene=scene)
    session = Session.simulated(truth, library, strategy, params, seed=seed,
                      sensor_noise=(sensor["position_noise"], sensor["normal_noise_deg"]),
                      sensor_outliers=sensor["outliers"], scene=scene)
    # The priors' bank before the clock starts (built first if the disk cache lacks it),
    # under a bar of its own: not inside the first step's filter update.
    pf = session.filter
    bank_for(pf.models, pf.params.distance_step, pf.params.angle_step_deg,
             prior_bar if progress else None)
    start = time.perf_counter()
    run = run_until_interrupted if keep_interrupted else run_steps
    steps = run(session, progress, max_steps or params.max_steps_novel, truth_model.name,
                max_steps)
    interrupted = keep_interrupted and steps.interrupted
    last = session.latest
    truth_pose = np.eye(4)
    truth_pose[:3, :3], truth_pose[:3, 3] = truth.rotation, truth.translation
    result = {"object": truth_model.name, "object_size": truth_model.length, "seed": seed,
            "strategy": strategy, "preset": preset,
            "params": params.to_dict(), "library": library.names,
            "truth_pose": {"rotation": truth.rotation.tolist(),
                           "translation": truth.translation.tolist(),
                           "file_to_world": (truth_pose @ truth_model.file_to_object).tolist()},
            "sensor": sensor, "scene": None if scene is None else scene.as_dict(),
            "terminated_at": last.step if last.terminated else None,
            "decided_at": next((s["t"] for s in steps if s["decided"]), None),
            "code_version": code_version(), "interrupted": interrupted,
            "seconds": time.perf_counter() - start, "steps": steps}
    if finish is not None:
        result.update(finish(session, interrupted) if keep_interrupted else finish(session))
    return result


def run_trial_command(args):
    library = load_priors(args)
    units = scene_units(args, library)
    if args.object and args.object_name:
        raise ParameterError("--object-name names an --object-file object; a bundled "
                             "object keeps its name")
    truth_model = (load_bundled(args.object) if args.object
                   else load_mesh(args, args.object_file, units, name=args.object_name))
    for message in size_warnings(args, library, truth_model):
        say(args, "warning", message)
    learn_to = check_learning(args, library)
    scene = scene_from_args(args)

    def finish(session, interrupted=False):
        extra = {}
        if args.export:
            export_session(session, args.export, units, interrupted=interrupted)
            write_scene_line(Path(args.export) / "observations.csv", scene)
        if args.export_bag:
            export_bag(session, args.export_bag, units)
        if learn_to and interrupted:
            say(args, "note", "not learned: the run was interrupted")
        elif learn_to:
            extra["learned"] = learn(session, library, args.learn, learn_to, units, args)
        return extra

    result = run_trial(truth_model, library, args.strategy, args.seed, args.preset,
                       args.max_steps, progress=not args.no_progress, finish=finish,
                       sensor=sensor_settings(args),
                       params=with_settings(session_preset(args.preset), args.set),
                       scene=scene, keep_interrupted=True)
    result["units"] = units
    write_output(json.dumps(result, indent=1), args.json)
    tell_summary(args, result)
    return INTERRUPTED if result["interrupted"] else 0


INTERRUPTED = 130  # the exit status of a run stopped by Ctrl-C (what it did is written)


def tell_summary(args, result):
    """The result's summary on stderr (:func:`~.summary.result_summary`) unless
    ``--quiet``: what was judged, the pose and where the files went."""
    if getattr(args, "quiet", False):
        return
    files = [(what, str(path)) for what, path in (("JSON", args.json), ("export", args.export),
                                                  ("bag", args.export_bag)) if path]
    for line in result_summary(result, files):
        print(line, file=sys.stderr)
