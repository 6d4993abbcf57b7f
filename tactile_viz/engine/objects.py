"""Object models: a normalised mesh with lazily built, disk-cached derived data.

An :class:`ObjectModel` holds a checked, normalised mesh (object frame). Its exact signed
distance, SDF grid and feature points are built on first use only, and the grid and
features are cached on disk by the mesh's content hash and the parameters that made them.
"""

import json
import os
from dataclasses import asdict, dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import trimesh

from .cache import ArrayCache
from .errors import MeshError
from .features import poisson_disk_points
from .meshes import LONGEST_SIDE, content_hash, load_mesh, prepare_mesh
from .ppf import PairTable
from .sdf import ExactDistance, SDFGrid, build_sdf_grid

ASSETS_ENV_VAR = "TACTILE_VIZ_ASSETS"


@dataclass(frozen=True)
class ModelParams:
    """What the derived data of an object model is built with (speed/accuracy knobs).

    Attributes
    ----------
    sdf_resolution : int
        Voxels along the longest side of the padded SDF grid.
    sdf_padding : float
        Margin of the SDF grid around the bounding box, in object units.
    n_features : int
        Number of Poisson-disk feature points.
    feature_seed : int
        Seed of the feature-point sampling (features are part of the model's identity).
    """

    sdf_resolution: int = 64
    sdf_padding: float = 1.0
    n_features: int = 200
    feature_seed: int = 0


class ObjectModel:
    """A known (or learned) object shape.

    Parameters
    ----------
    name : str
    mesh : trimesh.Trimesh
        Already checked and normalised (see :func:`~tactile_viz.engine.meshes.prepare_mesh`).
    params : ModelParams, optional
    cache : ArrayCache, optional
        Where derived arrays are stored; the default is the user cache folder.
    learned : bool
        The shape was reconstructed by a session rather than given (its feature normals
        come from a reconstruction, so its point-pair poses are coarser).
    """

    def __init__(self, name, mesh, params=None, cache=None, learned=False):
        self.name = str(name)
        self.mesh = mesh
        self.params = params or ModelParams()
        self.cache = cache if cache is not None else ArrayCache()
        self.learned = bool(learned)

    def __repr__(self):
        return f"ObjectModel({self.name!r}, faces={len(self.mesh.faces)})"

    def __getstate__(self):
        # The exact distance holds libigl trees, which do not pickle; it is rebuilt on use.
        state = dict(self.__dict__)
        state.pop("exact", None)
        return state

    @classmethod
    def from_file(cls, path, name=None, params=None, cache=None):
        """Load a mesh file (checked, repaired, normalised); the name defaults to the file stem."""
        mesh = load_mesh(path)
        return cls(name or Path(path).stem, mesh, params, cache)

    @classmethod
    def from_arrays(cls, vertices, faces, name, params=None, cache=None,
                    longest_side=LONGEST_SIDE, learned=False):
        """Build a model from ``(n, 3)`` vertices and ``(m, 3)`` faces (checked and normalised;
        ``longest_side=None`` keeps their size)."""
        return cls(name, prepare_mesh(vertices, faces, source=name, longest_side=longest_side),
                   params, cache, learned)

    def with_params(self, **changes):
        """The same mesh with other :class:`ModelParams` (shares the exact distance)."""
        other = ObjectModel(self.name, self.mesh, replace(self.params, **changes), self.cache,
                            self.learned)
        if "exact" in self.__dict__:
            other.__dict__["exact"] = self.exact
        return other

    def renamed(self, name):
        """The same model under another name."""
        other = ObjectModel(name, self.mesh, self.params, self.cache, self.learned)
        other.__dict__.update({k: v for k, v in self.__dict__.items()
                               if k in ("exact", "sdf", "features", "content_hash")})
        return other

    @property
    def length(self):
        """Longest side of the bounding box (6 after normalisation)."""
        return float(self.mesh.extents.max())

    @cached_property
    def content_hash(self):
        """SHA-256 of the mesh arrays."""
        return content_hash(self.mesh)

    @cached_property
    def exact(self):
        """:class:`~tactile_viz.engine.sdf.ExactDistance` of the mesh."""
        return ExactDistance(self.mesh.vertices, self.mesh.faces)

    @cached_property
    def sdf(self):
        """:class:`~tactile_viz.engine.sdf.SDFGrid`, built on first use and cached on disk."""
        params = {"resolution": self.params.sdf_resolution, "padding": self.params.sdf_padding}
        arrays = self.cache.get_or_build(
            "sdf", self.content_hash, params,
            lambda: build_sdf_grid(self.exact, self.mesh.bounds, **params).to_arrays())
        return SDFGrid.from_arrays(arrays)

    @cached_property
    def features(self):
        """Feature points ``(points, normals)``: (n_features, 3) each, object frame."""
        params = {"count": self.params.n_features, "seed": self.params.feature_seed}
        arrays = self.cache.get_or_build("features", self.content_hash, params, self._build_features)
        return arrays["points"], arrays["normals"]

    def _build_features(self):
        points, faces = poisson_disk_points(self.mesh, self.params.n_features,
                                            rng=self.params.feature_seed)
        # Project onto the surface exactly so normals come from the same place the SDF does.
        _, closest, face = self.exact.query(points)
        return {"points": closest, "normals": self.exact.surface_normal(closest, face)}

    def pair_table(self, distance_step=0.1, angle_step_deg=12.0):
        """The :class:`~tactile_viz.engine.ppf.PairTable` of the feature points (cached)."""
        key = (float(distance_step), float(angle_step_deg))
        tables = self.__dict__.setdefault("_pair_tables", {})
        if key not in tables:
            params = {"distance_step": key[0], "angle_step_deg": key[1],
                      "count": self.params.n_features, "seed": self.params.feature_seed}

            def build():
                points, normals = self.features
                return PairTable.build(points, normals, key[0], np.radians(key[1])).to_arrays()

            tables[key] = PairTable.from_arrays(
                self.cache.get_or_build("pairs", self.content_hash, params, build))
        return tables[key]

    def describe(self):
        """A JSON-ready summary (name, sizes, parameters, hash)."""
        return {"name": self.name, "learned": self.learned, "faces": int(len(self.mesh.faces)),
                "vertices": int(len(self.mesh.vertices)), "content_hash": self.content_hash,
                "params": asdict(self.params)}


def assets_dir():
    """The folder of the bundled object set (``$TACTILE_VIZ_ASSETS`` overrides it)."""
    if os.environ.get(ASSETS_ENV_VAR):
        return Path(os.environ[ASSETS_ENV_VAR])
    return Path(__file__).resolve().parents[2] / "assets"


def bundled_manifest():
    """Entries of the bundled set: a list of dicts with ``name``, ``set``, ``file``, ..."""
    path = assets_dir() / "manifest.json"
    try:
        return json.loads(path.read_text())["objects"]
    except (OSError, ValueError, KeyError) as error:
        raise MeshError(path, f"the bundled object manifest cannot be read ({error})") from error


def bundled_names(which="all"):
    """Names of the bundled objects in ``which`` set: ``"known"``, ``"novel"`` or ``"all"``."""
    if which not in ("known", "novel", "all"):
        raise ValueError(f"which must be 'known', 'novel' or 'all', not {which!r}")
    return [entry["name"] for entry in bundled_manifest() if which in ("all", entry["set"])]


def load_bundled(name, params=None, cache=None):
    """The bundled object ``name`` as an :class:`ObjectModel`.

    The bundled meshes are stored normalised and checked, so they are read without
    re-processing (which keeps their content hash, and so their cache entries, stable).
    """
    entries = {entry["name"]: entry for entry in bundled_manifest()}
    if name not in entries:
        raise MeshError(name, f"no bundled object of that name; choose from {', '.join(entries)}")
    path = assets_dir() / entries[name]["file"]
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as error:
        raise MeshError(path, f"cannot be read ({error})") from error
    mesh = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64),
                           np.asarray(mesh.faces, dtype=np.int64), process=False)
    return ObjectModel(name, mesh, params, cache)
