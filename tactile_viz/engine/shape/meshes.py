"""Load, check, repair and normalise triangle meshes.

Every object model starts here: :func:`load_mesh` reads any file trimesh reads and
:func:`prepare_mesh` turns raw arrays into a clean, watertight, outward-oriented mesh
centred at the origin. A mesh keeps its size (times an optional unit factor, see
:func:`unit_factor`) unless it is normalised to a given longest side, as the paper
normalises every object to ``LONGEST_SIDE``. The similarity from the file's coordinates to
the object frame is kept in ``mesh.metadata["file_to_object"]`` (4x4), so that poses map back
onto the user's file.
Faults that can be repaired are repaired (duplicate vertices, degenerate or duplicate
faces, inconsistent winding, inverted orientation; non-manifold edges, small holes, stray
open pieces and overlapping parts in :mod:`~tactile_viz.engine.shape.mesh_repair`), with one
:class:`~tactile_viz.engine.errors.MeshWarning` saying what was done; a mesh with no inside
(an open sheet) or a file that cannot be parsed raises
:class:`~tactile_viz.engine.errors.MeshError` naming the source and the reason.
"""

from __future__ import annotations

import hashlib
import os
import warnings

import numpy as np
import trimesh

from ..errors import MeshError, MeshWarning
from .mesh_repair import counted, needs_repair, repair_surface

LONGEST_SIDE = 6.0  # the paper's normalisation (an explicit choice: meshes keep their size)
# Length units a file or a recording may be in, as metres: a scene given in named units is
# in metres.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
# Sizes a mesh may have in scene units: beyond them tolerances of the libraries (trimesh
# merges vertices within 1e-8) and squared distances lose the shape.
MIN_SIZE, MAX_SIZE = 1e-4, 1e6
SUPPORTED_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
# Meshes with more faces are decimated to DECIMATED_FACES (with a MeshWarning): the filter
# sees an object through a 64^3 SDF grid, and the exact distance, the grid and the
# viewport cost time in proportion to the faces. A 2-million-face mesh loads in about 20 s
# on a 2-core machine this way, against about 45 s for the same mesh kept whole (6 s to
# load plus 40 s for its exact distance and SDF grid on first use).
MAX_FACES = 500_000
DECIMATED_FACES = 200_000


def unit_factor(units: str | float | None) -> float:
    """Scene units per file unit for ``units``: a name of :data:`UNITS` (converted to metres),
    a positive number (a factor) or None (1: the file's units are the scene's).

    Raises
    ------
    ValueError
        For anything else.
    """
    if units is None:
        return 1.0
    if isinstance(units, str):
        name = units.strip().lower()
        if name in UNITS:
            return UNITS[name]
        try:
            units = float(name)
        except ValueError:
            raise ValueError(f"unknown units {units!r}: use {', '.join(UNITS)} or a positive "
                             "number (scene units per file unit)") from None
    factor = float(units)
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"a unit factor must be a positive finite number, got {units!r}")
    return factor


def split_units(text: str) -> tuple[str, str | None]:
    """``(path, units)`` of a file named with its unit, ``cup.stl:mm`` or ``cup.stl:0.001``.

    Only a name of :data:`UNITS` or a number after the last colon is a unit, so paths with
    colons of their own (``C:\\cup.stl``) are kept whole: ``(text, None)``.
    """
    path, colon, suffix = str(text).rpartition(":")
    if not colon or not path:
        return str(text), None
    name = suffix.strip().lower()
    if name in UNITS:
        return path, name
    try:
        float(name)
    except ValueError:
        return str(text), None
    return path, suffix.strip()


def load_mesh(path, longest_side: float | None = None, max_faces: int | None = MAX_FACES,
              scale: float = 1.0) -> trimesh.Trimesh:
    """Read a mesh file and return it checked, repaired and centred (and scaled if asked).

    Parameters
    ----------
    path : str or os.PathLike
        An OBJ, PLY, STL, OFF or GLB file (anything trimesh reads as triangles).
    longest_side : float or None
        Normalise the longest side of the bounding box to this length (the paper's
        convention is ``LONGEST_SIDE``); None keeps the file's size times ``scale``.
    max_faces : int or None
        Meshes with more faces are decimated to ``DECIMATED_FACES`` with a
        :class:`~tactile_viz.engine.errors.MeshWarning`; ``None`` keeps every face.
    scale : float
        Scene units per file unit (:func:`unit_factor`), when ``longest_side`` is None.

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward oriented, object frame (centred on its bounding box), with
        ``metadata["file_to_object"]``.

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
    if suffix == ".off":
        check_off(path, name)
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as error:  # trimesh raises many types on bad bytes
        raise MeshError(name, f"cannot be read as {suffix[1:].upper()} "
                              f"({_in_user_words(error)})") from error
    vertices = getattr(loaded, "vertices", None)
    faces = getattr(loaded, "faces", None)
    if vertices is None or faces is None or len(faces) == 0:
        raise MeshError(name, "the file holds no triangles")
    return prepare_mesh(vertices, faces, source=name, longest_side=longest_side,
                        max_faces=max_faces, scale=scale)


def prepare_mesh(vertices, faces, source="arrays", longest_side=None, max_faces=MAX_FACES,
                 scale=1.0):
    """Check, repair and normalise a mesh given as arrays.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    source : str
        Named in error messages.
    longest_side : float or None
        Scale so that the longest side of the bounding box has this length; None keeps the
        size times ``scale`` (only recentres).
    max_faces : int or None
        See :func:`load_mesh`.
    scale : float
        Scene units per unit of ``vertices`` when ``longest_side`` is None.

    Returns
    -------
    trimesh.Trimesh
        With ``metadata["file_to_object"]``: the 4x4 similarity from the coordinates of
        ``vertices`` to the returned mesh's.
    """
    vertices, faces = _checked_arrays(vertices, faces, source)
    vertices, factor, offset = _normalised_vertices(vertices, faces, source)
    target = LONGEST_SIDE if longest_side is None else float(longest_side)
    if longest_side is None:
        target = scale / factor * LONGEST_SIDE  # the file's size in scene units
    if not MIN_SIZE <= target <= MAX_SIZE:
        raise MeshError(source, f"is {target:.3g} scene units long, outside "
                                f"[{MIN_SIZE:g}, {MAX_SIZE:g}]: give the file's units (a unit "
                                "factor) or normalise its size")
    mesh = _repaired(vertices, faces, source, max_faces)
    mesh.metadata["file_to_object"] = mesh.metadata["file_to_object"] @ similarity(factor, offset)
    return _resized(mesh, target / LONGEST_SIDE)


def _resized(mesh, factor):
    """The mesh scaled about its centre (float32-exact vertices), its ``file_to_object``
    following."""
    if factor == 1.0:
        return mesh
    mesh.vertices = (mesh.vertices * factor).astype(np.float32).astype(np.float64)
    mesh.metadata["file_to_object"] = similarity(factor, np.zeros(3)) @ mesh.metadata[
        "file_to_object"]
    return mesh


def _repaired(vertices, faces, source, max_faces):
    """Repairs and checks at the paper's size (trimesh merges vertices within an absolute
    tolerance, so a surface is repaired alike whatever its units), recentred; its
    ``file_to_object`` is the recentring. What was repaired beyond duplicate vertices,
    degenerate faces and the orientation is said in one :class:`MeshWarning`."""
    mesh = trimesh.Trimesh(vertices, faces, process=True, validate=False)
    mesh.update_faces(mesh.nondegenerate_faces())
    if len(mesh.faces) == 0:
        raise MeshError(source, "every face is degenerate (zero area)")
    notes = []
    unique = mesh.unique_faces()
    duplicates = int(len(mesh.faces) - unique.sum())
    if duplicates:
        mesh.update_faces(unique)
        notes.append(f"{counted(duplicates, 'duplicate face')} removed")
    mesh.remove_unreferenced_vertices()
    before = mesh.faces.copy()
    trimesh.repair.fix_winding(mesh)
    flipped = int((mesh.faces != before).any(axis=1).sum())
    flipped = min(flipped, len(mesh.faces) - flipped)  # the minority was turned
    if flipped:
        notes.append(f"{counted(flipped, 'flipped face')} turned")
    if needs_repair(mesh):
        mesh, repairs = repair_surface(mesh, source)
        notes += repairs
    if not mesh.is_watertight:
        raise MeshError(source, "not watertight and could not be repaired")
    if not mesh.is_winding_consistent:
        raise MeshError(source, "face winding is inconsistent (the surface is not orientable)")
    if mesh.volume < 0:
        mesh.invert()
    if mesh.volume <= 1e-6 * float(mesh.extents.max())**3:
        raise MeshError(source, "encloses no volume (a flat or degenerate surface)")
    if notes:
        warnings.warn(MeshWarning(f"{source}: repaired on loading: {'; '.join(notes)}"),
                      stacklevel=3)
    # Repairs move the box a little; recentre so the object frame stays the box centre.
    # Vertices are kept float32-exact so saving to PLY and reading back changes nothing.
    centre = mesh.bounds.mean(axis=0)
    mesh.vertices = (mesh.vertices - centre).astype(np.float32).astype(np.float64)
    mesh.metadata["file_to_object"] = similarity(1.0, -centre)
    if max_faces is not None and len(mesh.faces) > max_faces:
        return _decimated(mesh, source, max_faces)
    return mesh


def similarity(factor, offset):
    """The 4x4 matrix of ``x -> factor x + offset``."""
    matrix = np.eye(4)
    matrix[:3, :3] *= factor
    matrix[:3, 3] = offset
    return matrix


def _decimated(mesh, source, max_faces):
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
        vertices, factor, offset = _normalised_vertices(vertices, faces, source)
        smaller = _repaired(vertices, faces, source, max_faces=None)
        smaller.metadata["file_to_object"] = (smaller.metadata["file_to_object"]
                                              @ similarity(factor, offset))
        smaller.metadata["file_to_object"] = (smaller.metadata["file_to_object"]
                                              @ mesh.metadata["file_to_object"])
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


def bare_mesh(mesh):
    """A copy of ``mesh`` sharing its arrays but not its derived-data cache: what one use
    derives (2-3 MB of triangles, cross products and normals for a 20,000-face prior) goes
    with the copy instead of staying on a library's mesh."""
    return trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)


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


def check_off(path, name):
    """Raise a :class:`MeshError` naming the line of the first fault of an OFF file.

    trimesh reads an OFF file with numpy, whose errors speak of arrays, and reads a face
    row that lists more corners than it gives, or a file holding fewer rows than its
    counts announce, without complaint; this checks the rows against the counts first.
    """
    with open(path, "rb") as stream:
        text = stream.read().decode("utf-8", errors="replace")
    rows = [(number, line.split("#", 1)[0].split())
            for number, line in enumerate(text.splitlines(), start=1)]
    rows = [(number, fields) for number, fields in rows if fields]
    if not rows or not rows[0][1][0].upper().endswith("OFF"):
        raise MeshError(name, "cannot be read as OFF: the first line must say OFF")
    first = rows[0][1][1:]  # the counts may follow the keyword on its line
    rows = rows[1:] if not first else [(rows[0][0], first)] + rows[1:]
    if not rows:
        raise MeshError(name, "cannot be read as OFF: the line of counts is missing")
    number, counts = rows[0]
    try:
        n_vertices, n_faces = int(counts[0]), int(counts[1])
    except (ValueError, IndexError):
        raise MeshError(name, f"cannot be read as OFF: line {number}: expected the vertex "
                              f"and face counts, found {' '.join(counts)!r}") from None
    body = rows[1:]
    if len(body) < n_vertices + n_faces:
        raise MeshError(name, f"cannot be read as OFF: it announces {n_vertices} vertices "
                              f"and {n_faces} faces but holds {len(body)} rows")
    for number, fields in body[:n_vertices]:
        _check_off_row(name, number, fields, 3, "a vertex row needs 3 numbers (x y z)", float)
    for number, fields in body[n_vertices:n_vertices + n_faces]:
        _check_off_row(name, number, fields, 1, "a face row needs its corner count", int)
        corners = int(fields[0])
        if corners < 3 or len(fields) < corners + 1:
            raise MeshError(name, f"cannot be read as OFF: line {number}: the face lists "
                                  f"{corners} corners but gives {len(fields) - 1}")
        _check_off_row(name, number, fields[1:corners + 1], corners, "", int)


def _check_off_row(name, number, fields, count, need, kind):
    if len(fields) < count:
        raise MeshError(name, f"cannot be read as OFF: line {number}: {need}, found "
                              f"{len(fields)}")
    for field in fields[:count]:
        try:
            kind(field)
        except ValueError:
            expected = "a whole number" if kind is int else "a number"
            raise MeshError(name, f"cannot be read as OFF: line {number}: {field!r} is not "
                                  f"{expected}") from None


def _in_user_words(error):
    """A reader's error without numpy's vocabulary."""
    text = str(error)
    if "inhomogeneous" in text or "setting an array element with a sequence" in text:
        return "rows of unequal length"
    if "could not convert string to float" in text:
        return "a value is not a number: " + text.rsplit(":", 1)[-1].strip()
    if "cannot reshape array" in text:
        return "the number of values does not match the counts in the header"
    return text


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
        raise MeshError(source, f"{int(bad.sum())} of {len(vertices)} vertices are not finite "
                                "(NaN or inf)")
    return vertices, faces.astype(np.int64)


def _normalised_vertices(vertices, faces, source):
    """Vertices centred on their box and scaled to the paper's size, the factor and the
    offset: ``factor * vertices + offset``."""
    used = vertices[np.unique(faces)]
    low, high = used.min(axis=0), used.max(axis=0)
    size = float((high - low).max())
    # Relative to the coordinates' magnitude: a mesh 1e-9 units across is only small, but
    # one 1e-9 across at 1e6 from the origin has lost its shape to rounding.
    with np.errstate(over="ignore", divide="ignore"):
        factor = LONGEST_SIDE / size if size > 0 else np.inf
    if size <= 0 or not np.isfinite(factor) or size <= 1e-12 * float(np.abs(used).max()):
        raise MeshError(source, "degenerate: all vertices coincide")
    centre = (low + high) / 2
    return (vertices - centre) * factor, factor, -factor * centre
