"""One headless trial: ``python -m tactile_viz trial ...``.

Its JSON is what scripts and the benchmarks read, so its keys only grow: the set-up
(``object``, ``seed``, ``strategy``, ``preset``, ``params``, ``library``, ``truth_pose``,
``code_version``), ``terminated_at``, ``seconds`` and ``steps``, one
:meth:`~tactile_viz.engine.Snapshot.record` per step (``t``, ``map_class``, ``pose_error``,
``dhd``, ``novel``, ``recon_error``, ...). ``tests/engine/test_session.py`` checks the keys.
"""

import argparse
import functools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import (add_preset_argument, add_set_argument, bundled_object, finite_float,
                   output_dir, parameter_value, positive_int, seed_int, with_settings,
                   writable_output)
from ..engine.errors import ParameterError
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.bag_export import export_bag
from ..engine.io.export import export_session
from ..engine.io.files import write_atomic
from ..engine.shape.objects import load_bundled
from ..engine.params import with_changes
from ..engine.session import Session, make_truth, session_preset
from .inputs import (add_prior_arguments, add_unit_arguments, bag_output, check_learning, learn,
                     load_mesh, load_priors, mesh_file, say, scene_units, size_warnings)


NOISELESS = {"position_noise": 0.0, "normal_noise_deg": 0.0, "outliers": 0.0,
             "outlier_probability": None}


def nonnegative_float(text):
    """An argument type: a finite number >= 0."""
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {text!r}")
    return value


def fraction(text):
    """An argument type: a number in [0, 0.5) (the simulated sensor's share of wrong
    contacts)."""
    value = finite_float(text)
    if not 0 <= value < 0.5:
        raise argparse.ArgumentTypeError(f"must lie in [0, 0.5), got {text!r}")
    return value


def add_sensor_arguments(parser, simulated=True):
    """The sensor's noise (``--position-noise``, ``--normal-noise``: the simulator adds it
    and the model assumes it), the model's outlier probability and, for a simulated
    sensor, its rate of wrong contacts (``--outliers``)."""
    parser.add_argument("--position-noise", type=nonnegative_float, default=0.0, metavar="STD",
                        help="std of the sensor's contact positions, scene units (default 0)")
    parser.add_argument("--normal-noise", type=nonnegative_float, default=0.0, metavar="DEG",
                        help="std of the tilt of the sensor's normals, degrees (default 0)")
    parser.add_argument("--outlier-probability", type=parameter_value("outlier_probability"),
                        default=None, metavar="P",
                        help="the model's chance of a wrong contact: a robust likelihood "
                             "(default the preset's; 0 is the paper's Gaussian)")
    if simulated:
        parser.add_argument("--outliers", type=fraction, default=0.0, metavar="FRACTION",
                            help="the simulated sensor's chance of a wrong contact, a third "
                                 "of the object's size off (default 0)")


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


def add_output_arguments(parser, export_help):
    parser.add_argument("--json", metavar="OUT", type=writable_output,
                        help="write the JSON here (default stdout)")
    parser.add_argument("--export", metavar="DIR", type=output_dir, help=export_help)
    parser.add_argument("--export-bag", metavar="FILE.mcap", type=bag_output,
                        help="write every step as a ROS 2 bag (MCAP, metres) for RViz and "
                             "Foxglove: touches, MAP pose, posterior, MAP shape and GPIS "
                             "markers (docs/robots.md)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def add_trial_arguments(parser):
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--object", metavar="NAME", type=bundled_object(),
                      help="a bundled object (see `objects`)")
    what.add_argument("--object-file", metavar="MESH[:UNIT]", type=mesh_file,
                      help="any mesh file trimesh reads; a suffix :mm, :m, ... or :FACTOR "
                           "gives its unit")
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
    add_output_arguments(parser, "write observations.csv, map_shape.ply, reconstruction.ply "
                                 "(when novel) and estimate.json of the last step to DIR")


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
              max_steps=None, progress=False, params=None, finish=None, sensor=None):
    """Run one trial and return its JSON-ready result dict.

    ``params`` (a ``SessionParams``) replaces the preset's parameters when given (``preset``
    is then only a label). ``finish(session)`` is called after the last step; the dict it
    returns is merged into the result (benchmarks add final contacts, baselines, ...).
    ``sensor`` holds the simulated sensor's noise and outliers (:func:`sensor_settings`).
    """
    sensor = {**NOISELESS, **(sensor or {})}
    if max_steps is not None and max_steps < 1:
        raise ParameterError(f"max_steps must be at least 1, got {max_steps}")
    params = with_outliers(params or session_preset(preset), sensor["outlier_probability"])
    truth = make_truth(truth_model, rng=[seed, 0])
    session = Session(truth, library, strategy, params, seed=seed,
                      sensor_noise=(sensor["position_noise"], sensor["normal_noise_deg"]),
                      sensor_outliers=sensor["outliers"])
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_steps or params.max_steps_novel, desc=truth_model.name,
                   unit="step", file=sys.stderr, delay=2.0)
    start = time.perf_counter()
    steps = []
    while not session.terminated and (max_steps is None or len(steps) < max_steps):
        snapshot = session.step()
        steps.append(snapshot.record())
        if bar is not None:
            bar.update(1)
            bar.set_postfix(cls=snapshot.map_class, novel=snapshot.novel,
                            dhd=f"{snapshot.dhd:.2f}")
    if bar is not None:
        bar.close()
    last = session.latest
    truth_pose = np.eye(4)
    truth_pose[:3, :3], truth_pose[:3, 3] = truth.rotation, truth.translation
    result = {"object": truth_model.name, "object_size": truth_model.length, "seed": seed, "strategy": strategy, "preset": preset,
            "params": params.to_dict(), "library": library.names,
            "truth_pose": {"rotation": truth.rotation.tolist(),
                           "translation": truth.translation.tolist(),
                           "file_to_world": (truth_pose @ truth_model.file_to_object).tolist()},
            "sensor": sensor, "terminated_at": last.step if last.terminated else None,
            "decided_at": next((s["t"] for s in steps if s["decided"]), None),
            "code_version": code_version(),
            "seconds": time.perf_counter() - start, "steps": steps}
    if finish is not None:
        result.update(finish(session))
    return result


def run_trial_command(args):
    library = load_priors(args)
    units = scene_units(args, library)
    truth_model = (load_bundled(args.object) if args.object
                   else load_mesh(args, args.object_file, units))
    for message in size_warnings(args, library, truth_model):
        say(args, "warning", message)
    learn_to = check_learning(args, library)

    def finish(session):
        extra = {}
        if args.export:
            export_session(session, args.export, units)
        if args.export_bag:
            export_bag(session, args.export_bag, units)
        if learn_to:
            extra["learned"] = learn(session, library, args.learn, learn_to, units, args)
        return extra

    result = run_trial(truth_model, library, args.strategy, args.seed, args.preset,
                       args.max_steps, progress=not args.no_progress, finish=finish,
                       sensor=sensor_settings(args),
                       params=with_settings(session_preset(args.preset), args.set))
    result["units"] = units
    write_output(json.dumps(result, indent=1), args.json)
    return 0
