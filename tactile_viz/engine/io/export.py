"""What a session learned, as files other programs read.

:func:`export_session` writes a folder with

- ``observations.csv``: every touch in the recording format of
  :mod:`~tactile_viz.engine.io.observation_file` (replaying it reproduces the estimate);
- ``map_shape.ply``: the MAP prior at its estimated pose, world frame;
- ``reconstruction.ply``: the GPIS surface, when the object is judged novel, world frame,
  marked as a learned shape (``--prior-file`` loads it as the learned prior it is);
- ``estimate.json``: ``units``, ``map_class``, ``rotation`` (3x3) and ``translation`` (the
  object frame to the world: the object frame is the prior's bounding-box centre),
  ``file_to_world`` (4x4: the prior's own mesh file, in its own coordinates, to the world:
  what to apply to the user's file to place it), ``map_longest_side``,
  ``class_posterior``, ``novel``, ``log_evidence``, ``log_threshold``, and the step, seed,
  strategy, library and parameters it came from;
- ``session.mcap`` with ``bag=True``: every step as a ROS 2 bag for RViz and Foxglove
  (:func:`~tactile_viz.engine.io.bag_export.export_bag`, lengths in metres).

Every length is in the scene's units (those of the contacts).

Each file is written atomically; a reconstruction file left from an earlier export of a
known object is removed, so the folder always describes one estimate.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import trimesh

from ..shape.objects import mark_learned
from .files import write_atomic
from .observation_file import format_observations

FILES = ("observations.csv", "map_shape.ply", "reconstruction.ply", "estimate.json",
         "session.mcap")


def estimate_record(session, snapshot=None, units=None):
    """The JSON-ready estimate of a snapshot (default the latest) of ``session``;
    ``units`` names the scene's length unit (None: the mesh files' own)."""
    snapshot = snapshot or session.latest
    model = session.library[snapshot.map_class]
    object_to_world = np.eye(4)
    object_to_world[:3, :3] = snapshot.map_rotation
    object_to_world[:3, 3] = snapshot.map_translation
    return {"units": units, "step": snapshot.step, "map_class": snapshot.map_class,
            "rotation": snapshot.map_rotation.tolist(),
            "translation": snapshot.map_translation.tolist(),
            "file_to_world": (object_to_world @ model.file_to_object).tolist(),
            "map_longest_side": model.length,
            "class_posterior": {name: float(p) for name, p in snapshot.class_posterior.items()},
            "novel": bool(snapshot.novel), "log_evidence": float(snapshot.log_evidence),
            "log_threshold": float(snapshot.log_threshold),
            "terminated": bool(snapshot.terminated), "seed": session.seed,
            "strategy": session.strategy, "library": session.library.names,
            "params": session.params.to_dict()}


def _ply(vertices, faces):
    return trimesh.Trimesh(vertices, faces, process=False).export(file_type="ply")


def export_session(session, folder, units: str | None = None, bag: bool = False,
                   interrupted: bool = False) -> list[Path]:
    """Write the latest estimate of ``session`` and its touches to ``folder``.

    Parameters
    ----------
    session : Session
        With at least one step.
    folder : path-like
        Created when missing.
    units : str, optional
        The scene's length unit, written into the files (None: the mesh files' own).
    bag : bool
        Also write ``session.mcap`` (needs rosbags).
    interrupted : bool
        The run was stopped before it ended (Ctrl-C): ``estimate.json`` says so and the
        recording starts with an ``# interrupted:`` comment naming the last step.

    Returns
    -------
    list of Path
        The files written.
    """
    from ..session import SessionError

    snapshot = session.latest
    if snapshot is None:
        raise SessionError("nothing to export: the session has no step yet")
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        recording = format_observations(session.recorded_steps(), units)
        if interrupted:
            recording = (f"# interrupted: at step {snapshot.step}, before the session "
                         f"ended\n{recording}")
        written = [write_atomic(folder / "observations.csv", recording.encode()),
                   write_atomic(folder / "map_shape.ply",
                                _ply(snapshot.map_vertices, snapshot.map_faces))]
        reconstruction = folder / "reconstruction.ply"
        if snapshot.gpis_faces is not None and len(snapshot.gpis_faces):
            written.append(write_atomic(reconstruction, mark_learned(
                _ply(snapshot.gpis_vertices, snapshot.gpis_faces))))
        elif reconstruction.exists():
            os.remove(reconstruction)
        record = {**estimate_record(session, snapshot, units), "interrupted": interrupted}
        text = json.dumps(record, indent=1)
        written.append(write_atomic(folder / "estimate.json", text.encode()))
        if bag:
            from .bag_export import export_bag

            written.append(export_bag(session, folder / "session.mcap", units))
    except OSError as error:
        raise SessionError(f"cannot export to {folder}: {error}") from error
    return [Path(path) for path in written]


__all__ = ["FILES", "estimate_record", "export_session"]
