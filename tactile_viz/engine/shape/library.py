"""The prior library: the named set of object models the filter may recognise.

A library is saved as a folder of PLY meshes plus ``library.json``. Mesh files carry the
content hash in their name and are written before the manifest, which is replaced
atomically last: a failed or interrupted save leaves the previous library readable.

Each prior may name the length unit of its mesh (``units``: a name of
:data:`~tactile_viz.engine.shape.meshes.UNITS`, or None when unknown, as for the bundled objects at
the paper's scale). The manifest keeps it, so that a library saved in metres loads into a
millimetre scene converted; manifests written before it was kept load with unknown units.
:func:`size_warning` is the one check that a file without a unit is in the library's.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import re
from pathlib import Path

import numpy as np
import trimesh

from ..errors import LibraryError, MeshError
from ..io.files import write_atomic
from .meshes import UNITS, check_arrays
from .objects import ObjectModel, bundled_names, load_bundled

log = logging.getLogger(__name__)

MANIFEST = "library.json"
FORMAT = "tactile_viz-prior-library"
# A file whose size is this many times off the library's reference size (either way) is
# likely in another unit.
MISMATCH = 10.0


class PriorLibrary:
    """An ordered, named collection of :class:`~tactile_viz.engine.shape.objects.ObjectModel`.

    Parameters
    ----------
    models : iterable of ObjectModel, optional
    """

    def __init__(self, models=()):
        self._models = {}
        self._units = {}
        for model in models:
            self.add(model)

    def __len__(self):
        return len(self._models)

    def __iter__(self):
        return iter(self._models.values())

    def __contains__(self, name):
        return name in self._models

    def __getitem__(self, name):
        try:
            return self._models[name]
        except KeyError:
            raise LibraryError(f"no prior named {name!r}; the library has "
                               f"{', '.join(self._models) or 'none'}") from None

    def __repr__(self):
        return f"PriorLibrary({self.names})"

    @property
    def reference_size(self) -> float:
        """The median longest side of the priors, scene units: the size that the filter's
        length parameters scale with (6 for the paper's objects)."""
        if not self._models:
            raise LibraryError("the prior library is empty")
        return float(np.median([model.length for model in self]))

    @property
    def names(self) -> list[str]:
        """Names of the models, in the order they were added."""
        return list(self._models)

    def add(self, model: ObjectModel, replace: bool = False,
            units: str | None = None) -> ObjectModel:
        """Add a model; a name already present is an error unless ``replace``.

        ``units`` names the unit of the model's coordinates (a key of ``UNITS``; None:
        unknown), kept by :meth:`save`.
        """
        if model.name in self._models and not replace:
            raise LibraryError(f"the library already has a prior named {model.name!r}")
        if units is not None and units not in UNITS:
            raise LibraryError(f"prior {model.name!r}: unknown units {units!r}; use one of "
                               f"{', '.join(UNITS)}")
        self._models[model.name] = model
        self._units[model.name] = units
        return model

    def add_file(self, path: str | Path, name: str | None = None, units: str | None = None,
                 **kwargs) -> ObjectModel:
        """Load a mesh file as a new prior (raises MeshError and adds nothing if it is bad);
        ``units`` names the unit of the loaded model (after ``scale``), see :meth:`add`."""
        return self.add(ObjectModel.from_file(path, name=name, **kwargs), units=units)

    def add_arrays(self, vertices, faces, name, units=None, **kwargs):
        """Add a prior from ``(n, 3)`` vertices and ``(m, 3)`` faces."""
        return self.add(ObjectModel.from_arrays(vertices, faces, name, **kwargs), units=units)

    def remove(self, name):
        """Remove and return the model ``name``."""
        model = self[name]
        del self._models[name]
        self._units.pop(name, None)
        return model

    def subset(self, names):
        """A new library with only the named models (sharing them and their units)."""
        library = PriorLibrary()
        for name in names:
            library.add(self[name], units=self.units_of(name))
        return library

    def units_of(self, name) -> str | None:
        """The unit of the prior ``name``'s coordinates (None: unknown)."""
        self[name]  # raises LibraryError for an unknown name
        return self._units.get(name)

    @property
    def units(self) -> str | None:
        """The unit all priors share, None when any is unknown or they differ (or there
        are none)."""
        found = {self._units.get(name) for name in self._models}
        return found.pop() if len(found) == 1 else None

    @classmethod
    def bundled(cls, which: str = "known", params=None, cache=None) -> PriorLibrary:
        """The bundled object set: ``"known"`` (the paper's priors), ``"novel"`` or ``"all"``."""
        return cls(load_bundled(name, params, cache) for name in bundled_names(which))

    def save(self, folder: str | Path) -> Path:
        """Write the library to ``folder`` (created if needed) without risking the old one.

        Each entry of the manifest has the prior's ``name``, mesh ``file`` and its
        ``sha256``, ``learned``, ``longest_side``, ``file_to_object`` (4x4), ``shape_error``
        (a learned shape's, in its units), ``normal_error`` (a learned shape's) and
        ``units`` (None when unknown).
        """
        folder = Path(folder)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            entries = [{**_save_mesh(folder, model), "units": self._units.get(model.name)}
                       for model in self]
            manifest = {"format": FORMAT, "version": 1, "objects": entries}
            write_atomic(folder / MANIFEST, json.dumps(manifest, indent=1).encode())
        except OSError as error:
            raise LibraryError(f"cannot save the library to {folder}: {error}") from error
        kept = {entry["file"] for entry in entries}
        for stale in folder.glob("*.ply"):
            if stale.name not in kept:
                stale.unlink(missing_ok=True)
        log.info("saved %d priors to %s", len(entries), folder)
        return folder

    @classmethod
    def load(cls, folder: str | Path, params=None, cache=None,
             units: str | None = None) -> PriorLibrary:
        """Read a library folder written by :meth:`save`.

        Parameters
        ----------
        units : str, optional
            The scene's unit: priors saved in another named unit are converted to it. None:
            priors are kept as saved, except that priors in different named units are all
            converted to metres. Priors saved without a unit are never converted.

        Raises
        ------
        LibraryError
            If the folder, its manifest or any mesh is missing or corrupt.
        """
        folder = Path(folder)
        entries = _read_manifest(folder)
        if units is not None and units not in UNITS:
            raise LibraryError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
        named = {entry.get("units") for entry in entries} - {None}
        if units is None and len(named) > 1:
            units = "m"
        library = cls()
        for entry in entries:
            path = folder / entry["file"]
            try:
                data = path.read_bytes()
            except OSError as error:
                raise LibraryError(f"library {folder}: mesh file {entry['file']} of prior "
                                   f"{entry['name']!r} cannot be read ({error})") from error
            if hashlib.sha256(data).hexdigest() != entry["sha256"]:
                raise LibraryError(f"library {folder}: mesh file {entry['file']} of prior "
                                   f"{entry['name']!r} is corrupt (checksum mismatch)")
            mesh, saved = _mesh_from_ply(data, path), entry.get("units")
            scale = 1.0 if units is None or saved is None else UNITS[saved] / UNITS[units]
            mesh.apply_scale(scale)
            model = ObjectModel(entry["name"], mesh, params, cache,
                                learned=entry.get("learned") is True,
                                file_to_object=np.diag([scale] * 3 + [1.0]) @ _matrix(entry, path),
                                shape_error=scale * float(entry.get("shape_error", 0.0)),
                                normal_error=float(entry.get("normal_error", 0.0)))
            library.add(model, units=units if saved is not None and units else saved)
        log.info("loaded %d priors from %s", len(library), folder)
        return library


def _slug(name):
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "prior"


def _save_mesh(folder, model):
    data = model.mesh.export(file_type="ply", encoding="binary")
    digest = hashlib.sha256(data).hexdigest()
    filename = f"{_slug(model.name)}-{digest[:12]}.ply"
    if not (folder / filename).is_file():
        write_atomic(folder / filename, data)
    return {"name": model.name, "file": filename, "sha256": digest, "learned": model.learned,
            "longest_side": model.length, "file_to_object": model.file_to_object.tolist(),
            **model.own_errors()}


def _matrix(entry, path):
    """The entry's ``file_to_object`` (identity in libraries saved before it was kept)."""
    matrix = entry.get("file_to_object")
    if matrix is None:
        return np.eye(4)
    try:
        matrix = np.array(matrix, dtype=float).reshape(4, 4)
    except (TypeError, ValueError) as error:
        raise LibraryError(f"{path}: its file_to_object is not a 4x4 matrix ({error})") from error
    if not np.isfinite(matrix).all():
        raise LibraryError(f"{path}: its file_to_object is not finite")
    return matrix


def _mesh_from_ply(data, path):
    try:
        mesh = trimesh.load(io.BytesIO(data), file_type="ply", force="mesh", process=False)
        vertices, faces = getattr(mesh, "vertices", None), getattr(mesh, "faces", None)
    except Exception as error:
        raise LibraryError(f"{path}: cannot be read as a mesh ({error})") from error
    if vertices is None or faces is None:
        raise LibraryError(f"{path}: cannot be read as a mesh (it holds no triangles)")
    try:
        vertices, faces = check_arrays(vertices, faces, path)
    except MeshError as error:
        raise LibraryError(f"library mesh {error}") from error
    return trimesh.Trimesh(vertices, faces, process=False)


def _read_manifest(folder):
    path = folder / MANIFEST
    if not folder.is_dir():
        raise LibraryError(f"{folder} is not a library folder (it does not exist)")
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise LibraryError(f"{folder} is not a library folder (no {MANIFEST})") from None
    except (OSError, ValueError) as error:
        raise LibraryError(f"{path} is corrupt ({error})") from error
    try:
        if manifest["format"] != FORMAT:
            raise LibraryError(f"{path} is not a tactile_viz library "
                               f"(format {manifest['format']!r})")
        entries = list(manifest["objects"])
        for entry in entries:
            if not all(isinstance(entry[key], str) for key in ("name", "file", "sha256")):
                raise TypeError("name, file and sha256 must be strings")
            if Path(entry["file"]).name != entry["file"]:
                raise ValueError(f"file {entry['file']!r} is outside the folder")
            if entry.get("units") is not None and entry["units"] not in UNITS:
                raise ValueError(f"prior {entry['name']!r} has unknown units "
                                 f"{entry['units']!r}")
    except (KeyError, TypeError, ValueError) as error:
        raise LibraryError(f"{path} is corrupt ({error!r})") from error
    return entries


def likely_unit(size, reference, units):
    """The unit a file of ``size`` (in the scene unit ``units``) is most likely in, given
    that it should be about ``reference`` long: the name of ``UNITS`` that brings it
    closest; None when the scene's unit is unknown or no other unit comes closer."""
    if units not in UNITS:
        return None
    error = {name: abs(np.log(size * UNITS[name] / UNITS[units] / reference))
             for name in UNITS}
    best = min(error, key=error.get)
    return None if best == units else best


def size_warning(source, size, reference, units=None, remedy="", smaller=True):
    """Why a file without a unit is likely not in the library's unit, or None.

    Parameters
    ----------
    source : str
        Names the file (a mesh or a recording).
    size : float
        Its extent in scene units: a mesh's longest side, a recording's span.
    reference : float
        The library's reference size (:attr:`PriorLibrary.reference_size`), scene units.
    units : str, optional
        The scene's unit name (None: "scene units").
    remedy : str
        What to do, with ``{unit}`` for the likely unit (used only when one is found).
    smaller : bool
        Also warn when ``size`` is too small (False for a few touches, which may cover a
        small part of the object).

    Returns
    -------
    str or None
        One line naming both sizes and the likely unit, when they differ more than
        :data:`MISMATCH` times either way.
    """
    if not (size > 0 and reference > 0) or (1 / MISMATCH if smaller else 0.0) <= (
            size / reference) <= MISMATCH:
        return None
    name = units or "scene units"
    message = (f"{source} spans {size:.3g} {name} but the library's objects are "
               f"{reference:.3g} {name} long")
    guess = likely_unit(size, reference, units)
    if guess is None:
        ratio = size / reference
        how = f"{ratio:.3g} times larger" if ratio > 1 else f"{1 / ratio:.3g} times smaller"
        return f"{message} ({how}): are they in the same unit?"
    return f"{message}: is the file in {guess}?" + (f" {remedy.format(unit=guess)}"
                                                     if remedy else "")


__all__ = ["MISMATCH", "PriorLibrary", "likely_unit", "size_warning"]
