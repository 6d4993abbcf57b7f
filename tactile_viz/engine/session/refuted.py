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


@functools.lru_cache(maxsize=4)
def refuted_tree(points):
    """A KD-tree of refuted points given as the bytes of a ``(k, 3)`` float array, kept
    while they stay the same (a step asks twice, and a step without a miss adds none)."""
    return cKDTree(np.frombuffer(points, dtype=float).reshape(-1, 3))
