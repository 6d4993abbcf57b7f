"""Recorded touches through the filter and the GPIS: ``python -m tactile_viz replay ...``.

The touches come from an observation file (see
:mod:`tactile_viz.engine.io.observation_file`), made by a real sensor, another program or
``trial --export``. Every step of the file is replayed, also after the session would have
stopped; the JSON is the ``trial`` command's, with null truth metrics.

The robot's scene (a table, the reach cone, the tip's radius) comes from the scene options
or, when none is given, from a CSV recording's ``# scene: {...}`` line
(:func:`~.inputs.recorded_scene`); without either, the paper's free space.
"""

import json
import time
from pathlib import Path

from ..cli import (
    add_output_arguments,
    add_preset_argument,
    add_scene_arguments,
    add_sensor_arguments,
    add_set_argument,
    scene_from_args,
    seed_int,
    with_settings,
)
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.bag_export import export_bag
from ..engine.io.bags import read_recording as read_recording_file, recording_file_warning
from ..engine.io.export import export_session
from ..engine.session import RecordedSession, session_preset
from .inputs import (
    add_bag_arguments,
    add_prior_arguments,
    add_unit_arguments,
    bag_topics,
    check_learning,
    learn,
    load_priors,
    recorded_scene,
    recording_file,
    say,
    scene_units,
    size_warnings,
    write_scene_line,
)
from .trial import (
    INTERRUPTED,
    code_version,
    run_steps,
    run_until_interrupted,
    tell_summary,
    with_outliers,
    write_output,
)


def add_replay_arguments(parser):
    parser.add_argument("--observations", metavar="FILE", required=True, type=recording_file,
                        help="CSV of touches: header kind,x,y,z,nx,ny,nz (optional step "
                             "column); kind contact, noncontact or free; or a ROS 2 bag "
                             "(.mcap, .db3 or a bag folder; see the bag options)")
    add_prior_arguments(parser)
    add_preset_argument(parser)
    add_set_argument(parser)
    parser.add_argument("--strategy", choices=STRATEGIES, default="gpis-dhd",
                        help="recorded in the JSON; it only decides the proposed targets")
    parser.add_argument("--seed", type=seed_int, default=0,
                        help="filter seed (the trial's seed reproduces its estimate exactly)")
    add_unit_arguments(parser)
    add_sensor_arguments(parser, simulated=False)
    add_scene_arguments(parser, simulated=False)
    add_bag_arguments(parser)
    add_output_arguments(parser, "write observations.csv, map_shape.ply, reconstruction.ply "
                                 "(when novel) and estimate.json to DIR")


def replay(steps, library, preset="recommended", strategy="gpis-dhd", seed=0, progress=False,
           params=None, sensor_noise=(0.0, 0.0), scene=None):
    """Feed recorded steps to a new session without a simulated object.

    Parameters
    ----------
    steps : list of RecordedStep
    library : PriorLibrary
    preset : str
        Names the session parameters (``params`` replaces them when given).
    scene : Scene, optional
        The robot's world the touches were made in (None: the paper's free space).

    Returns
    -------
    session : Session
    records : list of dict
        One :meth:`Snapshot.record` per step.
    """
    session = RecordedSession(steps, library, strategy, params or session_preset(preset), seed,
                              sensor_noise=sensor_noise, scene=scene)
    return session, run_steps(session, progress, len(steps), "replay")


def read_recording(args, library):
    """The recorded steps of ``--observations`` (a CSV file or a bag) in the scene's unit,
    with a warning when the file is likely in another unit than the library (the app reads
    it the same way)."""
    units = scene_units(args, library)
    steps = read_recording_file(args.observations, units, bag_topics(args))
    message = recording_file_warning(args.observations, steps, library, units)
    if message:
        say(args, "warning", message)
    return steps


def run_replay_command(args):
    library = load_priors(args)
    units = scene_units(args, library)
    steps = read_recording(args, library)
    for message in size_warnings(args, library):
        say(args, "warning", message)
    learn_to = check_learning(args, library)
    scene = scene_from_args(args) or recorded_scene(args.observations, units)
    start = time.perf_counter()
    params = with_outliers(with_settings(session_preset(args.preset), args.set),
                           args.outlier_probability)
    session = RecordedSession(steps, library, args.strategy, params, args.seed,
                              sensor_noise=(args.position_noise, args.normal_noise), scene=scene)
    records = run_until_interrupted(session, not args.no_progress, len(steps), "replay")
    stop = next((r["t"] for r, s in zip(records, session.snapshots) if s.terminated), None)
    result = {"object": None, "observations": str(args.observations), "seed": args.seed,
              "strategy": args.strategy, "preset": args.preset,
              "params": session.params.to_dict(), "library": library.names,
              "truth_pose": None, "scene": None if scene is None else scene.as_dict(),
              "terminated_at": stop, "code_version": code_version(),
              "interrupted": records.interrupted,
              "units": units, "seconds": time.perf_counter() - start, "steps": records}
    if args.export:
        export_session(session, args.export, units, interrupted=records.interrupted)
        write_scene_line(Path(args.export) / "observations.csv", scene)
    if args.export_bag:
        export_bag(session, args.export_bag, units)
    if learn_to and records.interrupted:
        say(args, "note", "not learned: the run was interrupted")
    elif learn_to:
        result["learned"] = learn(session, library, args.learn, learn_to, units, args)
    write_output(json.dumps(result, indent=1), args.json)
    tell_summary(args, result)
    return INTERRUPTED if records.interrupted else 0
