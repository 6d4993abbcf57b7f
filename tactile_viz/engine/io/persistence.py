"""Saving a session to one ``.npz`` file and rebuilding it.

A session file holds the set-up (strategy, seed, parameters, sensor noise, the prior
meshes, the simulated object and its pose when there is one) and the history: the number
of steps, the contacts, and for a session fed by its caller the recorded observations
(:mod:`~tactile_viz.engine.io.observation_file` text). Loading replays the steps, which are
deterministic from the seed, and checks that the contacts come out the same.

The session's set-up is what :meth:`Session.setup <tactile_viz.engine.session.Session.setup>`
gives (the arguments that made it). This module does not import the session (which
imports it): :func:`load_session` is given the class to rebuild.
"""

import io
import json

import numpy as np
import trimesh

from ..errors import SessionError, TactileVizError
from ..explore.simulator import GroundTruth
from ..param_schema import check_integer
from ..params import SessionParams
from ..scene import Scene
from ..shape.library import PriorLibrary
from ..shape.meshes import check_arrays
from ..shape.objects import OWN_ERRORS, ObjectModel, checked_own_error
from .files import write_atomic
from .observation_file import ObservationFileError, format_observations, parse_observations

FORMAT = "tactile_viz-session"


def save_session(session, path):
    """Write ``session`` to ``path`` (atomically: an old file survives a failed write).

    Returns
    -------
    path
    """
    setup = session.setup()
    truth, library = setup.get("truth"), setup["library"]
    config = {"format": FORMAT, "version": 2 if truth is None else 1,
              "strategy": setup["strategy"], "seed": setup["seed"],
              "params": setup["params"].to_dict(), "sensor_noise": list(setup["sensor_noise"]),
              "sensor_outliers": setup.get("sensor_outliers", 0.0) if truth else 0.0,
              "steps": session.step_count, "library": library.names,
              "learned": [model.name for model in library if model.learned],
              "own_errors": {model.name: model.own_errors() for model in library
                             if model.learned},
              "truth_name": None if truth is None else truth.model.name,
              "scene": setup["scene"].as_dict() if setup.get("scene") is not None else None}
    arrays = {"config": np.frombuffer(json.dumps(config).encode(), dtype=np.uint8),
              "contacts": session.filter.contact_positions,
              "noncontacts": session.filter.noncontact_positions}
    if truth is None:
        text = format_observations(session.recorded_steps())
        arrays["observations"] = np.frombuffer(text.encode(), dtype=np.uint8)
    else:
        arrays.update(truth_rotation=truth.rotation, truth_translation=truth.translation,
                      truth_vertices=truth.model.mesh.vertices,
                      truth_faces=truth.model.mesh.faces)
    for index, model in enumerate(library):
        arrays[f"prior{index}_vertices"] = model.mesh.vertices
        arrays[f"prior{index}_faces"] = model.mesh.faces
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    try:
        write_atomic(path, buffer.getvalue())
    except OSError as error:
        raise SessionError(f"cannot save the session to {path}: {error}") from error
    return path


def _read(path, build):
    """The session's set-up from ``path``: (``build(**set-up)``, a session with no steps;
    steps; contacts; recorded steps or None)."""
    with np.load(path, allow_pickle=False) as stored:
        arrays = {name: stored[name] for name in stored.files}
    config = json.loads(arrays["config"].tobytes().decode())
    if config.get("format") != FORMAT:
        raise ValueError("not a tactile_viz session file")
    learned = config.get("learned", [])
    if not (isinstance(learned, list) and all(isinstance(name, str) for name in learned)):
        raise ValueError("the list of learned priors is not a list of names")
    learned, errors = set(learned), _own_errors(config.get("own_errors", {}))
    library = PriorLibrary(_model_from_arrays(name, arrays[f"prior{i}_vertices"],
                                              arrays[f"prior{i}_faces"],
                                              f"the mesh of prior {name!r}", name in learned,
                                              errors.get(name, {}))
                           for i, name in enumerate(config["library"]))
    truth, recorded = None, None
    if config["truth_name"] is None:
        recorded = parse_observations(arrays["observations"].tobytes().decode(),
                                      f"{path} (its observations)")
    else:
        truth_model = _model_from_arrays(config["truth_name"], arrays["truth_vertices"],
                                         arrays["truth_faces"], "the truth mesh")
        rotation, translation = _checked_pose(arrays["truth_rotation"],
                                              arrays["truth_translation"])
        truth = GroundTruth(truth_model, rotation, translation)
    session = build(truth=truth, library=library, strategy=config["strategy"],
                    params=SessionParams.from_dict(config["params"]), seed=config["seed"],
                    sensor_noise=tuple(config["sensor_noise"]),
                    sensor_outliers=float(config.get("sensor_outliers", 0.0)),
                    scene=None if config.get("scene") is None else Scene.from_dict(config["scene"]))
    steps = check_integer("steps", config["steps"])
    cap = max(session.params.max_steps_known, session.params.max_steps_novel)
    if recorded is not None and steps != len(recorded):
        raise ValueError(f"{steps} steps but {len(recorded)} recorded")
    if recorded is None and not 0 <= steps <= cap:
        raise ValueError(f"steps must lie in [0, {cap}], got {steps}")
    return session, steps, np.asarray(arrays["contacts"], dtype=float), recorded


def load_session(path, build, callback=None):
    """Rebuild a saved session by replaying its steps.

    Parameters
    ----------
    path : path-like
    build : callable
        Makes the session from the saved set-up (by keyword, with ``truth`` and
        ``sensor_outliers`` for a simulated one): ``Session.from_setup``, as
        ``Session.load`` gives it.
    callback : callable, optional
        Called with each replayed :class:`Snapshot` (progress, cancelling by raising).

    Returns
    -------
    Session

    Raises
    ------
    SessionError
        The file is not a readable session, or replaying it fails or does not reproduce
        its contacts.
    """
    try:
        session, steps, contacts, recorded = _read(path, build)
    except ObservationFileError as error:
        raise SessionError(f"{path}: not a readable session file ({error})") from error
    except (OSError, ValueError, KeyError, TypeError, EOFError) as error:
        raise SessionError(f"{path}: not a readable session file ({error})") from error
    except Exception as error:  # zipfile.BadZipFile and friends from a truncated file
        raise SessionError(f"{path}: not a readable session file ({error!r})") from error
    for index in range(steps):
        try:
            if recorded is None:
                snapshot = session.step()
            else:
                snapshot = session.observe(recorded[index].observations,
                                           recorded[index].free_space)
        except (TactileVizError, ValueError, TypeError, IndexError, ArithmeticError,
                np.linalg.LinAlgError) as error:
            raise SessionError(f"{path}: replaying step {session.step_count + 1} failed "
                               f"({error!r})") from error
        if callback is not None:
            callback(snapshot)
    if (contacts.shape != session.filter.contact_positions.shape
            or not np.allclose(session.filter.contact_positions, contacts)):
        raise SessionError(f"{path}: replaying the session did not reproduce its contacts")
    return session


def _model_from_arrays(name, vertices, faces, what="the mesh", learned=False, errors=None):
    """A model from stored (already normalised) arrays, checked but not re-processed, with
    its own ``errors`` (:meth:`~..shape.objects.ObjectModel.own_errors`)."""
    if not isinstance(name, str):
        raise TypeError(f"the name of {what} must be a string, got {name!r}")
    vertices, faces = check_arrays(vertices, faces, what)
    return ObjectModel(name, trimesh.Trimesh(vertices, faces, process=False), learned=learned,
                       **(errors or {}))


def _own_errors(stored):
    """The learned priors' own errors as saved: ``{name: {"shape_error": float,
    "normal_error": float}}``, each a finite number >= 0 (files saved before they were
    kept have none: 0)."""
    if not isinstance(stored, dict) or not all(
            isinstance(errors, dict) and set(errors) <= set(OWN_ERRORS)
            for errors in stored.values()):
        raise ValueError("the learned priors' own errors are not a table of their errors")
    checked = {}
    for name, errors in stored.items():
        try:
            checked[name] = {key: checked_own_error(key, value) for key, value in errors.items()}
        except ValueError as error:
            raise ValueError(f"learned prior {name!r}: {error}") from None
    return checked


def _checked_pose(rotation, translation):
    """A stored ``object_to_world`` pose: a proper rotation and a finite translation."""
    rotation = np.asarray(rotation, dtype=float)
    translation = np.asarray(translation, dtype=float)
    if rotation.shape != (3, 3) or translation.shape != (3,):
        raise ValueError(f"the truth pose has shapes {rotation.shape} and {translation.shape}, "
                         "not (3, 3) and (3,)")
    if not (np.isfinite(rotation).all() and np.isfinite(translation).all()):
        raise ValueError("the truth pose is not finite")
    if (np.abs(rotation.T @ rotation - np.eye(3)).max() > 1e-6
            or not abs(np.linalg.det(rotation) - 1) < 1e-6):
        raise ValueError("the truth rotation is not a rotation matrix")
    if np.abs(translation).max() > 1e6:
        raise ValueError("the truth translation is out of range")
    return rotation, translation


__all__ = ["load_session", "save_session"]
