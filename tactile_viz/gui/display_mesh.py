"""Meshes for display: the layers' data sets, and a GPIS surface no finer than the viewport
can show.

A software render (Mesa's llvmpipe, as on a machine without a GPU) costs time for every
triangle, and the window shares its cores with the engine. A GPIS surface is remade every
step from the engine's grid; at a run's last step (a finer grid) it reaches about 25,000
faces. It is drawn with at most :func:`face_budget` triangles, which grants each face
:data:`PIXELS_PER_FACE` pixels of the viewport (a 716 x 825 viewport, that of the default
1500 x 900 window: 11,800 faces): a surface filling the whole view would get faces of about
7 x 7 pixels, and a surface fills a part of the view with half of its faces turned away, so
the detail removed is a few pixels across. Only the display is decimated.

Decimation (vtkDecimatePro) removes vertices and never moves the ones it keeps, so a
decimated surface is a subset of its vertices with new faces over them, and its per-vertex
variance is taken at the kept vertices (the colours cover it as before, and the colour bar
keeps the whole surface's range).

The ground truth and the MAP shape (20,000 faces each for the bundled objects) are not
decimated: halving them saved a few ms of a 35 ms render (neptune, 716 x 825), and the MAP
shape changes class during a run, each new one a 60 ms decimation.
"""

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
