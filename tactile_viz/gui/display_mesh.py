"""Surfaces for display: no more triangles than the viewport can show.

A software render (Mesa's llvmpipe, as on a machine without a GPU) costs time for every
triangle of every translucent surface, and the window shares its cores with the engine: the
ground truth and the MAP shape (20,000 faces each for the bundled objects) and a GPIS surface
from a fine grid (up to about 25,000 faces at a run's last step) are drawn with at most
:func:`face_budget` triangles each. The budget grants each face :data:`PIXELS_PER_FACE`
pixels of the viewport (a 716 x 825 viewport, that of the default 1500 x 900 window: 11,800
faces): a surface filling the whole view would get faces of about 7 x 7 pixels, and an
object fills a part of the view with half of its faces turned away, so the detail removed
is smaller than a few pixels. Only the display is decimated; the engine's meshes are
untouched.

Also the builders of the layers' meshes (triangles, spheres, lines) as pyvista data sets.

Decimation (vtkDecimatePro) removes vertices and never moves the ones it keeps, so a
decimated surface is a subset of its vertices with new faces over them: per-vertex data
(the GPIS variance) is taken at the kept vertices, and a shape that moves rigidly (the MAP
shape: the same model's faces, posed anew each step) is decimated once and then only
indexed (:class:`Decimations`).
"""

import hashlib
from collections import OrderedDict

import numpy as np
import pyvista as pv
from scipy.spatial import cKDTree

PIXELS_PER_FACE = 50
MIN_FACE_BUDGET = 4000  # a small or not yet shown viewport still gets a recognisable shape


def face_budget(width, height):
    """The largest number of triangles drawn for one surface in a ``width`` x ``height``
    pixel viewport."""
    return max(MIN_FACE_BUDGET, int(width) * int(height) // PIXELS_PER_FACE)


def decimation(vertices, faces, budget):
    """Which vertices to keep, and faces over them, so that at most about ``budget`` faces
    remain.

    Parameters
    ----------
    vertices : (n, 3) float array
    faces : (m, 3) int array
        Triangles, indices into ``vertices``.
    budget : int
        Faces wanted; a surface with no more faces is returned whole.

    Returns
    -------
    kept : (k,) int array
        Indices into ``vertices`` of the vertices drawn, increasing.
    faces : (f, 3) int array
        Triangles, indices into ``kept``; ``f`` is at most about ``budget``.
    """
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) <= budget:
        return np.arange(len(vertices)), faces
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    reduced = pv.PolyData(vertices, cells).decimate_pro(
        1.0 - budget / len(faces), preserve_topology=False, splitting=False,
        boundary_vertex_deletion=True)
    # The kept vertices are input vertices (exactly): find their indices.
    _, original = cKDTree(vertices).query(np.asarray(reduced.points), k=1)
    triangles = original[reduced.faces.reshape(-1, 4)[:, 1:]]
    triangles = triangles[(triangles[:, 0] != triangles[:, 1])
                          & (triangles[:, 1] != triangles[:, 2])
                          & (triangles[:, 0] != triangles[:, 2])]
    kept, inverse = np.unique(triangles, return_inverse=True)
    return kept, inverse.reshape(-1, 3)


class Decimations:
    """Decimations of surfaces that come back (the MAP shape of each class, the ground
    truth), by their faces' content, vertex count and budget: each is computed once and the
    vertices of any pose of that surface are then only indexed.

    Parameters
    ----------
    size : int
        Decimations kept (the least recently used go first).
    """

    def __init__(self, size=16):
        self.size = int(size)
        self._cache = OrderedDict()

    def __call__(self, vertices, faces, budget):
        """``(kept, faces)`` as :func:`decimation` returns them."""
        faces = np.ascontiguousarray(faces)
        if len(faces) <= budget:
            return np.arange(len(vertices)), np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        key = (hashlib.blake2b(faces.data, digest_size=16).digest(), faces.shape,
               len(vertices), int(budget))
        found = self._cache.get(key)
        if found is None:
            found = self._cache[key] = decimation(vertices, faces, budget)
            while len(self._cache) > self.size:
                self._cache.popitem(last=False)
        self._cache.move_to_end(key)
        return found


def faces_to_polydata(vertices, faces, normals=False):
    """A ``pv.PolyData`` from (n, 3) vertices and (m, 3) triangle indices, with vertex
    normals for smooth shading if ``normals``."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    mesh = pv.PolyData(vertices, cells)
    if normals:
        mesh.point_data.active_normals = vertex_normals(vertices, faces)
    return mesh


def vertex_normals(vertices, faces):
    """Area-weighted unit vertex normals of a triangle mesh.

    The layers' meshes carry their own normals (rather than pyvista's ``smooth_shading``,
    which puts a filter between the mesh and the mapper) so that a layer's data set can be
    swapped in place.
    """
    triangles = vertices[faces]
    face_normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals = np.zeros_like(vertices)
    for axis in range(3):
        weights = np.repeat(face_normals[:, axis], 3)
        normals[:, axis] = np.bincount(faces.ravel(), weights, minlength=len(vertices))
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.where(length > 0, length, 1.0)


_SPHERE = None


def spheres(points, radius):
    """Small spheres of ``radius`` (scene units) at (k, 3) points, as one mesh."""
    global _SPHERE
    if _SPHERE is None:
        # 8 x 8: 96 triangles a contact (10 x 10: 160); at a contact's size the difference
        # does not show, the software renderer's time on a few hundred contacts does.
        _SPHERE = pv.Sphere(radius=1.0, theta_resolution=8, phi_resolution=8)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    unit = np.asarray(_SPHERE.points)
    cells = _SPHERE.faces.reshape(-1, 4)
    vertices = (points[:, None, :] + radius * unit[None]).reshape(-1, 3)
    offsets = (np.arange(len(points)) * len(unit))[:, None, None]
    faces = (cells[None, :, 1:] + offsets).reshape(-1, 3)
    mesh = faces_to_polydata(vertices, faces)
    mesh.point_data.active_normals = np.tile(unit, (len(points), 1))
    return mesh


def polylines(paths):
    """One ``pv.PolyData`` holding every (k, 3) path as a line."""
    points, cells, offset = [], [], 0
    for path in paths:
        path = np.asarray(path, dtype=float)
        points.append(path)
        cells.append(np.r_[len(path), offset + np.arange(len(path))])
        offset += len(path)
    return pv.PolyData(np.vstack(points), lines=np.concatenate(cells))
