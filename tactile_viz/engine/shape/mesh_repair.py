"""Repairs of the surfaces scanners and CAD exports produce.

A scan or an export is often not one clean closed surface: a few edges are shared by three
or four faces (non-manifold), small holes are left open, faces are flipped, stray open
pieces float around, or closed parts overlap or nest. The signed distance takes its sign
from the generalised winding number, which is defined on all of these, but the feature
points, the normals, the volume and the metrics need a closed outward surface, so
:func:`repair_surface` makes one with pymeshlab (MeshLab's filters) and says what it did.
Only a surface with no inside (an open sheet) is refused.
"""

from __future__ import annotations

import numpy as np
import trimesh

from ..errors import MeshError

# A hole is closed only when the patch is a small part of its piece's surface; a larger
# opening means an open scan or sheet whose inside is a guess.
MAX_HOLE_AREA_FRACTION = 0.05
# Open pieces that cannot be closed (fins split off, flaps, loose triangles) are dropped
# while the closed parts hold most of the surface; a mesh that is mostly open is refused.
MAX_STRAY_AREA_FRACTION = 0.5


def counted(count, noun):
    """``"3 holes"``, ``"1 hole"``: ``count`` (any integer, numpy's too) and ``noun``."""
    count = int(count)
    return f"{count} {noun}{'s' * (count != 1)}"


def needs_repair(mesh):
    """Whether ``mesh`` is anything but one closed, consistently wound piece.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Vertices merged, winding fixed where it could be.

    Returns
    -------
    bool
    """
    return not (mesh.is_watertight and mesh.is_winding_consistent and mesh.body_count == 1)


def repair_surface(mesh, source):
    """A closed, outward oriented surface made from ``mesh``, and what was done.

    Non-manifold edges are split (each side keeps its faces), each open piece has its small
    holes closed, open pieces that stay open are dropped when small, each closed piece is
    oriented outward, and closed pieces that overlap or nest are merged by a Boolean union.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Vertices merged; no degenerate or duplicate faces.
    source : str
        Named in the error.

    Returns
    -------
    repaired : trimesh.Trimesh
        Every edge shared by exactly two faces (vertices are not merged again: a split edge
        stays split), outward.
    notes : list of str
        One phrase per kind of repair, e.g. ``"3 non-manifold edges split"``; empty when
        nothing had to change (``repaired`` is then ``mesh``).

    Raises
    ------
    MeshError
        If the surface has no inside: open pieces too large to close or to drop.
    """
    try:
        pymeshlab = _pymeshlab()
    except ImportError:
        raise MeshError(source, "is not one closed surface and its repair needs pymeshlab, "
                                "which is not installed (pip install pymeshlab)") from None
    try:
        return _repaired_surface(mesh, source)
    except (pymeshlab.PyMeshLabException, ValueError, IndexError) as error:
        # A surface MeshLab's filters refuse, or too broken for trimesh to split.
        reason = (str(error).strip().splitlines() or [type(error).__name__])[-1]
        raise MeshError(source, f"is not one closed surface and could not be repaired "
                                f"({reason})") from None


def _repaired_surface(mesh, source):
    """:func:`repair_surface` once pymeshlab is there."""
    notes = []
    count = _non_manifold_edge_count(mesh)
    split = _split_non_manifold(mesh, count)
    if count:
        notes.append(f"{counted(count, 'non-manifold edge')} split")
    parts = split.split(only_watertight=False, repair=False)
    closed, stray, holes = _closed_parts(parts, source)
    if holes:
        notes.append(f"{counted(holes, 'hole')} closed")
    if stray:
        total = sum(part.area for part in parts)
        notes.append(f"{counted(len(stray), 'open piece')} dropped "
                     f"({100 * sum(p.area for p in stray) / total:.2g}% of the surface)")
    flipped, inverted = np.sum([_orient_outward(part) for part in closed], axis=0)
    if flipped:
        notes.append(f"{counted(flipped, 'flipped face')} turned")
    if inverted and len(closed) > 1:
        notes.append(f"{counted(inverted, 'inside-out part')} turned")
    merged, failed = _merge_overlapping(closed)
    if failed:
        notes.append(f"{failed} overlapping parts kept as they are (the union failed)")
    elif len(merged) < len(closed):
        notes.append(f"{len(closed) - len(merged) + 1} overlapping or nested parts merged")
    if not notes and not inverted:
        return mesh, notes
    return _concatenated(merged), notes


def closed_faces(vertices, faces):
    """``faces`` with every hole of the surface closed by a patch across its rim
    (pymeshlab's hole filling, whatever the hole's size), or None when the result is not
    closed; the vertices stay as they are (the patches join existing vertices).

    Parameters
    ----------
    vertices : (v, 3) float
    faces : (f, 3) int

    Returns
    -------
    (g, 3) int or None
        The first ``f`` rows are ``faces``.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int32)
    if len(faces) == 0:
        return None
    pymeshlab = _pymeshlab()
    try:
        meshset = _meshset(trimesh.Trimesh(vertices, faces, process=False))
        meshset.meshing_close_holes(maxholesize=3 * len(faces) + 3, selfintersection=False)
    except pymeshlab.PyMeshLabException:  # e.g. a non-manifold rim: left as it is
        return None
    current = meshset.current_mesh()
    closed = current.face_matrix().astype(np.int64)
    if (current.vertex_matrix().shape != vertices.shape
            or not np.array_equal(current.vertex_matrix(), vertices)
            or not np.array_equal(closed[:len(faces)], faces)):
        return None
    mesh = trimesh.Trimesh(vertices, closed, process=False)
    return closed if mesh.is_watertight else None


def _non_manifold_edge_count(mesh):
    """Edges shared by more than two faces."""
    edges = mesh.edges_sorted.astype(np.int64)
    keys = edges[:, 0] * (len(mesh.vertices) + 1) + edges[:, 1]  # 1-D: a fast unique
    _, counts = np.unique(keys, return_counts=True)
    return int((counts > 2).sum())


def _pymeshlab():
    import pymeshlab  # a heavy import, needed only for repairs

    return pymeshlab


def _meshset(*meshes):
    pymeshlab = _pymeshlab()
    meshset = pymeshlab.MeshSet()
    for mesh in meshes:
        meshset.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices, dtype=np.float64),
                                        np.asarray(mesh.faces, dtype=np.int32)))
    return meshset


def _from_meshset(meshset):
    current = meshset.current_mesh()
    return trimesh.Trimesh(current.vertex_matrix(), current.face_matrix(), process=False)


def _split_non_manifold(mesh, count=None):
    """``mesh`` with its non-manifold edges and vertices split (itself if there are none);
    ``count`` is its number of non-manifold edges, if known."""
    if (_non_manifold_edge_count(mesh) if count is None else count) == 0:
        return mesh
    meshset = _meshset(mesh)
    # 'Split Vertices' keeps every face: a fin becomes a loose piece, two solids glued
    # along an edge become two closed solids ('Remove Faces' can delete a face of the body).
    meshset.meshing_repair_non_manifold_edges(method="Split Vertices")
    meshset.meshing_repair_non_manifold_vertices()
    return _from_meshset(meshset)


def _closed_parts(parts, source):
    """The closed pieces (holes closed where small), the open ones dropped, holes closed.

    Raises
    ------
    MeshError
        If the open pieces are too large a part of the surface to drop.
    """
    closed, stray, holes, worst = [], [], 0, None
    for part in parts:
        if part.is_watertight:
            closed.append(part)
            continue
        patched, count, fraction = _closed_holes(part)
        if patched is not None:
            closed.append(patched)
            holes += count
        else:
            stray.append(part)
            if worst is None or part.area > worst[2]:
                worst = (count, fraction, part.area)
    total = sum(part.area for part in parts)
    stray_area = sum(part.area for part in stray)
    if not closed:
        count, fraction, _ = worst
        added = (f"closing them would add {100 * fraction:.0f}% of its area (at most "
                 f"{100 * MAX_HOLE_AREA_FRACTION:.0f}% is closed)" if np.isfinite(fraction)
                 and fraction > MAX_HOLE_AREA_FRACTION else "they cannot be closed")
        raise MeshError(source, f"is an open surface with no inside: it has {count} open "
                                f"hole(s) and {added}; close it in a mesh editor")
    if stray_area > MAX_STRAY_AREA_FRACTION * total:
        raise MeshError(source, f"is mostly an open surface with no inside: {len(stray)} open "
                                f"piece(s) make {100 * stray_area / total:.0f}% of its area; "
                                "close them in a mesh editor")
    return closed, stray, holes


def _closed_holes(part):
    """``(closed piece or None, hole count, added area fraction)`` for an open piece."""
    outline = part.outline()
    count = len(outline.entities)
    if part.area <= 0:
        return None, count, np.inf
    meshset = _meshset(part)
    meshset.meshing_close_holes(maxholesize=int(len(part.edges)) + 3, selfintersection=False)
    patched = _from_meshset(meshset)
    patched.merge_vertices()
    fraction = (patched.area - part.area) / part.area
    if (not patched.is_watertight or fraction > MAX_HOLE_AREA_FRACTION
            or abs(patched.volume) <= 1e-6 * float(patched.extents.max()) ** 3):
        return None, count, fraction
    return patched, count, fraction


def _orient_outward(part):
    """Make a closed piece's winding consistent and outward, in place.

    Returns
    -------
    flipped : int
        Faces whose winding disagreed with the rest of the piece.
    inverted : int
        1 if the piece as a whole was inside out, else 0.
    """
    before = part.faces.copy()
    trimesh.repair.fix_winding(part)
    changed = int((part.faces != before).any(axis=1).sum())
    inverted = part.volume < 0
    if inverted:
        part.invert()
        changed = len(part.faces) - changed
    return min(changed, len(part.faces) - changed), int(changed > len(part.faces) / 2)


def _merge_overlapping(closed):
    """Closed pieces with those that overlap or nest united; and how many could not be."""
    if len(closed) < 2:
        return closed, 0
    groups = _overlapping_groups(closed)
    merged, failed = [], 0
    for group in groups:
        if len(group) == 1:
            merged.append(closed[group[0]])
            continue
        try:
            merged.append(_union([closed[i] for i in group]))
        except Exception:  # MeshLab's booleans raise on inputs CGAL rejects
            merged.extend(closed[i] for i in group)
            failed += len(group)
    return merged, failed


def _overlapping_groups(closed):
    """Index groups of pieces that cross or contain each other (connected components of
    the relation 'some vertex of one lies inside the other, by the winding number, or
    some faces of the two intersect')."""
    import igl
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = []
    for i, a in enumerate(closed):
        tree = igl.FastWindingNumberBVH()
        tree.init(np.ascontiguousarray(a.vertices), np.ascontiguousarray(a.faces, dtype=np.int64))
        for j, b in enumerate(closed):
            if i != j and _boxes_overlap(a.bounds, b.bounds):
                inside = tree.winding_number(np.ascontiguousarray(b.vertices)) > 0.5
                if inside.any() or (i < j and _crossing(a, b)):
                    pairs.append((i, j))
    if not pairs:
        return [[i] for i in range(len(closed))]
    rows, cols = np.array(pairs).T
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(closed),) * 2)
    _, labels = connected_components(graph, directed=False)
    return [list(np.flatnonzero(labels == label)) for label in np.unique(labels)]


def _crossing(a, b):
    """Whether faces of two pieces intersect (MeshLab's self-intersection test on both)."""
    meshset = _meshset(_concatenated([a, b]))
    meshset.compute_selection_by_self_intersections_per_face()
    return meshset.current_mesh().selected_face_number() > 0


def _boxes_overlap(a, b):
    return bool(np.all(a[0] < b[1]) and np.all(b[0] < a[1]))


def _union(pieces):
    """The Boolean union of closed outward pieces (MeshLab, exact arithmetic), closed and
    with its non-manifold edges split."""
    meshset = _meshset(*pieces)
    result = 0
    for index in range(1, len(pieces)):
        meshset.generate_boolean_union(first_mesh=result, second_mesh=index)
        result = meshset.current_mesh_id()
    union = _from_meshset(meshset)
    union.merge_vertices()
    union.update_faces(union.nondegenerate_faces())
    union.remove_unreferenced_vertices()
    union = _split_non_manifold(union)
    if not union.is_watertight or union.volume <= 0:
        raise ValueError("the union is not a closed outward surface")
    return union


def _concatenated(parts):
    """One mesh of several pieces, vertices not merged (split edges stay split)."""
    vertices, faces, offset = [], [], 0
    for part in parts:
        vertices.append(np.asarray(part.vertices, dtype=np.float64))
        faces.append(np.asarray(part.faces, dtype=np.int64) + offset)
        offset += len(part.vertices)
    return trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)
