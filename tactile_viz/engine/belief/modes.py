"""Which refined poses of a class are one hypothesis: their posed surfaces agree (a
symmetry of the shape, or two particles of one mode), as far as touches can tell."""

import numpy as np
from scipy.special import ndtri

from ..transforms import transform_points

AGREE_PERCENTILE = 99  # two poses of a class agree if all but 1% of their surfaces do
SURFACE_STRIDE = 3  # every third feature point compares two poses' surfaces
# A pose of the MAP candidate's mode leads instead of it when it is this many nats more
# probable (a hundred times): ties (exact fits of a symmetric shape) keep the MAP's.
LEAD_MARGIN = float(np.log(100.0))


def mode_tolerance(model, same_mode):
    """How far two poses of a class's surface may lie apart and be one hypothesis (scene
    units, as :func:`surface_disagreement`): ``same_mode`` and, for a learned shape, as
    far as its own error (``shape_error``, an RMS) puts two copies of it apart at the
    ``AGREE_PERCENTILE`` percentile, in quadrature (independent errors; ``same_mode``
    alone for a given mesh). Touches cannot tell apart poses of a shape that differ by
    less than the shape is known to (a learned cross screwdriver's turns about its shaft,
    4 mm apart on its blob of a tip, split the decision for 150 touches; the larger of the
    two left a learned fork met at 2 mm a rival 4 degrees and 5.7 mm from its lead)."""
    spread = np.sqrt(2) * model.shape_error * ndtri(0.5 + AGREE_PERCENTILE / 200)
    return float(np.hypot(same_mode, spread))


def distinct(bank, classes, rotations, translations, cost, tolerance, lead_tolerance=None):
    """Indices of the refined hypotheses that are distinct, each kept once (the least
    ``cost`` of a mode), the MAP candidate's mode first (index 0, or a pose of its mode
    that costs :data:`LEAD_MARGIN` less and lies within ``lead_tolerance`` of it, default
    its class's tolerance; ``cost`` in nats). ``tolerance``: (classes,) float, scene units,
    by class index (:func:`mode_tolerance`).

    The MAP candidate's mode leads at its best pose: a known ice cream cone's MAP particle
    refined to a pose 4.6 mm off (a misfit of 7.2 mm^2) while a pose of its mode refined
    to 1.1 mm (0.5 mm^2), 42 nats more probable; kept at the worse, it misfitted five
    touches in a row and the object was judged novel. A learned shape's mode is as wide as
    its own error (:func:`mode_tolerance`): ``lead_tolerance`` keeps its lead near the MAP
    candidate (a learned cup met again at 2 mm was left 34% of its size off)."""
    order = np.argsort(cost, kind="stable")
    near = tolerance[classes[0]] if lead_tolerance is None else min(
        tolerance[classes[0]], lead_tolerance)
    lead = next((int(index) for index in order
                 if index == 0 or (classes[index] == classes[0]
                                   and cost[index] < cost[0] - LEAD_MARGIN
                                   and pose_disagreements(
                                       bank, classes[0], rotations[index], translations[index],
                                       rotations[:1], translations[:1])[0] <= near)), 0)
    kept = [lead]
    for index in order:
        if index == lead or not np.isfinite(cost[index]):
            continue
        same = [k for k in kept if classes[k] == classes[index]]
        if not same or np.all(pose_disagreements(
                bank, classes[index], rotations[index], translations[index],
                rotations[same], translations[same]) > tolerance[classes[index]]):
            kept.append(int(index))
    return np.array(kept, dtype=np.int64)


def surface_disagreement(bank, class_index, rotations, translations):
    """How far one class's surface at two poses lies apart, both ways: the
    ``AGREE_PERCENTILE`` percentile of the distance of its feature points at each pose to
    its surface at the other (scene units; about 0 for poses related by a symmetry).

    Nearly the largest, not the RMS: a mug's handle is a small part of its surface, and
    two poses that put it 2 cm apart agree in RMS within the noise, yet only one is the
    object. The top percent is left out as the grid's own error at thin edges."""
    return float(pose_disagreements(bank, class_index, rotations[0], translations[0],
                                    rotations[1:2], translations[1:2])[0])


def pose_disagreements(bank, class_index, rotation, translation, rotations, translations):
    """:func:`surface_disagreement` of one pose against each of ``k`` others of the same
    class, in two batched look-ups: (k,) float, scene units."""
    points = bank.points[class_index][::SURFACE_STRIDE]
    mine = transform_points(points, rotation, translation)  # (m, 3), world
    theirs = np.einsum("kij,mj->kmi", rotations, points) + translations[:, None]  # (k, m, 3)
    # Mine in each of their frames, and theirs in mine: x = R^T (p - t).
    in_theirs = np.einsum("kmi,kij->kmj", mine[None] - translations[:, None], rotations)
    in_mine = (theirs - translation) @ rotation
    count = len(rotations)
    values, _ = bank.evaluate(np.full(2 * count, class_index),
                              np.concatenate([in_theirs, in_mine]))
    spread = np.percentile(np.abs(values), AGREE_PERCENTILE, axis=1)
    return np.maximum(spread[:count], spread[count:])
