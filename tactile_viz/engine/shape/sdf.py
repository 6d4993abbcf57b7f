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

The grid is built in :mod:`.sdf_build`.
"""

from dataclasses import dataclass
from functools import cached_property

import igl
import numpy as np
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from trimesh.triangles import angles as triangle_angles

# Below this length a gradient is taken to vanish (the medial axis or a flat grid region).
_TINY = 1e-12
PSEUDONORMAL_TOLERANCE = 1e-6  # a barycentric weight under this: on the opposite side
CODE_MAX = 32767  # the largest 16-bit code of a node value
GRADIENT_MAX = 127  # the 8-bit code of a gradient component of 1


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

    def query_near(self, points):
        """:meth:`query` with the sign taken from the closest point's angle-weighted
        pseudonormal (Baerentzen and Aanaes 2005) on a surface where that sign is exact at
        any distance (one closed, manifold piece without degenerate faces; else
        :meth:`query`'s winding number). A pose fit's contacts lie on the surface, where
        the winding number takes ten times the closest points' time."""
        pseudo = self._pseudonormals
        if pseudo is None:
            return self.query(points)
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=np.float64)
        squared, face, closest = self._closest(points)
        mine = self.faces[face]
        normal = _pseudonormal(closest, self.vertices[mine], face, mine, *pseudo)
        inward = np.einsum("ij,ij->i", points - closest, normal) < 0
        distance = np.sqrt(np.maximum(squared, 0.0))
        return np.where(inward, -distance, distance), closest, face

    @cached_property
    def _pseudonormals(self):
        """``(face normals (m, 3), the faces' edge normals (m, 3, 3), vertex normals
        (n, 3))``, angle-weighted and summed over each edge's two faces; None where the
        pseudonormal's sign is not exact (several pieces may overlap, an edge of one face
        or of three has no inside across it, a degenerate face has no normal)."""
        faces, vertices = self.faces, self.vertices
        corners = vertices[faces]
        doubled = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                          corners[:, 2] - corners[:, 0]), axis=1)
        if len(faces) == 0 or not self.closed or doubled.min() <= 1e-12 * doubled.max():
            return None
        ends = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2), axis=2)
        keys = (ends[..., 0] * len(vertices) + ends[..., 1]).reshape(-1)
        unique, edge, count = np.unique(keys, return_inverse=True, return_counts=True)
        pairs = ends.reshape(-1, 2)
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                           shape=(len(vertices),) * 2)
        labels = connected_components(graph, directed=False)[1]
        if np.any(count != 2) or len(np.unique(labels[faces[:, 0]])) != 1:
            return None
        normals = self._face_normals
        edges = np.zeros((len(unique), 3))
        np.add.at(edges, edge, np.repeat(normals, 3, axis=0))
        angles = triangle_angles(corners)
        at_vertices = np.zeros_like(vertices)
        for k in range(3):
            np.add.at(at_vertices, faces[:, k], angles[:, k, None] * normals)
        return normals, edges[edge].reshape(-1, 3, 3), at_vertices

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


def _pseudonormal(closest, corners, face, faces, normals, edges, at_vertices):
    """The pseudonormal at each closest point on its ``face``: the face's inside it, the
    edge's on an edge (edge ``k`` joins corners ``k`` and ``k + 1``, opposite corner
    ``k + 2``), the vertex's at a corner; ``corners`` ``(k, 3, 3)`` and ``faces`` the
    faces' vertex indices ``(k, 3)``."""
    weights = _barycentric(closest, corners)
    on = weights < PSEUDONORMAL_TOLERANCE  # on the side opposite that corner
    result = normals[face].copy()
    single = on.sum(axis=1) == 1
    if single.any():
        opposite = np.argmax(on[single], axis=1)
        result[single] = edges[face[single], (opposite + 1) % 3]
    corner = on.sum(axis=1) >= 2
    if corner.any():
        result[corner] = at_vertices[faces[corner, np.argmax(weights[corner], axis=1)]]
    return result


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
