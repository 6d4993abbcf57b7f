"""Object models: a checked, centred mesh with lazily built, disk-cached derived data.

An :class:`ObjectModel` holds a checked mesh in its object frame (centred on its bounding
box, at its real size in the scene's units unless normalised on loading). Its exact signed
distance, SDF grid and feature points are built on first use only, and the grid and
features are cached on disk by the mesh's content hash and the parameters that made them.
"""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import trimesh

from ..belief.features import poisson_disk_points
from ..belief.ppf import PairTable
from ..errors import MeshError
from ..io.cache import ArrayCache
from ..params import PAPER_SIZE
from .meshes import bare_mesh, content_hash, load_mesh, prepare_mesh
from .metrics import diameter
from .sdf import ExactDistance, SDFGrid
from .sdf_build import (
    MAX_REFINED_NODES,
    MISS_COSINE,
    REFINED_BAND,
    THIN_MISSES,
    build_sdf_grid,
    fitted_resolution,
)

ASSETS_ENV_VAR = "TACTILE_VIZ_ASSETS"
SURFACE_CHECKS = 2000  # surface samples on which a grid is checked for thin parts


@dataclass(frozen=True)
class ModelParams:
    """What the derived data of an object model is built with (speed/accuracy knobs).

    Attributes
    ----------
    sdf_resolution : int
        Voxels along the longest side of the padded SDF grid.
    sdf_max_resolution : int
        Up to how many voxels the grid is refined (doubling) while it misses thin parts
        (:func:`~tactile_viz.engine.shape.sdf_build.fitted_resolution`); at most
        ``sdf_resolution``: never.
    sdf_padding : float, size units
        Margin of the SDF grid around the bounding box (a size unit is a sixth of the
        object's longest side).
    sdf_exact_band : float, voxels
        0: the grid holds the exact distance at every node. Otherwise only nodes within
        this many voxels of the surface are exact and the others are interpolated from
        coarser grids (:func:`~tactile_viz.engine.shape.sdf_build.banded_distance`).
    n_features : int
        Number of Poisson-disk feature points.
    feature_seed : int
        Seed of the feature-point sampling (features are part of the model's identity).
    """

    sdf_resolution: int = 64
    sdf_max_resolution: int = 256
    sdf_padding: float = 1.0
    sdf_exact_band: float = 0.0
    n_features: int = 200
    feature_seed: int = 0


class ObjectModel:
    """A known (or learned) object shape.

    Parameters
    ----------
    name : str
    mesh : trimesh.Trimesh
        Already checked and normalised (see :func:`~tactile_viz.engine.shape.meshes.prepare_mesh`).
    params : ModelParams, optional
    cache : ArrayCache, optional
        Where derived arrays are stored; the default is the user cache folder.
    learned : bool
        The shape was reconstructed by a session rather than given (its feature normals
        come from a reconstruction, so its point-pair poses are coarser).
    file_to_object : (4, 4) float, optional
        The similarity from the coordinates of the file the mesh came from to the object
        frame (centring, unit factor or normalisation); default ``mesh.metadata``'s, else
        the identity. ``object_to_world @ file_to_object`` places the user's file.
    shape_error : float, scene units
        How far a touch may lie off this surface although the object is this one: 0 for a
        given mesh; for a learned shape its contacts' held-out errors and distances to it
        (:func:`~tactile_viz.engine.session.learning.own_errors`), which the decision adds
        to the sensor's noise.
    normal_error : float
        How far a touch's normal may lie off this surface's although the object is this
        one, as the RMS length of the difference of unit normals: 0 for a given mesh; for
        a learned shape its learning contacts' (a thin part's reconstruction turns its
        normals), which the novelty test grants (``ParticleFilter.own_turn``).
    """

    def __init__(self, name, mesh, params=None, cache=None, learned=False, file_to_object=None,
                 shape_error=0.0, normal_error=0.0):
        self.name = str(name)
        self.mesh = mesh
        self.params = params or ModelParams()
        self.cache = cache if cache is not None else ArrayCache()
        self.learned = bool(learned)
        self.shape_error = float(shape_error)
        self.normal_error = float(normal_error)
        if file_to_object is None:
            file_to_object = mesh.metadata.get("file_to_object", np.eye(4))
        self.file_to_object = np.array(file_to_object, dtype=float).reshape(4, 4)

    def __repr__(self):
        return f"ObjectModel({self.name!r}, faces={len(self.mesh.faces)})"

    def __getstate__(self):
        # The exact distance holds libigl trees, which do not pickle; it is rebuilt on use,
        # as are the metrics' KD-trees.
        state = dict(self.__dict__)
        state.pop("exact", None)
        state.pop("_sample_trees", None)
        return state

    @classmethod
    def from_file(cls, path: str | Path, name: str | None = None, params=None, cache=None,
                  longest_side: float | None = None, scale: float = 1.0,
                  learned: bool | None = None) -> ObjectModel:
        """Load a mesh file (checked, repaired, centred); the name defaults to the file stem.

        Parameters
        ----------
        longest_side : float or None
            Normalise to this longest side (the paper's convention is 6); None keeps the
            file's size times ``scale`` (scene units per file unit, see
            :func:`~tactile_viz.engine.shape.meshes.unit_factor`).
        learned : bool or None
            None: a file that :func:`~tactile_viz.engine.io.export.export_session` wrote as a
            reconstruction is a learned shape (never normalised, with the own errors its
            header keeps, :func:`file_own_errors`), others are not.
        """
        if learned is None:
            learned = is_learned_file(path)
        mesh = load_mesh(path, None if learned else longest_side, scale=scale)
        errors = file_own_errors(path) if learned else {}
        if "shape_error" in errors:
            errors["shape_error"] *= scale  # a length, in the file's units
        return cls(name or Path(path).stem, mesh, params, cache, learned, **errors)

    @classmethod
    def from_arrays(cls, vertices, faces, name, params=None, cache=None, longest_side=None,
                    learned=False, scale=1.0, shape_error=0.0, normal_error=0.0):
        """Build a model from ``(n, 3)`` vertices and ``(m, 3)`` faces (checked and centred;
        ``longest_side`` normalises their size)."""
        mesh = prepare_mesh(vertices, faces, source=name, longest_side=longest_side,
                            scale=scale)
        return cls(name, mesh, params, cache, learned, shape_error=shape_error,
                   normal_error=normal_error)

    def own_errors(self):
        """``{"shape_error": ..., "normal_error": ...}``: how far a touch may lie off this
        shape although the object is this one (both 0 for a given mesh)."""
        return {name: getattr(self, name) for name in OWN_ERRORS}

    def _like(self, name=None, params=None):
        return ObjectModel(name or self.name, self.mesh, params or self.params, self.cache,
                           self.learned, self.file_to_object, self.shape_error,
                           self.normal_error)

    def with_params(self, **changes):
        """The same mesh with other :class:`ModelParams` (shares the exact distance)."""
        other = self._like(params=replace(self.params, **changes))
        if "exact" in self.__dict__:
            other.__dict__["exact"] = self.exact
        return other

    def renamed(self, name):
        """The same model under another name."""
        other = self._like(name=name)
        other.__dict__.update({k: v for k, v in self.__dict__.items()
                               if k in ("exact", "sdf", "features", "content_hash")})
        return other

    @property
    def length(self) -> float:
        """Longest side of the bounding box, scene units (6 for the paper's objects)."""
        return float(self.mesh.extents.max())

    @cached_property
    def diameter(self) -> float:
        """The largest distance between two of the mesh's vertices, scene units."""
        return float(diameter(self.mesh.vertices))

    @property
    def size_unit(self) -> float:
        """A sixth of :attr:`length`: the scene units of one size unit of the parameters."""
        return self.length / PAPER_SIZE

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays this model holds: its mesh's, those trimesh derived from the
        mesh and kept, and the derived data kept here (features, grid, pair tables, the
        exact distance's arrays; libigl's trees are not counted). A model whose prior bank
        was built from meshes holds what one read from the disk cache does."""
        cached = getattr(getattr(self.mesh, "_cache", None), "cache", {})
        arrays = [self.mesh.vertices, self.mesh.faces, *cached.values(),
                  *self.__dict__.get("features", ())]
        exact = self.__dict__.get("exact")
        if exact is not None:
            arrays += [exact.vertices, exact.faces, exact._face_normals, exact._vertex_normals]
        tables = self.__dict__.get("_pair_tables", {}).values()
        extra = sum(table.nbytes for table in tables)
        if "sdf" in self.__dict__:
            extra += self.sdf.nbytes
        return int(extra + sum(getattr(array, "nbytes", 0) for array in arrays))

    @cached_property
    def content_hash(self):
        """SHA-256 of the mesh arrays."""
        return content_hash(self.mesh)

    @cached_property
    def exact(self):
        """:class:`~tactile_viz.engine.shape.sdf.ExactDistance` of the mesh."""
        return ExactDistance(self.mesh.vertices, self.mesh.faces)

    @contextmanager
    def transient_exact(self):
        """Within the block :attr:`exact` may be built; if it was not there before, it is
        dropped after (libigl trees of some 8 MB: a library of a thousand priors must not
        keep one per prior that a grid build or a metric needed once)."""
        had = "exact" in self.__dict__
        try:
            yield
        finally:
            if not had:
                self.__dict__.pop("exact", None)

    @cached_property
    def sdf(self):
        """:class:`~tactile_viz.engine.shape.sdf.SDFGrid`, built on first use and cached on disk."""
        return self.load_sdf()

    def load_sdf(self):
        """The SDF grid from the disk cache (built if missing) without keeping it here: a
        prior bank copies it into its shared array."""
        if "sdf" in self.__dict__:
            return self.__dict__["sdf"]
        return self._grid_at(self.grid_resolution)

    def _grid_at(self, resolution):
        params = self._grid_params(resolution)
        arrays = self.cache.get_or_build(
            "sdf5", self.content_hash, params,
            lambda: build_sdf_grid(self.exact, self.mesh.bounds, **params).to_arrays())
        return SDFGrid.from_arrays(arrays)

    @cached_property
    def grid_resolution(self) -> int:
        """Voxels along the longest side of the padded grid: ``sdf_resolution``, doubled
        while the grid misses the shape's thin parts (up to ``sdf_max_resolution``; cached
        on disk)."""
        if self.params.sdf_max_resolution <= self.params.sdf_resolution:
            return self.params.sdf_resolution

        def fit():
            # On a bare copy, whose triangles and normals do not stay on the mesh.
            surface = bare_mesh(self.mesh)
            points, _ = trimesh.sample.sample_surface(surface, SURFACE_CHECKS, seed=0)
            closest, face = self.exact.closest_points(points)
            # Face normals: a CAD box's vertex normals are its corners' averages.
            return {"resolution": np.array(fitted_resolution(
                self._grid_at, self.mesh.bounds, self._padding, closest,
                surface.face_normals[face], self.params.sdf_resolution,
                self.params.sdf_max_resolution))}

        return int(self.cache.get_or_build("sdfres", self.content_hash,
                                           self._resolution_params(), fit)["resolution"])

    @cached_property
    def features(self):
        """Feature points ``(points, normals)``: (n_features, 3) each, object frame."""
        arrays = self.cache.get_or_build("features", self.content_hash,
                                         self._features_params(), self._build_features)
        return arrays["points"], arrays["normals"]

    @cached_property
    def inertia(self):
        """The mesh's principal axes of inertia ``(3, 3)`` (rows), their moments ``(3,)``
        and its centre of mass ``(3,)``, object frame; cached on disk (a 22-prior
        library's first decisions spent 0.3 s on them)."""
        arrays = self.cache.get_or_build("inertia", self.content_hash, {}, self._build_inertia)
        return arrays["axes"], arrays["moments"], arrays["centre"]

    def _build_inertia(self):
        mesh = bare_mesh(self.mesh)
        return {"axes": np.asarray(mesh.principal_inertia_vectors, float),
                "moments": np.asarray(mesh.principal_inertia_components, float),
                "centre": np.asarray(mesh.center_mass, float)}

    def _build_features(self):
        # A bare copy: sampling derives triangles, cross products and areas (2 MB for a
        # 10,000-face prior) that would stay on the mesh, where a warm load has none.
        points, faces = poisson_disk_points(bare_mesh(self.mesh), self.params.n_features,
                                            rng=self.params.feature_seed)
        # Project onto the surface exactly so normals come from the same place the SDF does.
        closest, face = self.exact.closest_points(points)
        return {"points": closest, "normals": self.exact.surface_normal(closest, face)}

    def pair_table(self, distance_step=0.1, angle_step_deg=12.0, keep=True):
        """The :class:`~tactile_viz.engine.belief.ppf.PairTable` of the feature points (cached on
        disk, and here unless ``keep`` is False)."""
        key = (float(distance_step), float(angle_step_deg))
        tables = self.__dict__.setdefault("_pair_tables", {})
        if key in tables:
            return tables[key]
        params = self._pairs_params(*key)

        def build():
            points, normals = self.features
            return PairTable.build(points, normals, key[0], np.radians(key[1])).to_arrays()

        table = PairTable.from_arrays(self.cache.get_or_build("pairs2", self.content_hash,
                                                              params, build))
        if keep:
            tables[key] = table
        return table

    @property
    def _padding(self):
        return self.params.sdf_padding * self.size_unit

    def _grid_params(self, resolution):
        # An exact grid's key has no band: the entries built before bands stay valid.
        band = self.params.sdf_exact_band
        key = {"resolution": int(resolution), "padding": self._padding}
        if band > 0:
            return {**key, "band": float(band)}
        if resolution > self.params.sdf_resolution:  # refined: exact near the surface
            return {**key, "band": REFINED_BAND,
                    "exact_resolution": int(self.params.sdf_resolution)}
        return key

    def _sdf_params(self):
        return self._grid_params(self.grid_resolution)

    def _resolution_params(self):
        return {**self._grid_params(self.params.sdf_resolution),
                "max_resolution": self.params.sdf_max_resolution,
                "misses": THIN_MISSES, "cosine": MISS_COSINE, "nodes": MAX_REFINED_NODES,
                "checks": SURFACE_CHECKS}

    def _grid_stored(self):
        refines = self.params.sdf_max_resolution > self.params.sdf_resolution
        if refines and "grid_resolution" not in self.__dict__ and not self.cache.has(
                "sdfres", self.content_hash, self._resolution_params()):
            return False
        return self.cache.has("sdf5", self.content_hash, self._sdf_params())

    def _features_params(self):
        return {"count": self.params.n_features, "seed": self.params.feature_seed}

    def _pairs_params(self, distance_step, angle_step_deg):
        return {"distance_step": float(distance_step), "angle_step_deg": float(angle_step_deg),
                **self._features_params()}

    def derived_stored(self, distance_step=0.1, angle_step_deg=12.0) -> bool:
        """Whether the grid, features, pair table and inertia a prior bank reads are here
        or in the disk cache (so that building the bank builds nothing)."""
        tables = self.__dict__.get("_pair_tables", {})
        has = lambda kind, params: self.cache.has(kind, self.content_hash, params)  # noqa: E731
        return (("sdf" in self.__dict__ or self._grid_stored())
                and ("features" in self.__dict__ or has("features", self._features_params()))
                and ((float(distance_step), float(angle_step_deg)) in tables
                     or has("pairs2", self._pairs_params(distance_step, angle_step_deg)))
                and ("inertia" in self.__dict__ or has("inertia", {})))

    def describe(self):
        """A JSON-ready summary (name, sizes, parameters, hash)."""
        return {"name": self.name, "learned": self.learned, "faces": int(len(self.mesh.faces)),
                "vertices": int(len(self.mesh.vertices)), "content_hash": self.content_hash,
                "longest_side": self.length, "file_to_object": self.file_to_object.tolist(),
                "params": asdict(self.params)}


LEARNED_MARK = b"comment tactile_viz learned shape"
OWN_ERRORS = ("shape_error", "normal_error")  # ObjectModel.own_errors, as saved
OWN_ERRORS_MARK = b"comment tactile_viz own errors"


def _ply_header(path):
    """The header of a PLY file (bytes before ``end_header``; empty for another file)."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(1024)
    except OSError:
        return b""
    return head.split(b"end_header")[0] if head.startswith(b"ply") else b""


def is_learned_file(path):
    """Whether a mesh file is a reconstruction :func:`mark_learned` marked (a PLY header
    comment): such a shape is a learned prior, in the units of the session that made it."""
    return LEARNED_MARK in _ply_header(path)


def file_own_errors(path):
    """The own errors :func:`mark_learned` wrote into a learned file's header, in its
    units (:meth:`ObjectModel.own_errors`; ``{}`` without them).

    Raises
    ------
    MeshError
        A value that is not a finite number >= 0 (:func:`checked_own_error`).
    """
    errors = {}
    for line in _ply_header(path).splitlines():
        if not line.startswith(OWN_ERRORS_MARK):
            continue
        for pair in line[len(OWN_ERRORS_MARK):].decode(errors="replace").split():
            name, _, text = pair.partition("=")
            if name not in OWN_ERRORS:
                continue
            try:
                errors[name] = checked_own_error(name, float(text))
            except ValueError:
                raise MeshError(path, f"its {name} must be a finite number >= 0, "
                                      f"got {text!r}") from None
    return errors


def checked_own_error(name, value):
    """``value`` as one of :data:`OWN_ERRORS` (a float); ValueError unless it is a finite
    number >= 0."""
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not np.isfinite(value) or value < 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def mark_learned(ply_bytes, errors=None):
    """PLY bytes with the learned-shape comment after the format line, and a comment with
    the shape's own ``errors`` (:meth:`ObjectModel.own_errors`, in the file's units)."""
    first, rest = ply_bytes.split(b"\n", 1)
    second, rest = rest.split(b"\n", 1)
    marks = [LEARNED_MARK]
    if errors:
        marks.append(OWN_ERRORS_MARK + "".join(
            f" {name}={float(errors[name])!r}" for name in OWN_ERRORS if name in errors
        ).encode())
    return b"\n".join([first, second, *marks, rest])


def assets_dir():
    """The folder of the bundled object set (``$TACTILE_VIZ_ASSETS`` overrides it)."""
    if os.environ.get(ASSETS_ENV_VAR):
        return Path(os.environ[ASSETS_ENV_VAR])
    return Path(__file__).resolve().parents[3] / "assets"


def bundled_manifest():
    """Entries of the bundled set: a list of dicts with ``name``, ``set``, ``file``, ..."""
    path = assets_dir() / "manifest.json"
    try:
        return json.loads(path.read_text())["objects"]
    except (OSError, ValueError, KeyError) as error:
        raise MeshError(path, f"the bundled object manifest cannot be read ({error})") from error


def bundled_names(which: str = "all") -> list[str]:
    """Names of the bundled objects in ``which`` set: ``"known"``, ``"novel"`` or ``"all"``."""
    if which not in ("known", "novel", "all"):
        raise ValueError(f"which must be 'known', 'novel' or 'all', not {which!r}")
    return [entry["name"] for entry in bundled_manifest() if which in ("all", entry["set"])]


def load_bundled(name: str, params=None, cache=None, size: float | None = None) -> ObjectModel:
    """The bundled object ``name`` as an :class:`ObjectModel`.

    The bundled meshes are the paper's objects, stored normalised to a longest side of 6
    and checked, so they are read without re-processing (which keeps their content hash,
    and so their cache entries, stable).

    Parameters
    ----------
    size : float, optional
        Scale the object to this longest side (scene units, e.g. 0.12 for a 12 cm mug in
        a metric scene); None keeps the paper's 6.
    """
    entries = {entry["name"]: entry for entry in bundled_manifest()}
    if name not in entries:
        raise MeshError(name, f"no bundled object of that name; choose from {', '.join(entries)}")
    path = assets_dir() / entries[name]["file"]
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as error:
        raise MeshError(path, f"cannot be read ({error})") from error
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    factor = 1.0
    if size is not None:
        if not (np.isfinite(size) and size > 0):
            raise MeshError(name, f"the size must be a positive length, got {size!r}")
        factor = float(size) / float((vertices.max(axis=0) - vertices.min(axis=0)).max())
        vertices = vertices * factor
    mesh = trimesh.Trimesh(vertices, np.asarray(mesh.faces, dtype=np.int64), process=False)
    return ObjectModel(name, mesh, params, cache, file_to_object=np.diag([factor] * 3 + [1.0]))
