"""The parts of an estimated surface a snapshot reports: those some contact supports,
without those misses refute (beyond the paper).

A part no contact comes near is a phantom of the prior mean or the kernel.

The stop weighs only the estimate's vertices away from the misses
(:func:`~.refuted.open_vertices`): near a target given up or a missed probe's path, the
estimate is surface the probes looked for and did not find. A part there that no contact
comes within ``eps`` of is the prior mean's or the kernel's, not the object's: on a 20 cm
fork at 2 mm noise such parts were a fifth to a third of the reported surface, up to
36 mm off the fork and 20-33 mm from every contact, and they were learned with it. A
snapshot reports its surface without them; a stopping session's last surface has the
holes they leave closed, so that what it reports is what it learns.
"""

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from ..shape.mesh_repair import closed_faces
from .refuted import part_labels, refuted_tree

FACING_NEIGHBOURS = 16  # nearest contacts a vertex asks which way they face


def support_reach(p, noise=0.0):
    """How near a contact a reported surface is supported where misses refute it, and how
    near one a part of it must come (scene units): ``eps``, or under position noise of std
    ``noise`` (with ``final_support_near``) ``contact_spacing`` and at least
    ``target_noise_stds`` stds (what the noise explains), at most ``eps``.

    Under noise the thin-plate fit swings between readings that disagree, and the surface
    grows blobs beside thin parts: a 20 cm fork's last surface at 2 mm kept blobs 6-20 mm
    from every contact, within 5 mm of the misses about them and up to 23 mm off the fork
    (12.0% of its size; 6.7% with the nearer reach, the same touches). Noiseless the
    surface within eps of a contact interpolates exact readings, and the nearer reach cut
    true parts near misses (a 15 cm elephant's 5.4% -> 15.0%)."""
    if not p.final_support_near or noise <= 0:
        return p.eps
    return min(p.eps, max(p.contact_spacing, p.target_noise_stds * noise))


def refuted_vertices(vertices, refuted, contacts, spacing, reach, closure=None,
                     cap_reach=0.0):
    """Mask of the ``vertices`` that misses refute: within ``spacing`` of a ``refuted``
    point, or those of ``closure`` (where the surface closes at its box,
    :func:`~..shape.level_set.box_closure`) within ``cap_reach`` of one, and farther than
    ``reach`` from every contact (the stop's view, :func:`~.refuted.open_estimate`).

    Parameters
    ----------
    vertices : (v, 3) float
    refuted : (k, 3) float
        Given-up targets and free-space samples (``ExplorationState.refuted``).
    contacts : (n, 3) float
    spacing : float
        The session's ``contact_spacing`` (the stop's reach of a miss), scene units.
    reach : float
        The session's ``eps`` (a contact's cover), scene units.
    closure : (v,) bool, optional
    cap_reach : float
        The carve's reach (``gpis_carve_radius``), scene units; at most ``spacing``:
        the caps as the rest.

    Returns
    -------
    (v,) bool
        All False without refuted points or vertices; every vertex far from the misses
        is False.
    """
    vertices = np.asarray(vertices, dtype=float).reshape(-1, 3)
    refuted = np.ascontiguousarray(refuted, dtype=float).reshape(-1, 3)
    if len(refuted) == 0 or len(vertices) == 0:
        return np.zeros(len(vertices), bool)
    wide = closure is not None and cap_reach > spacing and np.any(closure)
    far = max(spacing, cap_reach) if wide else spacing
    distance = refuted_tree(refuted.tobytes()).query(vertices, distance_upper_bound=far)[0]
    near = distance < spacing
    if wide:
        near |= np.asarray(closure, bool) & (distance < cap_reach)
    contacts = np.asarray(contacts, dtype=float).reshape(-1, 3)
    if len(contacts) and near.any():
        near[near] = cKDTree(contacts).query(vertices[near])[0] > reach
    return near


def without_refuted(recon, refuted, contacts, spacing, reach, close=False, cut=None,
                    cap_reach=0.0):
    """``recon`` (a :class:`~.snapshot.Reconstruction`) without the faces on a vertex
    :func:`refuted_vertices` marks; with ``close``, the holes this leaves closed by patches
    across their rims (:func:`~..shape.mesh_repair.closed_faces`), and if they cannot be
    (a rim that is not manifold), ``cut(recon)``: its surface extracted again with what
    the misses refute cut out of its solid (None: ``recon`` unchanged; either way a
    surface that can be learned). Nothing is dropped when every vertex is refuted.

    Returns
    -------
    Reconstruction
    """
    if recon is None or recon.empty:
        return recon
    keep = ~refuted_vertices(recon.vertices, refuted, contacts, spacing, reach,
                             recon.closure if cap_reach > spacing else None, cap_reach)
    if keep.all() or not keep.any():
        return recon
    # A kept vertex whose faces all went is dropped with them.
    faces = recon.faces[keep[recon.faces].all(axis=1)]
    keep = np.zeros(len(keep), bool)
    keep[faces.ravel()] = True
    kept = recon.restricted(keep)
    if not close or len(kept.faces) == 0:
        return kept if len(kept.faces) else recon
    faces = closed_faces(kept.vertices, kept.faces)
    if faces is not None:
        return replace(kept, faces=faces)
    return recon if cut is None else cut(recon)


def reported_parts(recon, refuted, contacts, spacing, reach, close=False, cut=None,
                   cap_reach=0.0, normals=None):
    """``recon`` :func:`without_refuted` (``close``, ``cut`` and ``cap_reach`` passed on),
    and of the rest only the connected parts some contact comes within ``reach`` of, facing
    its way with the contacts' ``normals`` (:func:`supported_parts`).

    Returns
    -------
    Reconstruction
    """
    if recon is None or recon.empty:
        return recon
    recon = without_refuted(recon, refuted, contacts, spacing, reach, close=close, cut=cut,
                            cap_reach=cap_reach)
    keep = supported_parts(recon.vertices, recon.faces, contacts, reach, normals)
    return recon.restricted(keep) if keep.any() and not keep.all() else recon


def supported_parts(vertices, faces, points, reach, normals=None):
    """Mask of the vertices on connected parts of a surface that come within ``reach`` of
    a point: the parts some contact supports. With the contacts' ``normals``, a contact
    supports only surface that faces its way (:func:`facing_near`): a closed part inside
    the estimate's solid, facing into the object, is a void of the fit that no probe can
    reach, however near the contacts on the surface outside it (a 15 cm elephant at 2 mm
    kept one 46 mm long, 7 mm inside its back and 27 mm off the elephant).

    Parameters
    ----------
    vertices : (v, 3) float
    faces : (f, 3) int
    points : (n, 3) float
        Contacts, the same frame as ``vertices``.
    reach : float
        Scene units.
    normals : (n, 3) float, optional
        The contacts' unit normals.

    Returns
    -------
    (v,) bool
        All False without points or vertices.
    """
    vertices, faces = np.asarray(vertices, float), np.asarray(faces, int)
    if len(vertices) == 0 or len(points) == 0:
        return np.zeros(len(vertices), bool)
    labels = part_labels(vertices, faces)
    if normals is None:
        near = cKDTree(points).query(vertices, distance_upper_bound=reach)[0] <= reach
    else:
        near = facing_near(vertices, faces, points, normals, reach)
    return np.isin(labels, labels[near])


def facing_near(vertices, faces, points, normals, reach, neighbours=FACING_NEIGHBOURS):
    """``(v,)`` bool: the vertices within ``reach`` of one of their ``neighbours`` nearest
    contacts whose normal makes a positive dot product with the surface's normal there. The
    surface's normals are oriented as the contacts find it (the sign most contacts agree
    with at their nearest vertex), whatever the winding of its faces."""
    vertices = np.asarray(vertices, float)
    points, normals = np.asarray(points, float), np.asarray(normals, float)
    surface = vertex_normals(vertices, faces)
    tree = cKDTree(points)
    nearest = cKDTree(vertices).query(points)[1]
    if np.median(np.einsum("ij,ij->i", normals, surface[nearest])) < 0:
        surface = -surface
    count = min(int(neighbours), len(points))
    distance, index = tree.query(vertices, k=count, distance_upper_bound=reach)
    distance, index = distance.reshape(len(vertices), count), index.reshape(len(vertices), count)
    found = distance <= reach
    padded = np.vstack([normals, np.zeros((1, 3))])  # a missing neighbour faces nowhere
    facing = np.einsum("vkj,vj->vk", padded[np.where(found, index, len(points))], surface) > 0
    return np.any(found & facing, axis=1)


def vertex_normals(vertices, faces):
    """``(v, 3)`` float: each vertex's faces' normals summed, weighted by their areas
    (unnormalised; only their signs are read), along the faces' winding."""
    vertices, faces = np.asarray(vertices, float), np.asarray(faces, int).reshape(-1, 3)
    corners = vertices[faces]
    area = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return np.column_stack([np.bincount(faces.ravel(), np.repeat(area[:, axis], 3),
                                        minlength=len(vertices)) for axis in range(3)])
