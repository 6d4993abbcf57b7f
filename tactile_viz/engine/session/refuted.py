"""Where missed probes refute an estimate (beyond the paper): the masks of the vertices a
session may still have to visit, which the target, the DHD that stops it and the final
surface's support share.

Near a given-up target or a missed probe's path, probing again cannot teach anything: the
vertices within ``contact_spacing`` of one are left out, and where a GPIS estimate closes
at its box (:func:`~..shape.level_set.box_closure`) far from every contact, as far as the carve
reaches.
"""

import functools

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


def open_vertices(vertices, state, radius, all_refuted=True):
    """Mask of ``vertices`` farther than ``radius`` from every given-up target and every
    free-space point of the exploration ``state`` (all of them if none is, unless
    ``all_refuted`` is False)."""
    refuted = state.refuted
    if len(refuted) == 0 or len(vertices) == 0:
        return np.ones(len(vertices), bool)
    distance = refuted_tree(np.ascontiguousarray(refuted, dtype=float).tobytes()).query(
        vertices, distance_upper_bound=radius)[0]
    far = distance >= radius
    return far if far.any() or not all_refuted else np.ones(len(vertices), bool)


def open_estimate(vertices, closure, state, p, contacts):
    """Mask of a GPIS estimate's ``vertices`` still to visit (:func:`open_vertices`
    within ``contact_spacing``), and of those where it closes at its box (``closure``,
    :func:`~..shape.level_set.box_closure`) farther than ``eps`` from every contact, only the
    ones farther than the carve's reach (``gpis_carve_radius``) from every refuted point
    (beyond the paper). A thin-plate fit's solid can reach the box far from every contact:
    an 8 cm cup's estimate against a mug prior closed 260 vertices at its box, and 100
    probes in a row missed there, each refuting the few vertices its path passed within
    ``contact_spacing`` of. Within ``eps`` of a contact a cap can be the object going on
    past the box: there, as the carve, a miss refutes no more than elsewhere."""
    keep = open_vertices(vertices, state, p.contact_spacing)
    reach = max(p.contact_spacing, p.gpis_carve_radius)
    if reach <= p.contact_spacing or not closure.any() or not keep.any():
        return keep
    far = closure.copy()
    if len(contacts):
        far[far] = cKDTree(contacts).query(vertices[far], distance_upper_bound=p.eps)[0] > p.eps
    if not far.any():
        return keep
    wider = keep.copy()
    wider[far] &= open_vertices(vertices[far], state, reach, all_refuted=False)
    return wider if wider.any() else keep


def missed_parts(vertices, faces, contacts, given_up, reach, misses):
    """Mask of the vertices on connected parts of an estimate that no contact comes within
    ``reach`` of and near which (within ``reach``) at least ``misses`` targets were given
    up: a part the prior or the fit put where probes keep finding nothing (beyond the
    paper). A 20 cm fork's estimate held a blob 80 x 80 x 110 mm, 130 mm from every
    contact, on its own part; each miss there refuted the few vertices within
    ``contact_spacing`` of its path and the next target lay 6 mm from the last, for 300
    touches to the step cap.

    Parameters
    ----------
    vertices : (v, 3) float
    faces : (f, 3) int
    contacts, given_up : (n, 3), (k, 3) float
        The same frame as ``vertices``.
    reach : float
        Scene units (``eps``).
    misses : int
        ``missed_parts`` (0: none is refuted).

    Returns
    -------
    (v,) bool
    """
    refuted = np.zeros(len(vertices), bool)
    given_up = np.reshape(given_up, (-1, 3))
    if misses <= 0 or len(given_up) < misses or len(vertices) == 0:
        return refuted
    labels = part_labels(vertices, faces)
    supported = np.zeros(labels.max() + 1, bool)
    if len(contacts):
        near = cKDTree(contacts).query(vertices, distance_upper_bound=reach)[0] <= reach
        supported[labels[near]] = True
    # Each given-up target counts once, for the part of its nearest vertex within reach.
    distance, nearest = cKDTree(vertices).query(given_up, distance_upper_bound=reach)
    counts = np.bincount(labels[nearest[distance <= reach]], minlength=len(supported))
    return (counts >= misses)[labels] & ~supported[labels]


def open_parts(reachable, vertices, faces, contacts, state, p):
    """``reachable`` without the vertices :func:`missed_parts` refutes (``missed_parts``
    given-up targets of the exploration ``state``, within ``eps``), unless none would be
    left."""
    if not p.missed_parts:
        return reachable
    kept = reachable & ~missed_parts(vertices, faces, contacts, state.given_up, p.eps,
                                     p.missed_parts)
    return kept if kept.any() else reachable


@functools.lru_cache(maxsize=4)
def refuted_tree(points):
    """A KD-tree of refuted points given as the bytes of a ``(k, 3)`` float array, kept
    while they stay the same (a step asks twice, and a step without a miss adds none)."""
    return cKDTree(np.frombuffer(points, dtype=float).reshape(-1, 3))


def part_labels(vertices, faces):
    """The connected part of each vertex of a triangle mesh, ``(v,)`` int from 0."""
    faces = np.asarray(faces, int).reshape(-1, 3)
    ends = np.roll(faces, 1, axis=1)
    graph = coo_matrix((np.ones(faces.size), (faces.ravel(), ends.ravel())),
                       shape=(len(vertices),) * 2)
    return connected_components(graph, directed=False)[1]
