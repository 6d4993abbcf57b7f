"""Poses of a near-symmetric shape the particles may never hold (beyond the paper).

A mug upside down fits touches of its outside as well, and its handle may lie anywhere
round its body while nothing touched it; a screwdriver under noise is posed about its
shaft only by its tip. :func:`flips` proposes the first kind to the decision, and
:func:`turn_round_hypotheses` turns the refined hypotheses of a round shape about its axis
to where the contacts' normals fit best.
"""

import numpy as np
from scipy.spatial.transform import Rotation

from .oriented import turned_cost
from .pose_refinement import refine_poses

ROUND_MOMENTS = 0.2  # an axis with its other two moments this close: turned in steps of
ROUND_TURN_DEG = 15.0  # (a handle turned 45 degrees off lies 3 cm from one 20 degrees off)
# Turns tried about a round axis at each near hypothesis (not 0: its own cost is known).
FAN_DEG = np.r_[-30:0:5, 5:31:5].astype(float)
FAN_NATS = 20.0  # hypotheses within this cost of the least costly are turned so


def flips(pf, class_index, rotation, translation):
    """The MAP's pose turned half about each principal axis of its shape (through the
    centre of mass), and in steps of ``ROUND_TURN_DEG`` about an axis the shape is nearly
    round about (its other two moments within ``ROUND_MOMENTS``; in eighths of a turn
    about each when there are more than one, a near-sphere): the modes a
    near-symmetric shape is most easily mistaken in (a mug upside down, or its handle
    anywhere round the body while nothing touched it), which the particles may never have
    held. The refinement cannot turn a hypothesis towards an untouched handle, so the
    steps must be fine enough that one lies near it.

    Returns
    -------
    rotations : (k, 3, 3) float
    translations : (k, 3) float
    """
    cache = pf.bank.__dict__.setdefault("_flips", {})
    if class_index not in cache:
        axes, round_axes, centre = principal_axes(pf, class_index)
        turns = [Rotation.from_rotvec(np.pi * a).as_matrix() for a in axes]
        # One round axis (a mug): its modes are one turn, swept finely; a near-sphere's
        # are not a one-parameter family, and eighths about each axis keep it affordable.
        step = ROUND_TURN_DEG if len(round_axes) == 1 else 45.0
        for axis in round_axes:
            turns += [Rotation.from_rotvec(angle * axis).as_matrix()
                      for angle in np.radians(np.arange(step, 360, step))
                      if not np.isclose(angle, np.pi)]
        cache[class_index] = np.stack(turns), centre
    turns, centre = cache[class_index]
    return turned_poses(rotation, translation, turns, centre)


def turned_poses(rotation, translation, turns, centre):
    """A pose with its object turned by ``turns (f, 3, 3)`` about ``centre`` (object frame):
    x -> S (x - c) + c, then the pose: R S and t + R (c - S c)."""
    return rotation @ turns, translation + (centre - turns @ centre) @ rotation.T


def principal_axes(pf, class_index):
    """A class's principal axes ``(3, 3)``, those it is nearly round about (its other two
    moments within ``ROUND_MOMENTS``) and its centre of mass, object frame."""
    cache = pf.bank.__dict__.setdefault("_axes", {})
    if class_index not in cache:
        mesh = pf.models[class_index].mesh
        axes = np.asarray(mesh.principal_inertia_vectors)
        moments = np.asarray(mesh.principal_inertia_components, float)
        others = [np.delete(moments, i) for i in range(3)]
        round_axes = [axis for axis, pair in zip(axes, others)
                      if np.ptp(pair) <= ROUND_MOMENTS * pair.max()]
        cache[class_index] = (axes, np.reshape(round_axes, (-1, 3)),
                              np.asarray(mesh.center_mass, float))
    return cache[class_index]


def turn_round_hypotheses(pf, oriented, classes, rotations, translations, misfit, turned,
                          scale2, outside, normal_noise_deg, among=None):
    """Each refined hypothesis within ``FAN_NATS`` of the least costly whose shape is round
    about one axis, turned about it by ``FAN_DEG`` and kept at its least costly turn
    (squared residuals over ``2 s^2`` and the normals' cost).

    The positions pin such a pose about its axis only by a small part, whose normals pin
    it far better: at 2 mm noise a flat screwdriver's refined pose sat 20 degrees off
    about its shaft, its tip's normals 20-60 degrees off, and the cross was decided.

    Parameters
    ----------
    pf : ParticleFilter
        Its bank, models, parameters and contacts are read.
    oriented : OrientedEvaluator
    classes : (k,) int
    rotations : (k, 3, 3) float
    translations : (k, 3) float, world frame
        The refined poses.
    misfit, turned : (k,) float
        Their squared residuals (squared scene units) and normals' cost (nats).
    scale2 : float, squared scene units
        The residuals' variance ``s^2``.
    outside : (q, 3) float, world frame
        Non-contacts and points of missed paths, as refined.
    normal_noise_deg : float
    among : (j,) int, optional
        The hypotheses that may be turned (default all): one a mode, the flips of a round
        class 15 degrees apart being one.

    Returns
    -------
    rotations, translations, misfit, turned : the arrays given, those hypotheses replaced
    """
    cost = misfit / (2 * scale2) + turned
    if not np.isfinite(cost).any():
        return rotations, translations, misfit, turned
    among = np.arange(len(cost)) if among is None else np.asarray(among)
    near = [k for k in among[cost[among] <= np.nanmin(cost) + FAN_NATS]
            if len(principal_axes(pf, classes[k])[1]) == 1]
    if not near:
        return rotations, translations, misfit, turned
    posed = []
    for k in near:
        _, (axis,), centre = principal_axes(pf, classes[k])
        turns = Rotation.from_rotvec(np.radians(FAN_DEG)[:, None] * axis).as_matrix()
        posed.append(turned_poses(rotations[k], translations[k], turns, centre))
    fan_classes = np.repeat(classes[near], len(FAN_DEG))
    fan_rotations = np.concatenate([r for r, _ in posed])
    fan_translations = np.concatenate([t for _, t in posed])
    *_, fan_misfit = refine_poses(pf.bank.evaluate, fan_classes, fan_rotations, fan_translations,
                                  pf.contact_positions, outside, 0,
                                  trim=pf.params.outlier_probability, normals=pf.contact_normals,
                                  oriented=oriented)
    fan_turned = turned_cost(oriented, fan_classes, fan_rotations, fan_translations,
                             pf.contact_positions, pf.contact_normals, normal_noise_deg)
    fan_cost = (fan_misfit / (2 * scale2) + fan_turned).reshape(len(near), len(FAN_DEG))
    rotations, translations = rotations.copy(), translations.copy()
    misfit, turned = misfit.copy(), turned.copy()
    for row, k in enumerate(near):
        best = row * len(FAN_DEG) + int(np.argmin(fan_cost[row]))
        if fan_cost.flat[best] < cost[k]:
            rotations[k], translations[k] = fan_rotations[best], fan_translations[best]
            misfit[k], turned[k] = fan_misfit[best], fan_turned[best]
    return rotations, translations, misfit, turned
