"""Signed distance fields of object models.

Two kinds, both with negative values inside:

- :class:`ExactDistance` asks libigl for the exact distance to the mesh (AABB tree) and
  the sign from the fast winding number, so it is robust on meshes that are not perfectly
  watertight. It is the ground truth for the simulator and the tests.
- :class:`SDFGrid` samples that field once on a regular grid over the padded bounding box,
  stores it in 5 bytes a node and interpolates trilinearly: value and gradient at any point
  in a few array operations. Outside the grid it falls back to the distance to the box plus
  the value at the clamped point, which is always positive. :func:`interpolate` does the
  same for many grids stored one after another (the prior bank).

Building a grid asks the winding number only where the sign can change: on a closed
surface (every edge in both directions) the winding number is the same all over a region
of nodes farther than a voxel from the surface and joined through such nodes, so one node
(two, as a check) of each region answers for all of it. A cup's grid took half its time
in winding numbers, in its cavity; the signs are those of asking every node (every
bundled object's grid and the tests' are the same bytes).
"""

from dataclasses import dataclass
from functools import cached_property

import igl
import numpy as np
from numba import njit
from scipy import ndimage

# Below this length a gradient is taken to vanish (the medial axis or a flat grid region).
_TINY = 1e-12
CODE_MAX = 32767  # the largest 16-bit code of a node value
GRADIENT_MAX = 127  # the 8-bit code of a gradient component of 1
# Grid nodes per distance query of a grid build: the query's closest points (24 bytes a
# node) are not kept, so a 2-million-node grid needs some 10 MB for them, not 50.
_GRID_BATCH = 1 << 18
# A banded grid's coarsest level is exact everywhere (16 voxels a side: 5,000 nodes or so).
_COARSEST = 17
_FAR_VOXELS = 1.001  # nodes farther than this from the surface share their region's sign
# A grid is fine enough when at most this share of surface points sees its gradient more
# than 60 degrees off the surface normal (the bundled objects: at most 0.5% at 64 voxels;
# a fork's 2 mm tines on a 20 cm fork: 11%, and 0 at 128).
THIN_MISSES = 0.01
MISS_COSINE = 0.5
# The finest grid a thin part may ask for: about 10 MB (a compact object at 128 voxels).
MAX_REFINED_NODES = 2_100_000


def normalise_rows(vectors, fallback=(0.0, 0.0, 1.0)):
    """Unit-length rows; rows of (near) zero length become ``fallback``.

    Parameters
    ----------
    vectors : (n, 3) float

    Returns
    -------
    (n, 3) float
    """
    vectors = np.asarray(vectors, dtype=float)
    norms = np.linalg.norm(vectors, axis=-1, keepdims=True)
    safe = np.where(norms > _TINY, norms, 1.0)
    return np.where(norms > _TINY, vectors / safe, np.asarray(fallback, dtype=float))


class ExactDistance:
    """Exact signed distance to a triangle mesh with cached acceleration structures.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    """

    def __init__(self, vertices, faces):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self._tree = igl.AABB()
        self._tree.init(self.vertices, self.faces)
        normals = np.cross(self.vertices[self.faces[:, 1]] - self.vertices[self.faces[:, 0]],
                           self.vertices[self.faces[:, 2]] - self.vertices[self.faces[:, 0]])
        self._face_normals = normalise_rows(normals)
        self._vertex_normals = _area_weighted_vertex_normals(self.vertices, self.faces, normals)

    @cached_property
    def _winding(self):
        """The inside test's tree, built when a sign is first asked for."""
        winding = igl.FastWindingNumberBVH()
        winding.init(self.vertices, self.faces)
        return winding

    def query(self, points):
        """Signed distance, closest surface point and face index.

        Parameters
        ----------
        points : (k, 3) float, object frame

        Returns
        -------
        distance : (k,) float
        closest : (k, 3) float
        face : (k,) int
        """
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)
        squared, face, closest = self._closest(points)
        inside = self.inside(points)
        distance = np.sqrt(np.maximum(squared, 0.0))
        return np.where(inside, -distance, distance), closest, face

    def inside(self, points):
        """Whether each of ``(k, 3)`` points is inside: a winding number over 1/2.

        Asked only inside the mesh's bounding box: a point outside it sees the whole
        surface within less than a half space, a solid angle under 2 pi, so its winding
        number is below 1/2 (most of a decision's free-space points lie there)."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)
        low, high = self.bounds
        within = np.all((points >= low) & (points <= high), axis=1)
        result = np.zeros(len(points), dtype=bool)
        if within.any():
            result[within] = self._winding.winding_number(
                np.ascontiguousarray(points[within])) > 0.5
        return result

    @cached_property
    def bounds(self):
        """The mesh's axis-aligned bounding box: ``(low (3,), high (3,))``, object frame."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    @cached_property
    def closed(self):
        """Whether the surface bounds its inside: each edge is as often a face's a->b as
        another's b->a. Then the winding number changes only across the surface."""
        a, b = self.faces, np.roll(self.faces, -1, axis=1)
        count = len(self.vertices)
        forward = np.sort((a * count + b).reshape(-1))
        backward = np.sort((b * count + a).reshape(-1))
        return bool(np.array_equal(forward, backward))

    def _closest(self, points):
        # libigl splits the points over every core itself (IGL_NUM_THREADS); its Python
        # binding holds the GIL meanwhile, so threads of ours would only wait for it.
        return self._tree.squared_distance(self.vertices, self.faces, points)

    def closest_points(self, points):
        """:meth:`query`'s closest surface points and faces, ``(k, 3)`` and ``(k,)``, without
        its inside test (a point on the surface costs the winding number the most)."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)
        _, face, closest = self._closest(points)
        return closest, face

    def signed_distance(self, points):
        """Signed distance only: (k,) float for (k, 3) points."""
        return self.query(points)[0]

    def nearest_face(self, points):
        """:meth:`query`'s distance unsigned and its face, ``(k,)`` each: without the
        inside test, whose winding numbers take ten times the closest points' time."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)
        squared, face, _ = self._closest(points)
        return np.sqrt(np.maximum(squared, 0.0)), face

    def face_normal(self, face):
        """Outward unit normals of faces: (k, 3) float for (k,) face indices."""
        return self._face_normals[face]

    def surface_normal(self, closest, face):
        """Outward unit normal at surface points, interpolated from the vertex normals.

        Parameters
        ----------
        closest : (k, 3) float
            Points on the surface.
        face : (k,) int
            The face each point lies on.

        Returns
        -------
        (k, 3) float
        """
        corners = self.vertices[self.faces[face]]
        weights = _barycentric(closest, corners)
        normals = np.einsum("kc,kcd->kd", weights, self._vertex_normals[self.faces[face]])
        return normalise_rows(normals, fallback=(0.0, 0.0, 1.0))


@dataclass(frozen=True, eq=False)
class SDFGrid:
    """A signed distance field sampled on a regular grid, object frame, stored compactly.

    The node values are 16-bit integers in steps of ``value_step`` (a 65,535th of the
    largest magnitude, some 1e-4 of a voxel near the surface at the default resolution) and
    the central-difference gradients 8-bit integers in steps of 1/127 (a distance field's
    gradient components lie in [-1, 1]): 5 bytes a node instead of the 32 of a float64
    value and gradient (docs/priors-at-scale.md measures the errors against the exact
    distance).

    Attributes
    ----------
    origin : (3,) float
        Position of grid node ``(0, 0, 0)``.
    spacing : float
        Distance between neighbouring nodes (the voxel size).
    codes : (nx, ny, nz) int16
        Node values in units of ``value_step``.
    value_step : float
    gradient_codes : (nx, ny, nz, 3) int8
        Node gradients in units of 1/127.
    """

    origin: np.ndarray
    spacing: float
    codes: np.ndarray
    value_step: float
    gradient_codes: np.ndarray

    @classmethod
    def from_values(cls, origin, spacing, values):
        """Encode float node values ``(nx, ny, nz)`` and their central-difference
        gradients."""
        values = np.asarray(values, dtype=float)
        step = max(float(np.abs(values).max()), _TINY) / CODE_MAX
        codes = np.clip(np.rint(values / step), -CODE_MAX, CODE_MAX).astype(np.int16)
        gradient_codes = np.empty(values.shape + (values.ndim,), np.int8)
        for axis in range(values.ndim):  # one float array at a time, not a stack of three
            gradient = np.gradient(values, float(spacing), axis=axis)
            gradient_codes[..., axis] = np.clip(np.rint(gradient * GRADIENT_MAX),
                                                -GRADIENT_MAX, GRADIENT_MAX)
        return cls(np.asarray(origin, dtype=float), float(spacing), codes, step,
                   gradient_codes)

    @property
    def shape(self):
        return self.codes.shape

    @property
    def values(self):
        """(nx, ny, nz) float: the decoded node values."""
        return self.codes * self.value_step

    @property
    def nbytes(self):
        return self.codes.nbytes + self.gradient_codes.nbytes

    @property
    def upper(self):
        """(3,) float: position of the last grid node."""
        return self.origin + self.spacing * (np.array(self.shape) - 1)

    def evaluate(self, points):
        """Signed distance and outward unit gradient at points.

        Parameters
        ----------
        points : (..., 3) float, object frame

        Returns
        -------
        values : (...) float
        gradients : (..., 3) float, unit length
        """
        return interpolate(self.codes.reshape(-1), self.gradient_codes.reshape(-1, 3), 0,
                           np.array(self.shape), self.origin, self.spacing, self.value_step,
                           np.asarray(points, dtype=float))

    def distance(self, points):
        """Signed distance only: (...) float for (..., 3) points."""
        return self.evaluate(points)[0]

    def to_arrays(self):
        """The grid as a dict of arrays (for ``np.savez``)."""
        return {"origin": self.origin, "spacing": np.array(self.spacing), "codes": self.codes,
                "value_step": np.array(self.value_step), "gradient_codes": self.gradient_codes}

    @classmethod
    def from_arrays(cls, arrays):
        """Inverse of :meth:`to_arrays`."""
        return cls(origin=np.asarray(arrays["origin"], dtype=float),
                   spacing=float(arrays["spacing"]),
                   codes=np.asarray(arrays["codes"], dtype=np.int16),
                   value_step=float(arrays["value_step"]),
                   gradient_codes=np.asarray(arrays["gradient_codes"], dtype=np.int8))


def interpolate(codes, gradient_codes, offset, shape, origin, spacing, value_step, points):
    """Trilinear value and unit gradient of grids stored one after another.

    Every argument but the codes broadcasts against the points: the grid of a point starts
    at ``codes[offset]`` (and ``gradient_codes[offset]``), has ``shape`` nodes from
    ``origin`` at ``spacing``, and its values are ``codes * value_step``. Outside its grid
    a point's value is the value at the clamped point plus the distance to it, always
    positive, and its gradient points away from the grid.

    Parameters
    ----------
    codes : (total,) int16
    gradient_codes : (total, 3) int8
    offset : (...) int
    shape : (..., 3) int
    origin : (..., 3) float
    spacing, value_step : (...) float
    points : (..., 3) float, each grid's frame

    Returns
    -------
    values : (...) float
    gradients : (..., 3) float, unit length
    """
    points = np.asarray(points, dtype=float)
    lead = np.broadcast_shapes(points.shape[:-1], np.shape(offset), np.shape(shape)[:-1],
                               np.shape(origin)[:-1], np.shape(spacing), np.shape(value_step))
    count = int(np.prod(lead))

    def per_point(array, dtype, tail=()):
        array = np.broadcast_to(np.asarray(array, dtype=dtype), lead + tail)
        return np.ascontiguousarray(array.reshape((count,) + tail))

    values, gradients = np.empty(count), np.empty((count, 3))
    _interpolate(np.ascontiguousarray(codes).reshape(-1),
                 np.ascontiguousarray(gradient_codes).reshape(-1, 3),
                 per_point(offset, np.int64), per_point(shape, np.int64, (3,)),
                 per_point(origin, float, (3,)), per_point(spacing, float),
                 per_point(value_step, float), per_point(points, float, (3,)), _TINY,
                 values, gradients)
    return values.reshape(lead), gradients.reshape(lead + (3,))


@njit(cache=True, inline="always")
def grid_lookup(codes, gradient_codes, offset, shape, origin, spacing, step, x, y, z):
    """Value and unnormalised gradient of one grid at one point: :func:`interpolate`'s
    terms, each rounded as its numpy expressions were (no fastmath; the prior bank's
    likelihood loops use it too)."""
    px, py, pz = x, y, z
    upper = (origin[0] + spacing * (shape[0] - 1), origin[1] + spacing * (shape[1] - 1),
             origin[2] + spacing * (shape[2] - 1))
    cx = min(max(px, origin[0]), upper[0])
    cy = min(max(py, origin[1]), upper[1])
    cz = min(max(pz, origin[2]), upper[2])
    fx = (cx - origin[0]) / spacing
    fy = (cy - origin[1]) / spacing
    fz = (cz - origin[2]) / spacing
    ix = min(int(fx), shape[0] - 2)
    iy = min(int(fy), shape[1] - 2)
    iz = min(int(fz), shape[2] - 2)
    fx -= ix
    fy -= iy
    fz -= iz
    nz = shape[2]
    nyz = shape[1] * nz
    base = offset + ix * nyz + iy * nz + iz
    value = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for dx in range(2):
        wx = fx if dx else 1.0 - fx
        for dy in range(2):
            wy = fy if dy else 1.0 - fy
            for dz in range(2):
                w = wx * wy * (fz if dz else 1.0 - fz)
                corner = base + dx * nyz + dy * nz + dz
                value += w * codes[corner]
                gx += w * gradient_codes[corner, 0]
                gy += w * gradient_codes[corner, 1]
                gz += w * gradient_codes[corner, 2]
    ox, oy, oz = px - cx, py - cy, pz - cz
    outside = np.sqrt(ox * ox + oy * oy + oz * oz)
    value = value * step + outside
    if outside > 0:
        gx, gy, gz = ox / outside, oy / outside, oz / outside
    return value, gx, gy, gz


@njit(cache=True)
def _interpolate(codes, gradient_codes, offset, shape, origin, spacing, value_step, points,
                 tiny, values, gradients):
    """:func:`interpolate` of (n, 3) points by :func:`grid_lookup`, each gradient made unit
    as :func:`normalise_rows` makes it."""
    for i in range(len(points)):
        value, gx, gy, gz = grid_lookup(codes, gradient_codes, offset[i], shape[i], origin[i],
                                        spacing[i], value_step[i], points[i, 0], points[i, 1],
                                        points[i, 2])
        values[i] = value
        norm = np.sqrt(gx * gx + gy * gy + gz * gz)
        if norm > tiny:
            gradients[i, 0], gradients[i, 1], gradients[i, 2] = gx / norm, gy / norm, gz / norm
        else:
            gradients[i, 0], gradients[i, 1], gradients[i, 2] = 0.0, 0.0, 1.0


def build_sdf_grid(exact, bounds, resolution=64, padding=1.0, band=0.0):
    """Sample a signed distance on a regular grid over a padded box.

    Parameters
    ----------
    exact : ExactDistance
    bounds : (2, 3) float
        The object's axis-aligned bounding box.
    resolution : int
        Number of voxels along the longest side of the padded box.
    padding : float
        Margin added on every side of the box.
    band : float, voxels
        0: the exact distance at every node. Otherwise exact only at the nodes that may
        lie within ``band`` voxels of the surface, the rest interpolated
        (:func:`banded_distance`); the signs are exact either way.

    Returns
    -------
    SDFGrid
    """
    origin, spacing, counts = grid_layout(bounds, resolution, padding)
    shape = tuple(int(n) for n in counts)
    nodes = _node_positions(origin, spacing, shape)
    if band > 0:
        distance = banded_distance(exact, origin, spacing, shape, band).reshape(-1)
    else:
        distance = _exact_distance(exact, nodes, np.arange(int(np.prod(shape))))
    inside = _grid_inside(exact, nodes, distance, shape, spacing)
    values = np.where(inside, -distance, distance).reshape(shape)
    return SDFGrid.from_values(origin, spacing, values)


def _node_positions(origin, spacing, shape):
    """``nodes(index)``: the (k, 3) positions of flat node indices (C order)."""
    axes = [origin[i] + spacing * np.arange(shape[i]) for i in range(3)]

    def nodes(index):
        index = np.unravel_index(index, shape)
        return np.column_stack([axis[i] for axis, i in zip(axes, index)])

    return nodes


def _exact_distance(exact, nodes, index):
    """Unsigned exact distances at the flat node indices ``index``, a batch at a time."""
    distance = np.empty(len(index))
    for start in range(0, len(index), _GRID_BATCH):
        batch = slice(start, start + _GRID_BATCH)
        squared = exact._closest(nodes(index[batch]))[0]  # the closest points not kept
        distance[batch] = np.sqrt(np.maximum(squared, 0.0))
    return distance


def banded_distance(exact, origin, spacing, shape, band, coarsest=_COARSEST):
    """Unsigned distance on a grid, exact within ``band`` voxels of the surface.

    A grid of twice the spacing is built first (the same way, down to ``coarsest`` voxels
    a side, which is exact everywhere) and interpolated trilinearly at this grid's nodes.
    A distance changes by at most the distance moved, so a node whose coarse neighbour's
    lower bound less the way to it is still ``band`` voxels or more is far from the surface
    and keeps the interpolated value; every other node is asked exactly. Far nodes cost
    the exact query the most (a 16,000-face cup refined to 128 voxels: 5.5 s of closest
    points against 1.7 s with a band of 4); their values are off by at most some 17% of
    the distance (the seams of a concave field), none within the band.

    Parameters
    ----------
    exact : ExactDistance
    origin : (3,) float
    spacing : float
    shape : (3,) int
    band : float, voxels
    coarsest : int
        Nodes along the longest side at or below which the grid is exact everywhere.

    Returns
    -------
    (nx, ny, nz) float
    """
    return _banded(exact, np.asarray(origin, float), float(spacing), tuple(shape), band,
                   coarsest)[0]


def _banded(exact, origin, spacing, shape, band, coarsest):
    """:func:`banded_distance` and a lower bound of the distance at each node."""
    nodes = _node_positions(origin, spacing, shape)
    if max(shape) <= coarsest:
        distance = _exact_distance(exact, nodes, np.arange(int(np.prod(shape))))
        distance = distance.reshape(shape)
        return distance, distance
    coarse_shape = tuple(n // 2 + 1 for n in shape)  # coarse node i is this grid's 2i
    coarse, coarse_low = _banded(exact, origin, 2 * spacing, coarse_shape, band, coarsest)
    value = _upsampled(coarse, shape)
    # The coarse node at (i // 2, j // 2, k // 2) lies one spacing away along each odd
    # index: the distance here is at least its lower bound less that way.
    odd = sum((np.arange(n, dtype=np.uint8) % 2).reshape([-1 if axis == a else 1
                                                          for a in range(3)])
              for axis, n in enumerate(shape))
    low = coarse_low[_halves(shape)] - spacing * np.sqrt(np.arange(4.0))[odd]
    near = np.flatnonzero(low < band * spacing)
    exact_values = _exact_distance(exact, nodes, near)
    value.reshape(-1)[near] = exact_values
    low.reshape(-1)[near] = exact_values
    return value, low


def _halves(shape):
    """Index arrays that pick coarse node (i // 2, j // 2, k // 2) for each node."""
    return np.ix_(*(np.arange(n) // 2 for n in shape))


def _upsampled(coarse, shape):
    """Trilinear values at the nodes of a grid of half the spacing, ``shape`` nodes: axis by
    axis, even nodes the coarse ones, odd nodes the mean of their two neighbours."""
    values = coarse
    for axis, n in enumerate(shape):
        lower = np.take(values, np.arange(n) // 2, axis=axis)
        upper = np.take(values, (np.arange(n) + 1) // 2, axis=axis)
        values = 0.5 * (lower + upper)
    return np.ascontiguousarray(values)


def _grid_inside(exact, nodes, distance, shape, spacing):
    """Whether each grid node is inside (:meth:`ExactDistance.inside`), from winding
    numbers at the nodes within a voxel of a closed surface and at two nodes of each region
    of the others (see the module's docstring); a region whose two disagree is asked
    node by node, as is every node of a surface that is not closed."""
    inside = np.empty(len(distance), bool)

    def ask(index):
        for start in range(0, len(index), _GRID_BATCH):
            batch = index[start:start + _GRID_BATCH]
            inside[batch] = exact.inside(nodes(batch))

    if not exact.closed:
        ask(np.arange(len(distance)))
        return inside
    # Two neighbours (a voxel apart) of which one is farther than a voxel from the
    # surface have no surface between them: their winding numbers are the same.
    labels, count = ndimage.label((distance > _FAR_VOXELS * spacing).reshape(shape))
    labels = labels.reshape(-1)
    ask(np.flatnonzero(labels == 0))
    if count:
        first = np.unique(labels, return_index=True)[1][1:]
        last = len(labels) - 1 - np.unique(labels[::-1], return_index=True)[1][1:]
        region = np.concatenate([[False], exact.inside(nodes(first))])
        far = np.flatnonzero(labels)
        inside[far] = region[labels[far]]
        unsure = np.flatnonzero(region[1:] != exact.inside(nodes(last))) + 1
        if len(unsure):
            ask(np.flatnonzero(np.isin(labels, unsure)))
    return inside


def missed_share(grid, points, normals):
    """Share of surface points at which a grid's gradient is more than 60 degrees off the
    surface normal: parts thinner than about two voxels, whose field the grid folds.

    Parameters
    ----------
    grid : SDFGrid
    points, normals : (n, 3) float, object frame
        Points on the surface and their outward unit normals.

    Returns
    -------
    float
    """
    _, gradients = grid.evaluate(points)
    return float(np.mean(np.einsum("ij,ij->i", gradients, normals) < MISS_COSINE))


def fitted_resolution(grid_at, bounds, padding, points, normals, resolution, max_resolution):
    """The coarsest grid resolution, doubling from ``resolution``, that resolves a shape's
    thin parts (:func:`missed_share` at most :data:`THIN_MISSES`), at most ``max_resolution``
    voxels and :data:`MAX_REFINED_NODES` nodes; the finest allowed if none does.

    Parameters
    ----------
    grid_at : callable
        ``grid_at(resolution) -> SDFGrid`` (built or read from a cache).
    bounds : (2, 3) float
    padding : float
    points, normals : (n, 3) float
        Surface samples and their outward unit normals, object frame.
    resolution, max_resolution : int

    Returns
    -------
    int
    """
    while missed_share(grid_at(resolution), points, normals) > THIN_MISSES:
        finer = 2 * resolution
        nodes = np.prod(grid_layout(bounds, finer, padding)[2])
        if finer > max_resolution or nodes > MAX_REFINED_NODES:
            break
        resolution = finer
    return resolution


def grid_layout(bounds, resolution=64, padding=1.0):
    """Where :func:`build_sdf_grid` puts its nodes: ``origin`` (3,), ``spacing`` and
    ``counts`` (3,) int."""
    low = np.asarray(bounds[0], dtype=float) - padding
    high = np.asarray(bounds[1], dtype=float) + padding
    spacing = float((high - low).max()) / int(resolution)
    counts = np.ceil((high - low) / spacing - 1e-9).astype(int) + 1
    # Centre the nodes on the box so the object sits symmetrically in the grid.
    origin = (low + high) / 2 - spacing * (counts - 1) / 2
    return origin, spacing, counts


def _area_weighted_vertex_normals(vertices, faces, face_normals_unscaled):
    normals = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals_unscaled)
    return normalise_rows(normals)


def _barycentric(points, corners):
    """Barycentric weights (k, 3) of points (k, 3) in triangles (k, 3, 3)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    denominator = d00 * d11 - d01 * d01
    safe = np.where(np.abs(denominator) > _TINY, denominator, 1.0)
    v = np.where(np.abs(denominator) > _TINY, (d11 * d20 - d01 * d21) / safe, 1 / 3)
    w = np.where(np.abs(denominator) > _TINY, (d00 * d21 - d01 * d20) / safe, 1 / 3)
    weights = np.stack([1 - v - w, v, w], axis=1)
    return np.clip(weights, 0.0, 1.0)
