"""Point-to-plane Gauss-Newton refinement of several poses at once.

Each pose ``(R, t)`` maps its class's object frame into the world. The residual of a
contact ``p`` is the class's signed distance at ``x = R^T (p - t)``; a non-contact adds
``min(s(x) - r, 0)`` (it only counts inside the shape grown by the probe's radius ``r``, since
a missed tip's centre stays ``r`` off the surface). A step turns the pose by a small
rotation ``w`` about the contacts' centre ``c`` and shifts it by ``d``; with the world-frame
gradient ``n = R grad s(x)`` and ``a = p - c`` the residual's derivative is
``-(a x n, n) . (w, d)``, so the step solves the damped normal equations
``(J^T J + mu diag(J^T J)) (w, d) = -J^T r`` (Levenberg-Marquardt). A step that does not
lower a pose's sum of squares is undone and its damping raised. With ``trim`` the
``ceil(trim m)`` contacts farthest from each pose are left out of its sum (trimmed least
squares: a wrong reading cannot pull the pose).
"""

import numpy as np
from scipy.spatial.transform import Rotation

from ..transforms import inverse_transform_points_batch
from .support import support_residuals

POSE_PARAMETERS = 6  # three of rotation, three of translation
_DAMPING = 1e-3  # initial Marquardt damping, relative to the diagonal of J^T J
# Of the largest diagonal entry, added to all: a direction nothing constrains stays put.
_FLOOR = 1e-12


def refine_poses(evaluate, classes, rotations, translations, contacts, noncontacts=None,
                 iterations=10, trim=0.0, normals=None, oriented=None, clearance=0.0,
                 support=None):
    """Refine poses to fit the observations by Levenberg-Marquardt on the signed distance.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(classes (k,), points (k, m, 3))`` -> ``values (k, m), gradients
        (k, m, 3)``, signed distance and outward gradient in each class's object frame
        (:meth:`~tactile_viz.engine.belief.prior_bank.PriorBank.evaluate`).
    classes : (k,) int
    rotations : (k, 3, 3) float
        Object-to-world rotations.
    translations : (k, 3) float, world frame
    contacts : (m, 3) float, world frame
        At least one.
    noncontacts : (q, 3) float, world frame, optional
    iterations : int
        Gauss-Newton steps.
    trim : float
        Fraction of the contacts (the farthest from each pose) left out, 0-0.5.
    normals : (m, 3) float, world frame, optional
        The contacts' measured outward normals, for ``oriented``.
    oriented : callable, optional
        ``oriented(classes (q,), points (q, 3), normals (q, 3))`` -> residuals ``(q,)`` and
        outward normals ``(q, 3)``, object frame
        (:class:`~.oriented.OrientedEvaluator`: to the nearest surface facing their way):
        the residual of a contact whose nearest surface on the grid faces away from its
        measured normal (noise pushed it past a thin wall's middle, or the hypothesis
        explains it with a wall's far side).
    clearance : float, length units
        How far every non-contact is known to stay off the surface: the probe tip's radius
        (non-contacts are its centre).
    support : Support, optional
        A table the poses rest on: the heights of the hull vertices each rests on are
        residuals too (:func:`~.support.support_residuals`).

    Returns
    -------
    rotations : (k, 3, 3) float
    translations : (k, 3) float
        The refined poses; a pose whose fit no step improved is returned unchanged.
    misfit : (k,) float, squared length units
        Their sum of squared residuals.
    """
    contacts = np.asarray(contacts, dtype=float)
    noncontacts = np.zeros((0, 3)) if noncontacts is None else np.asarray(noncontacts, float)
    points = np.vstack([contacts, noncontacts])
    inside_only = np.arange(len(points)) >= len(contacts)
    if oriented is not None and normals is None:
        raise ValueError("refine_poses: oriented residuals need the contacts' normals")
    measured = None if normals is None else np.asarray(normals, dtype=float)
    drop = int(np.ceil(trim * len(contacts)))
    centre = contacts.mean(axis=0)
    arm = points - centre  # a = p - c, (m + q, 3)
    classes = np.asarray(classes)
    rotations, translations = np.array(rotations, float), np.array(translations, float)

    def residuals(rotations, translations):
        local = inverse_transform_points_batch(points, rotations, translations)  # R^T (p - t)
        values, gradients = evaluate(classes, local)
        if oriented is not None:
            m = len(contacts)
            facing = inverse_transform_points_batch(measured, rotations)  # R^T n
            k, i = np.nonzero(np.einsum("kmj,kmj->km", gradients[:, :m], facing) < 0)
            if len(k):
                values[k, i], gradients[k, i] = oriented(classes[k], local[k, i], facing[k, i])
        if clearance:
            values[:, len(contacts):] -= clearance
        active = ~inside_only | (values < 0)
        if drop:
            farthest = np.argsort(-np.abs(values[:, :len(contacts)]), axis=1)[:, :drop]
            np.put_along_axis(active, farthest, False, axis=1)
        values = np.where(active, values, 0.0)
        normals = np.matmul(gradients, rotations.transpose(0, 2, 1)) * active[..., None]
        jacobian = -np.concatenate([np.cross(arm, normals), normals], axis=2)  # (k, m, 6)
        if support is not None:
            heights, rows = support_residuals(support, classes, rotations, translations, centre)
            values, jacobian = np.hstack([values, heights]), np.hstack([jacobian, rows])
        return values, jacobian

    values, jacobian = residuals(rotations, translations)
    cost = np.square(values).sum(axis=1)
    damping = np.full(len(classes), _DAMPING)
    for _ in range(iterations):
        transposed = jacobian.transpose(0, 2, 1)
        normal = np.matmul(transposed, jacobian)  # J^T J
        diagonal = np.einsum("kii->ki", normal)
        diagonal = diagonal + _FLOOR * diagonal.max(axis=1, keepdims=True) + np.finfo(float).tiny
        lhs = normal + (damping[:, None] * diagonal)[:, :, None] * np.eye(6)
        step = np.linalg.solve(lhs, -np.matmul(transposed, values[..., None]))[..., 0]
        turn = Rotation.from_rotvec(step[:, :3]).as_matrix()
        new_rotations = turn @ rotations
        new_translations = (np.einsum("kij,kj->ki", turn, translations - centre) + centre
                            + step[:, 3:])
        new_values, new_jacobian = residuals(new_rotations, new_translations)
        new_cost = np.square(new_values).sum(axis=1)
        better = new_cost < cost
        rotations[better], translations[better] = new_rotations[better], new_translations[better]
        values[better], jacobian[better], cost[better] = (new_values[better],
                                                          new_jacobian[better], new_cost[better])
        damping = np.where(better, damping / 3, damping * 10)
    return rotations, translations, cost


def surface_uncertainty(evaluate, class_index, rotation, translation, contacts, points,
                        normals, scale2, free_turns=(), pivot=None, support=None):
    """How far a refined pose may still be off: the standard deviation of each surface
    point's displacement along its normal (scene units).

    The pose's covariance is the Gauss-Newton one of :func:`refine_poses` on the contacts,
    ``C = s^2 (J^T J)^+`` (a direction nothing constrains, a turn about a round axis, moves
    no surface); a surface point ``x`` with normal ``n`` moves along ``n`` by
    ``g . (w, d)`` with ``g = ((x - c) x n, n)``, of variance ``g C g^T``.

    Parameters
    ----------
    evaluate : callable
        As for :func:`refine_poses`.
    class_index : int
    rotation : (3, 3) float
    translation : (3,) float
    contacts : (m, 3) float, world frame
    points, normals : (q, 3) float, object frame
        Surface points of the class and their outward unit normals.
    scale2 : float, squared scene units
        The residuals' variance ``s^2``.
    free_turns : (k, 3) float, world frame
        Unit axes through ``pivot`` of turns that move no surface (a round shape's axis,
        or three for a sphere): left out of the pose, as nothing but the shape's detail
        pins them and they move the surface by no more than that detail. Kept in, the
        near-null direction's vast variance put a hexagonal pencil's shaft 4-6 mm off at
        2 mm noise, where its pose was within 2.4 mm.
    pivot : (3,) float, world frame
        The point the free turns' axes pass through.
    support : Support, optional
        A table the pose rests on: its resting vertices' heights pin it as contacts do.

    Returns
    -------
    (q,) float
    """
    contacts = np.asarray(contacts, dtype=float)
    centre = contacts.mean(axis=0)
    local = ((contacts - translation) @ rotation)[None]
    _, gradients = evaluate(np.array([class_index]), local)
    contact_normals = gradients[0] @ rotation.T
    jacobian = np.concatenate([np.cross(contacts - centre, contact_normals), contact_normals],
                              axis=1)
    if support is not None:
        _, rows = support_residuals(support, np.array([class_index]), rotation[None],
                                    np.asarray(translation, float)[None], centre)
        jacobian = np.vstack([jacobian, rows[0]])
    # A turn w about an axis through the pivot p is (w, w x (c - p)) in these parameters.
    free = np.reshape(free_turns, (-1, 3))
    pivot = centre if pivot is None else np.asarray(pivot, dtype=float)
    free = np.concatenate([free, np.cross(free, centre - pivot)], axis=1)
    keep = np.eye(6) - free.T @ np.linalg.pinv(free.T) if len(free) else np.eye(6)
    information = keep @ (jacobian.T @ jacobian) @ keep
    covariance = scale2 * np.linalg.pinv(information, rcond=1e-9, hermitian=True)
    world = points @ rotation.T + translation
    world_normals = normals @ rotation.T
    rows = np.concatenate([np.cross(world - centre, world_normals), world_normals], axis=1)
    variance = np.einsum("qi,ij,qj->q", rows, covariance, rows)
    return np.sqrt(np.maximum(variance, 0.0))
