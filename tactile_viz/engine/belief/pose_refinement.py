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

With ``normal_noise`` ``(s, sigma_n)`` each contact's measured normal ``n`` is a residual
too, ``lambda (N - n)`` with ``N`` the pose's outward normal there (world frame), whose
derivative in the turn is ``lambda N x e_j`` for its component ``j`` (a shift moves no
normal), and ``lambda = s / sqrt(sigma_n^2 + c^2)`` weighs it as the joint Gaussian does:
``c`` is how far the surface's normal turns across the position noise about the contact
(0 on a flat face, ``s / rho`` on a ball of radius ``rho``; :func:`normal_weights`).
A small object's turn is pinned by its flat faces' normals long before their positions
pin it: a 2 cm block under 2 mm noise turns by a degree for each 0.35 mm its corners
move. A contact whose normal lies farther than ``NORMAL_GATE_DEG`` from the pose's (an
edge, a turned face) says nothing of the turn.
"""

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..transforms import inverse_transform_points_batch
from .outside import dense_below, outside_terms
from .support import support_residuals

POSE_PARAMETERS = 6  # three of rotation, three of translation
_DAMPING = 1e-3  # initial Marquardt damping, relative to the diagonal of J^T J
# Of the largest diagonal entry, added to all: a direction nothing constrains stays put.
_FLOOR = 1e-12
_FITTED = 1e-9  # a fit this far below its start is done (with a tolerance: rounding)
NORMAL_GATE_DEG = 30.0  # three stds of the least normal noise the oriented match assumes
_FORWARD = np.finfo(float).eps ** 0.5  # scipy's relative step of a 2-point derivative


def refine_poses(evaluate, classes, rotations, translations, contacts, noncontacts=None,
                 iterations=10, trim=0.0, normals=None, oriented=None, clearance=0.0,
                 support=None, below=None, tolerance=0.0, normal_noise=None):
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
    below : callable, optional
        The non-contacts' look-up of :func:`~.outside.outside_terms`: the pairs of a
        pose and a non-contact inside the shape grown by ``clearance``
        (:meth:`~.prior_bank.PriorBank.below`, which skips the points far off unlooked;
        None: ``evaluate`` at every pair, :func:`~.outside.dense_below`).
    tolerance : float
        A pose's fit ends early once a step taken lowers its sum of squares by less than
        this share, or it is below ``_FITTED`` of where it began (0: every pose takes every
        step; a refused step raises the damping and the fit goes on).
    normal_noise : (float, float), optional
        ``(s, sigma_n)``, the position noise (length units) and the normal noise (radians):
        the measured ``normals`` are residuals too (None: positions alone).

    Returns
    -------
    rotations : (k, 3, 3) float
    translations : (k, 3) float
        The refined poses; a pose whose fit no step improved is returned unchanged.
    misfit : (k,) float, squared length units
        Their sum of squared residuals (the positions' and the table's: not the normals',
        which only pose the fit).
    """
    contacts = np.asarray(contacts, dtype=float)
    noncontacts = np.zeros((0, 3)) if noncontacts is None else np.asarray(noncontacts, float)
    if (oriented is not None or normal_noise is not None) and normals is None:
        raise ValueError("refine_poses: oriented or normal residuals need the contacts' "
                         "normals")
    measured = None if normals is None else np.asarray(normals, dtype=float)
    m, drop = len(contacts), int(np.ceil(trim * len(contacts)))
    centre = contacts.mean(axis=0)
    arm = contacts - centre  # a = p - c, (m, 3)
    classes = np.asarray(classes)
    rotations, translations = np.array(rotations, float), np.array(translations, float)
    below = below or dense_below(evaluate)
    weights = None if normal_noise is None else normal_weights(
        evaluate, classes, inverse_transform_points_batch(contacts, rotations, translations),
        *normal_noise)  # at the starting poses: (k, m)

    def residuals(rotations, translations, which):
        """The contacts' (and the table's and normals') residuals and Jacobian rows, and
        the non-contacts' sums (:func:`~.outside.outside_terms`)."""
        classes_ = classes[which]
        local = inverse_transform_points_batch(contacts, rotations, translations)  # R^T (p - t)
        values, gradients = evaluate(classes_, local)
        if oriented is not None:
            facing = inverse_transform_points_batch(measured, rotations)  # R^T n
            k, i = np.nonzero(np.einsum("kmj,kmj->km", gradients, facing) < 0)
            if len(k):
                values[k, i], gradients[k, i] = oriented(classes_[k], local[k, i], facing[k, i])
        if drop:  # the farthest contacts leave the fit: residual and row 0
            farthest = np.argsort(-np.abs(values), axis=1)[:, :drop]
            np.put_along_axis(values, farthest, 0.0, axis=1)
            np.put_along_axis(gradients, farthest[..., None], 0.0, axis=1)
        normals = np.matmul(gradients, rotations.transpose(0, 2, 1))
        jacobian = -np.concatenate([np.cross(arm, normals), normals], axis=2)  # (k, m, 6)
        if support is not None:
            heights, rows = support_residuals(support, classes_, rotations, translations, centre)
            # As wide as for every class (some poses are refined apart: ``tolerance``).
            pad = support.width(classes)
            heights = np.pad(heights, ((0, 0), (0, pad - heights.shape[1])))
            rows = np.pad(rows, ((0, 0), (0, pad - rows.shape[1]), (0, 0)))
            values, jacobian = np.hstack([values, heights]), np.hstack([jacobian, rows])
        if weights is not None:
            turns, rows = normal_residuals(normals, measured, weights[which])
            values, jacobian = np.hstack([values, turns]), np.hstack([jacobian, rows])
        outside = outside_terms(below, classes_, rotations, translations, noncontacts,
                                centre, clearance)
        return values, jacobian, outside

    # The normals' rows are the last 3 m: the misfit returned is the rest's.
    counted = slice(None, -3 * m if weights is not None else None)
    values, jacobian, (free, free_normal, free_gradient) = residuals(
        rotations, translations, np.arange(len(classes)))
    cost = np.square(values).sum(axis=1) + free
    damping = np.full(len(classes), _DAMPING)
    fitting = np.arange(len(classes))  # the poses still refined
    first, done = cost.copy(), np.zeros(len(classes), bool)
    for _ in range(iterations):
        if tolerance:
            fitting = np.flatnonzero(~done & (cost > _FITTED * first))
            if not len(fitting):
                break
        k = fitting
        transposed = jacobian[k].transpose(0, 2, 1)
        normal = np.matmul(transposed, jacobian[k]) + free_normal[k]  # J^T J
        diagonal = np.einsum("kii->ki", normal)
        diagonal = diagonal + _FLOOR * diagonal.max(axis=1, keepdims=True) + np.finfo(float).tiny
        lhs = normal + (damping[k][:, None] * diagonal)[:, :, None] * np.eye(6)
        rhs = np.matmul(transposed, values[k][..., None])[..., 0] + free_gradient[k]  # J^T r
        step = np.linalg.solve(lhs, -rhs[..., None])[..., 0]
        turn = Rotation.from_rotvec(step[:, :3]).as_matrix()
        new_rotations = turn @ rotations[k]
        new_translations = (np.einsum("kij,kj->ki", turn, translations[k] - centre) + centre
                            + step[:, 3:])
        new_values, new_jacobian, new_free = residuals(new_rotations, new_translations, k)
        new_cost = np.square(new_values).sum(axis=1) + new_free[0]
        better = new_cost < cost[k]
        # A step taken that gains less than the tolerance ends a pose's fit.
        done[k] = better & (new_cost >= cost[k] * (1 - tolerance))
        b = k[better]
        rotations[b], translations[b] = new_rotations[better], new_translations[better]
        values[b], jacobian[b], cost[b] = (new_values[better], new_jacobian[better],
                                           new_cost[better])
        free[b], free_normal[b], free_gradient[b] = (part[better] for part in new_free)
        damping[k] = np.where(better, damping[k] / 3, damping[k] * 10)
    return rotations, translations, np.square(values[:, counted]).sum(axis=1) + free


def normal_weights(evaluate, classes, local, scale, sigma):
    """Each contact's ``lambda = s / sqrt(sigma^2 + c^2)`` (see the module docstring).

    ``c^2`` is the mean squared turn of the unit gradient between ``x + s t`` and
    ``x - s t``, halved, over two tangents ``t`` at ``x`` (``(s / rho)^2`` on a ball of
    radius ``rho``): the normal's own spread under the position noise, large across an edge
    or a thin rod and 0 on a flat face.

    Parameters
    ----------
    evaluate : callable
        As for :func:`refine_poses`.
    classes : (k,) int
    local : (k, m, 3) float
        The contacts in each pose's object frame.
    scale : float, length units
        ``s``, the position noise.
    sigma : float, radians
        The normal noise.

    Returns
    -------
    (k, m) float, length units
    """
    _, gradient = evaluate(classes, local)
    unit = gradient / np.maximum(np.linalg.norm(gradient, axis=2, keepdims=True), 1e-300)
    # Two tangents: the normal crossed with the axis it is least aligned with, and again.
    axis = np.eye(3)[np.argmin(np.abs(unit), axis=2)]
    first = np.cross(unit, axis)
    first /= np.maximum(np.linalg.norm(first, axis=2, keepdims=True), 1e-300)
    second = np.cross(unit, first)
    offsets = scale * np.concatenate([first, -first, second, -second], axis=1)  # (k, 4m, 3)
    _, around = evaluate(classes, np.tile(local, (1, 4, 1)) + offsets)
    around = around / np.maximum(np.linalg.norm(around, axis=2, keepdims=True), 1e-300)
    m = local.shape[1]
    turn2 = (np.square(around[:, :m] - around[:, m:2 * m]).sum(axis=2)
             + np.square(around[:, 2 * m:3 * m] - around[:, 3 * m:]).sum(axis=2)) / 8
    return scale / np.sqrt(sigma**2 + turn2)


def normal_residuals(posed, measured, weight):
    """The contacts' normal residuals ``lambda (N - n)`` and their derivatives in
    :func:`refine_poses`' parameters (see the module docstring).

    Parameters
    ----------
    posed : (k, m, 3) float, world frame
        Each pose's outward normal direction at each contact (any length; 0 for a contact
        left out of the fit).
    measured : (m, 3) float, world frame
        The measured outward unit normals.
    weight : (k, m) float, length units
        ``lambda`` of each contact (:func:`normal_weights`).

    Returns
    -------
    values : (k, 3 m) float, length units
        0 for a contact whose normals lie farther apart than ``NORMAL_GATE_DEG``.
    jacobian : (k, 3 m, 6) float
    """
    length = np.linalg.norm(posed, axis=2, keepdims=True)
    unit = posed / np.maximum(length, np.finfo(float).tiny)
    gate = (np.einsum("kmj,mj->km", unit, measured)
            >= np.cos(np.radians(NORMAL_GATE_DEG))) & (length[..., 0] > 0)
    weight = np.where(gate, weight, 0.0)
    values = weight[..., None] * (unit - measured)  # (k, m, 3)
    # d(N)_j / dw = N x e_j: the rows of -[N]_x, the turn's cross-product matrix.
    turn = weight[..., None, None] * np.cross(unit[:, :, None, :], np.eye(3))
    k, m = gate.shape
    jacobian = np.concatenate([turn, np.zeros_like(turn)], axis=3)  # (k, m, 3, 6)
    return values.reshape(k, 3 * m), jacobian.reshape(k, 3 * m, 6)


def warm_starts(classes, rotations, translations, warm):
    """Where each pose starts: its refined pose of the last step when ``warm`` holds it.

    Parameters
    ----------
    classes : (k,) int
    rotations : (k, 3, 3) float
    translations : (k, 3) float
    warm : dict
        ``(class, rotation bytes, translation bytes)`` -> ``(rotation, translation)``: the
        last step's refined poses by their starts (a particle that survived resampling
        keeps its pose to the bit).

    Returns
    -------
    keys : list of tuple
        Each pose's key (its start as given).
    rotations, translations
        The starts, copies.
    started : (k,) bool
        Which start from a refined pose.
    """
    keys = [(int(c), r.tobytes(), t.tobytes()) for c, r, t in
            zip(classes, np.asarray(rotations, float), np.asarray(translations, float))]
    rotations, translations = np.array(rotations, float), np.array(translations, float)
    started = np.array([key in warm for key in keys], dtype=bool)
    for index in np.flatnonzero(started):
        rotations[index], translations[index] = warm[keys[index]]
    return keys, rotations, translations, started


def refine_warm(evaluate, classes, rotations, translations, warm, iterations, warm_iterations,
                contacts, noncontacts=None, **options):
    """:func:`refine_poses` in two batches: the poses marked ``warm`` (each starts from a
    pose refined at the last step, whose optimum one new contact moves little) take
    ``warm_iterations`` steps, the others ``iterations``.

    Parameters
    ----------
    evaluate, classes, rotations, translations, contacts, noncontacts, **options
        As for :func:`refine_poses`.
    warm : (k,) bool
    iterations, warm_iterations : int

    Returns
    -------
    rotations, translations, misfit
        As :func:`refine_poses`, in the order given.
    """
    classes, warm = np.asarray(classes), np.asarray(warm, dtype=bool)
    rotations, translations = np.array(rotations, float), np.array(translations, float)
    misfit = np.empty(len(classes))
    for chosen, steps in ((warm, warm_iterations), (~warm, iterations)):
        if chosen.any():
            rotations[chosen], translations[chosen], misfit[chosen] = refine_poses(
                evaluate, classes[chosen], rotations[chosen], translations[chosen], contacts,
                noncontacts, steps, **options)
    return rotations, translations, misfit


def surface_uncertainty(evaluate, class_index, rotation, translation, contacts, points,
                        normals, scale2, free_turns=(), pivot=None, support=None,
                        measured=None, normal_noise=None):
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
    measured : (m, 3) float, world frame, optional
        The contacts' measured outward normals, which pin the turn when ``normal_noise``
        is given (as in :func:`refine_poses`).
    normal_noise : (float, float), optional

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
    if normal_noise is not None:
        weights = normal_weights(evaluate, np.array([class_index]), local, *normal_noise)
        _, rows = normal_residuals(contact_normals[None], np.asarray(measured, float), weights)
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


def least_squares_pose(evaluate, class_index, rotation, translation, contacts, normals,
                       noncontacts, sigma_d, sigma_n, clearance=0.0, evaluations=70):
    """One pose fitted to every observation by scipy's trust-region least squares, the
    normals' raw differences residuals too: the filter's refinement of a particle.

    The residuals are the contacts' signed distances over ``sigma_d``, their grid normals
    less the measured ones over ``sigma_n`` and the non-contacts' ``min(s(x) - r, 0)`` over
    ``sigma_d``; the pose turns by a rotation vector about the contacts' centre and
    shifts. The Jacobian is scipy's forward difference (the same steps and arithmetic),
    its six poses evaluated in one call.

    Parameters
    ----------
    evaluate : callable
        As in :func:`refine_poses`.
    class_index : int
    rotation : (3, 3) float
        Object-to-world rotation the fit starts from.
    translation : (3,) float, world frame
    contacts, normals : (m, 3) float, world frame
        At least one contact and their measured outward unit normals.
    noncontacts : (q, 3) float, world frame
    sigma_d : float, length units
    sigma_n : float
        The normal residuals' scale.
    clearance : float, length units
        The probe tip's radius.
    evaluations : int
        Residual evaluations at most, the Jacobian's not counted.

    Returns
    -------
    rotation : (3, 3) float
    translation : (3,) float
    """
    contacts, normals = np.asarray(contacts, float), np.asarray(normals, float)
    points = np.vstack([contacts, np.asarray(noncontacts, float).reshape(-1, 3)])
    count, centre = len(contacts), contacts.mean(axis=0)

    def pose(x):
        turn = Rotation.from_rotvec(x[:3]).as_matrix()
        return turn @ rotation, turn @ (translation - centre) + centre + x[3:]

    def batch(steps):  # (b, 6) parameters -> (b, residuals)
        local, facing = np.empty((len(steps),) + points.shape), []
        for row, x in enumerate(steps):
            turned, shifted = pose(x)
            local[row] = (points - shifted) @ turned
            facing.append(normals @ turned)
        values, gradients = evaluate(np.full(len(steps), class_index), local)
        out = []
        for row in range(len(steps)):
            normal_error = gradients[row, :count] - facing[row]
            outside = np.minimum(values[row, count:] - clearance, 0.0)
            out.append(np.concatenate([values[row, :count] / sigma_d,
                                       normal_error.ravel() / sigma_n, outside / sigma_d]))
        return np.array(out)

    last = {}

    def residuals(x):
        last["x"], last["f"] = np.array(x), batch(np.asarray(x)[None])[0]
        return last["f"]

    def jacobian(x):
        f0 = last["f"] if np.array_equal(last.get("x"), x) else residuals(x)
        # scipy's 2-point step: sqrt(eps) max(1, |x|), positive at 0
        step = _FORWARD * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        steps = np.repeat(np.asarray(x, float)[None], len(x), axis=0)
        steps[np.arange(len(x)), np.arange(len(x))] = x + step
        return ((batch(steps) - f0) / ((x + step) - x)[:, None]).T

    result = least_squares(residuals, np.zeros(POSE_PARAMETERS), jac=jacobian, method="trf",
                           max_nfev=evaluations, x_scale=0.1)
    return pose(result.x)

