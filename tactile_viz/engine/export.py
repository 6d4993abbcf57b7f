"""What a session learned, as files other programs read.

:func:`export_session` writes a folder with

- ``observations.csv``: every touch in the recording format of
  :mod:`~tactile_viz.engine.observation_file` (replaying it reproduces the estimate);
- ``map_shape.ply``: the MAP prior at its estimated pose, world frame;
- ``reconstruction.ply``: the GPIS surface, when the object is judged novel;
- ``estimate.json``: ``map_class``, ``rotation`` (3x3, object to world), ``translation``,
  ``class_posterior``, ``novel``, ``log_evidence``, ``log_threshold``, and the step, seed,
  strategy, library and parameters it came from.

Each file is written atomically; a reconstruction file left from an earlier export of a
known object is removed, so the folder always describes one estimate.
"""

import json
import os
from pathlib import Path

import trimesh

from .files import write_atomic
from .observation_file import format_observations

FILES = ("observations.csv", "map_shape.ply", "reconstruction.ply", "estimate.json")


def estimate_record(session, snapshot=None):
    """The JSON-ready estimate of a snapshot (default the latest) of ``session``."""
    snapshot = snapshot or session.latest
    return {"step": snapshot.step, "map_class": snapshot.map_class,
            "rotation": snapshot.map_rotation.tolist(),
            "translation": snapshot.map_translation.tolist(),
            "class_posterior": {name: float(p) for name, p in snapshot.class_posterior.items()},
            "novel": bool(snapshot.novel), "log_evidence": float(snapshot.log_evidence),
            "log_threshold": float(snapshot.log_threshold),
            "terminated": bool(snapshot.terminated), "seed": session.seed,
            "strategy": session.strategy, "library": session.library.names,
            "params": session.params.to_dict()}


def _ply(vertices, faces):
    return trimesh.Trimesh(vertices, faces, process=False).export(file_type="ply")


def export_session(session, folder):
    """Write the latest estimate of ``session`` and its touches to ``folder``.

    Parameters
    ----------
    session : Session
        With at least one step.
    folder : path-like
        Created when missing.

    Returns
    -------
    list of Path
        The files written.
    """
    from .session import SessionError

    snapshot = session.latest
    if snapshot is None:
        raise SessionError("nothing to export: the session has no step yet")
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        written = [write_atomic(folder / "observations.csv",
                                format_observations(session.recorded_steps()).encode()),
                   write_atomic(folder / "map_shape.ply",
                                _ply(snapshot.map_vertices, snapshot.map_faces))]
        reconstruction = folder / "reconstruction.ply"
        if snapshot.gpis_faces is not None and len(snapshot.gpis_faces):
            written.append(write_atomic(reconstruction,
                                        _ply(snapshot.gpis_vertices, snapshot.gpis_faces)))
        elif reconstruction.exists():
            os.remove(reconstruction)
        text = json.dumps(estimate_record(session, snapshot), indent=1)
        written.append(write_atomic(folder / "estimate.json", text.encode()))
    except OSError as error:
        raise SessionError(f"cannot export to {folder}: {error}") from error
    return [Path(path) for path in written]


__all__ = ["FILES", "estimate_record", "export_session"]
