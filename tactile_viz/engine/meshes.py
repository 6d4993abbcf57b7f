"""Load, check, repair and normalise triangle meshes.

Every object model starts here: :func:`load_mesh` reads any file trimesh reads and
:func:`prepare_mesh` turns raw arrays into a clean, watertight, outward-oriented mesh
centred at the origin with its longest bounding-box side equal to ``LONGEST_SIDE``.
Faults that can be repaired are repaired (duplicate vertices, degenerate or duplicate
faces, inconsistent winding, inverted orientation, small holes); faults that cannot raise
:class:`~tactile_viz.engine.errors.MeshError` naming the source and the reason.
"""

import hashlib
import os
import warnings

import numpy as np
import trimesh

from .errors import MeshError, MeshWarning

LONGEST_SIDE = 6.0
SUPPORTED_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
# A hole is closed by a fan of triangles only when the patch is a small part of the surface;
# a larger opening means the file is an open scan or sheet whose inside is a guess.
MAX_HOLE_AREA_FRACTION = 0.05
# Meshes with more faces are decimated to DECIMATED_FACES (with a MeshWarning): the filter
# sees an object through a 64^3 SDF grid, and the exact distance, the grid and the
# viewport cost time in proportion to the faces. A 2-million-face mesh loads in about 20 s
# on a 2-core machine this way, against about 45 s for the same mesh kept whole (6 s to
# load plus 40 s for its exact distance and SDF grid on first use).
MAX_FACES = 500_000
DECIMATED_FACES = 200_000


def load_mesh(path, longest_side=LONGEST_SIDE, max_faces=MAX_FACES):
    """Read a mesh file and return it checked, repaired and normalised.

    Parameters
    ----------
    path : str or os.PathLike
        An OBJ, PLY, STL, OFF or GLB file (anything trimesh reads as triangles).
    longest_side : float
        Length of the longest side of the normalised bounding box.
    max_faces : int or None
        Meshes with more faces are decimated to ``DECIMATED_FACES`` with a
        :class:`~tactile_viz.engine.errors.MeshWarning`; ``None`` keeps every face.

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward oriented, object frame.

    Raises
    ------
    MeshError
        If the file is missing, empty, unreadable, or its mesh cannot be repaired.
    """
    path = os.fspath(path)
    name = os.path.basename(path) or path
    if not os.path.isfile(path):
        raise MeshError(path, "no such file")
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise MeshError(name, f"unsupported file type {suffix or '(none)'!r}; "
                              f"use one of {', '.join(SUPPORTED_SUFFIXES)}")
    if os.path.getsize(path) == 0:
        raise MeshError(name, "the file is empty")
    if suffix == ".stl":
        _check_binary_stl_size(path, name)
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as error:  # trimesh raises many types on bad bytes
        raise MeshError(name, f"cannot be read as {suffix[1:].upper()} ({error})") from error
    vertices = getattr(loaded, "vertices", None)
    faces = getattr(loaded, "faces", None)
    if vertices is None or faces is None or len(faces) == 0:
        raise MeshError(name, "the file holds no triangles")
    return prepare_mesh(vertices, faces, source=name, longest_side=longest_side,
                        max_faces=max_faces)


def prepare_mesh(vertices, faces, source="arrays", longest_side=LONGEST_SIDE,
                 max_faces=MAX_FACES):
    """Check, repair and normalise a mesh given as arrays.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    source : str
        Named in error messages.
    longest_side : float or None
        Scale so that the longest side of the bounding box has this length; None keeps the
        size (only recentres), as for a learned shape measured in world units.
    max_faces : int or None
        See :func:`load_mesh`.

    Returns
    -------
    trimesh.Trimesh
    """
    vertices, faces = _checked_arrays(vertices, faces, source)
    vertices = _normalised_vertices(vertices, faces, source, longest_side)
    mesh = trimesh.Trimesh(vertices, faces, process=True, validate=False)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise MeshError(source, "every face is degenerate (zero area)")
    trimesh.repair.fix_winding(mesh)
    if not mesh.is_watertight:
        _close_holes(mesh, source)
    if not mesh.is_watertight:
        raise MeshError(source, "not watertight and could not be repaired "
                                "(edges shared by more than two faces)")
    trimesh.repair.fix_winding(mesh)
    if not mesh.is_winding_consistent:
        raise MeshError(source, "face winding is inconsistent (the surface is not orientable)")
    if mesh.volume < 0:
        mesh.invert()
    if mesh.volume <= 1e-6 * float(mesh.extents.max())**3:
        raise MeshError(source, "encloses no volume (a flat or degenerate surface)")
    # Repairs move the box a little; recentre so the object frame stays the box centre.
    # Vertices are kept float32-exact so saving to PLY and reading back changes nothing.
    centred = mesh.vertices - mesh.bounds.mean(axis=0)
    mesh.vertices = centred.astype(np.float32).astype(np.float64)
    if max_faces is not None and len(mesh.faces) > max_faces:
        return _decimated(mesh, source, longest_side, max_faces)
    return mesh


def _decimated(mesh, source, longest_side, max_faces):
    """The mesh decimated to ``DECIMATED_FACES`` (edge collapses, libigl), checked again.

    If decimation fails or breaks the surface, the full mesh is kept; either way a
    :class:`MeshWarning` says what happened.
    """
    import igl

    target = min(DECIMATED_FACES, max_faces)
    try:
        vertices, faces, _, _ = igl.decimate(np.asfortranarray(mesh.vertices),
                                             np.asfortranarray(mesh.faces, dtype=np.int32),
                                             target)
        smaller = prepare_mesh(vertices, faces, source, longest_side, max_faces=None)
    except (MeshError, ValueError, RuntimeError, TypeError) as error:
        warnings.warn(MeshWarning(f"{source}: {len(mesh.faces)} faces exceed {max_faces} but "
                                  f"decimation failed ({error}); every face is kept"),
                      stacklevel=3)
        return mesh
    warnings.warn(MeshWarning(f"{source}: decimated from {len(mesh.faces)} to "
                              f"{len(smaller.faces)} faces (more than {max_faces})"),
                  stacklevel=3)
    smaller.metadata["decimated_from"] = int(len(mesh.faces))
    return smaller


def content_hash(mesh):
    """SHA-256 hex digest of a mesh's vertex and face arrays (its identity in caches)."""
    digest = hashlib.sha256()
    digest.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return digest.hexdigest()


def _check_binary_stl_size(path, name):
    """trimesh reads a cut-off binary STL as an empty mesh; say what is wrong instead."""
    with open(path, "rb") as stream:
        header = stream.read(84)
    if header[:5].lower() == b"solid" or len(header) < 84:
        return  # ASCII STL (or too short to be binary): the reader judges it
    count = int.from_bytes(header[80:84], "little")
    size = os.path.getsize(path)
    if size < 84 + 50 * count:
        raise MeshError(name, f"truncated binary STL: the header announces {count} triangles "
                              f"but the file holds {(size - 84) // 50}")


def check_arrays(vertices, faces, source="arrays"):
    """Vertices and faces read back from storage, checked but not repaired or moved.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int

    Returns
    -------
    vertices : (n, 3) float64
    faces : (m, 3) int64

    Raises
    ------
    MeshError
        Wrong shapes or types, no faces, indices out of range, or non-finite vertices
        (which would make the exact distance read out of bounds or return NaN).
    """
    return _checked_arrays(vertices, faces, source)


def _checked_arrays(vertices, faces, source):
    try:
        vertices = np.asarray(vertices, dtype=np.float64)
        faces = np.asarray(faces)
    except (TypeError, ValueError) as error:
        raise MeshError(source, f"vertices or faces are not numeric arrays ({error})") from error
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise MeshError(source, f"vertices must have shape (n, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise MeshError(source, f"faces must have shape (m, 3), got {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise MeshError(source, f"faces must be integer indices, got {faces.dtype}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(source, "faces index vertices that do not exist")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshError(source, f"{int(bad.sum())} of {len(vertices)} vertices are not finite (NaN or inf)")
    return vertices, faces.astype(np.int64)


def _normalised_vertices(vertices, faces, source, longest_side):
    used = vertices[np.unique(faces)]
    low, high = used.min(axis=0), used.max(axis=0)
    size = float((high - low).max())
    # Relative to the coordinates' magnitude: a mesh 1e-9 units across is only small, but
    # one 1e-9 across at 1e6 from the origin has lost its shape to rounding.
    with np.errstate(over="ignore", divide="ignore"):
        target = size if longest_side is None else longest_side
        factor = target / size if size > 0 else np.inf
    if not np.isfinite(factor) or size <= 1e-12 * float(np.abs(used).max()):
        raise MeshError(source, "degenerate: all vertices coincide")
    return (vertices - (low + high) / 2) * factor


def _close_holes(mesh, source):
    """Fill each open boundary loop with a fan around its centroid, if the loops are simple."""
    loops = _boundary_loops(mesh, source)
    new_vertices, new_faces = [], []
    next_index = len(mesh.vertices)
    for loop in loops:
        centre = mesh.vertices[loop].mean(axis=0)
        # Boundary edges run a->b in their face; the patch must use them as b->a.
        for a, b in zip(loop, np.roll(loop, -1)):
            new_faces.append((b, a, next_index))
        new_vertices.append(centre)
        next_index += 1
    patch = trimesh.Trimesh(np.vstack([mesh.vertices, new_vertices]), new_faces, process=False)
    patch_area = patch.area
    if patch_area > MAX_HOLE_AREA_FRACTION * mesh.area:
        raise MeshError(source, f"has {len(loops)} open hole(s) too large to close "
                                f"(they would add {100 * patch_area / mesh.area:.0f}% "
                                "of the surface)")
    repaired = trimesh.Trimesh(patch.vertices, np.vstack([mesh.faces, new_faces]), process=True)
    mesh.vertices, mesh.faces = repaired.vertices, repaired.faces


def _boundary_loops(mesh, source):
    """Directed boundary loops (vertex index arrays) of a mesh with consistent winding."""
    edges = mesh.edges  # directed, three per face, in face order
    keys = mesh.edges_sorted
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    if (counts > 2).any():
        raise MeshError(source, f"not watertight and not repairable: {int((counts > 2).sum())} "
                                "edges are shared by more than two faces (non-manifold)")
    boundary = edges[counts[inverse.ravel()] == 1]
    outgoing = {}
    for a, b in boundary:
        outgoing.setdefault(int(a), []).append(int(b))
    # Decompose the directed boundary into closed cycles; a vertex where two holes touch
    # simply starts or ends two cycles.
    loops = []
    while outgoing:
        start = next(iter(outgoing))
        loop, vertex = [start], _pop_successor(outgoing, start)
        while vertex != start:
            if vertex not in outgoing:
                raise MeshError(source, "not watertight and not repairable: an open boundary "
                                        "does not close into a loop")
            loop.append(vertex)
            vertex = _pop_successor(outgoing, vertex)
        loops.append(np.array(loop))
    return loops


def _pop_successor(outgoing, vertex):
    successors = outgoing[vertex]
    following = successors.pop()
    if not successors:
        del outgoing[vertex]
    return following
