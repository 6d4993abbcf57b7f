"""Poses of a near-symmetric shape the particles may never hold (beyond the paper).

A mug upside down fits touches of its outside as well, and its handle may lie anywhere
round its body while nothing touched it; a screwdriver under noise is posed about its
shaft only by its tip, and a bumpy ball all round by its bumps. :func:`flips` proposes the
first kind to the decision, :func:`turn_round_hypotheses` turns the refined hypotheses of
a round shape about its axis to where the contacts' normals fit best, and
:func:`turn_near_spheres` a bumpy ball's about its centre.
"""

import numpy as np
from scipy.spatial.transform import Rotation

from ..shape.symmetry import symmetry_group
from ..transforms import inverse_transform_points_batch
from .oriented import turned_cost
from .pose_refinement import refine_poses
from .support import table_support

ROUND_MOMENTS = 0.2  # an axis with its other two moments this close: turned in steps of
ROUND_TURN_DEG = 15.0  # (a handle turned 45 degrees off lies 3 cm from one 20 degrees off)
# Turns tried about a round axis at each near hypothesis (not 0: its own cost is known).
FAN_DEG = np.r_[-30:0:5, 5:31:5].astype(float)
FAN_NATS = 20.0  # hypotheses within this cost of the least costly are turned so
SPHERE_TURNS = 2000  # turns of a near-sphere tried (about 20 degrees apart), scored unrefined,
SPHERE_SCREENED = 100  # the closest this many by position weighed by their normals too,
SPHERE_REFINED = 8  # the least costly this many refined
SPHERE_DETAIL = 0.002  # a sphere's detail (RMS, share of its size) that makes its turn count


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
        axes, moments, centre = pf.models[class_index].inertia
        others = [np.delete(moments, i) for i in range(3)]
        round_axes = [axis for axis, pair in zip(axes, others)
                      if np.ptp(pair) <= ROUND_MOMENTS * pair.max()]
        cache[class_index] = axes, np.reshape(round_axes, (-1, 3)), centre
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
    fan_cost, fan = _cost(pf, oriented, np.repeat(classes[near], len(FAN_DEG)),
                          np.concatenate([r for r, _ in posed]),
                          np.concatenate([t for _, t in posed]), outside, normal_noise_deg,
                          scale2, 0)
    fan_cost = fan_cost.reshape(len(near), len(FAN_DEG))
    rotations, translations = rotations.copy(), translations.copy()
    misfit, turned = misfit.copy(), turned.copy()
    for row, k in enumerate(near):
        best = row * len(FAN_DEG) + int(np.argmin(fan_cost[row]))
        if fan_cost.flat[best] < cost[k]:
            rotations[k], translations[k], misfit[k], turned[k] = (r[best] for r in fan)
    return rotations, translations, misfit, turned


def sphere_turns(count=SPHERE_TURNS):
    """``count`` turns spread over all of SO(3), the same every call: ``(count, 3, 3)``."""
    return Rotation.random(count, random_state=0).as_matrix()


def turn_near_spheres(pf, oriented, classes, rotations, translations, misfit, turned, scale2,
                      outside, normal_noise_deg, among=None):
    """The least costly hypothesis of each class within ``FAN_NATS`` of the least costly
    whose shape is a sphere but for its detail (:func:`_rough_sphere`), turned about its centre
    to every one of :func:`sphere_turns`; the ``SPHERE_SCREENED`` whose contacts lie closest
    are weighed with their normals, the ``SPHERE_REFINED`` least costly refined, and the
    hypothesis kept at the least costly of those if it beats its own cost.

    Positions alone pin a bumpy ball's turn only by bumps as small as the noise; the
    bumps' normals pin it better, wherever the particles left it: at 1 mm noise the bumpy
    ball's hypotheses sat where their normals cost 23 nats, at its true pose 7.5, and the
    smooth ball was decided. Parameters and returns as :func:`turn_round_hypotheses`.
    """
    cost = misfit / (2 * scale2) + turned
    if not np.isfinite(cost).any():
        return rotations, translations, misfit, turned
    among = np.arange(len(cost)) if among is None else np.asarray(among)
    near = {}  # one search a class (it covers every turn), from its least costly hypothesis
    for k in among[np.argsort(cost[among], kind="stable")]:
        if cost[k] <= np.nanmin(cost) + FAN_NATS and _rough_sphere(pf.models[classes[k]]):
            near.setdefault(int(classes[k]), int(k))
    if not near:
        return rotations, translations, misfit, turned
    rotations, translations = rotations.copy(), translations.copy()
    misfit, turned = misfit.copy(), turned.copy()
    turns = sphere_turns()
    for k in near.values():
        centre = principal_axes(pf, classes[k])[2]
        tried_rotations, tried_translations = turned_poses(rotations[k], translations[k],
                                                           turns, centre)
        tried_classes = np.full(len(turns), classes[k])
        # Screened by the contacts' distances alone (cheap), then by their normals too.
        local = inverse_transform_points_batch(pf.contact_positions, tried_rotations,
                                               tried_translations)
        values, _ = pf.bank.evaluate(tried_classes, local)
        screened = np.argsort(np.square(values).sum(axis=1), kind="stable")[:SPHERE_SCREENED]
        normals_cost = turned_cost(oriented, tried_classes[screened], tried_rotations[screened],
                                   tried_translations[screened], pf.contact_positions,
                                   pf.contact_normals, normal_noise_deg)
        screened_cost = np.square(values[screened]).sum(axis=1) / (2 * scale2) + normals_cost
        best = screened[np.argsort(screened_cost, kind="stable")[:SPHERE_REFINED]]
        total, refined = _cost(pf, oriented, tried_classes[best], tried_rotations[best],
                               tried_translations[best], outside, normal_noise_deg, scale2,
                               pf.params.refine_iterations)
        j = int(np.argmin(total))
        if total[j] < cost[k]:
            rotations[k], translations[k], misfit[k], turned[k] = (r[j] for r in refined)
    return rotations, translations, misfit, turned


def _rough_sphere(model):
    """Whether a shape is a sphere but for detail above ``SPHERE_DETAIL`` of its size."""
    group = symmetry_group(model)
    return bool(group.is_sphere and group.roughness > SPHERE_DETAIL * model.length)


def _cost(pf, oriented, classes, rotations, translations, outside, normal_noise_deg, scale2,
          iterations):
    """Poses refined ``iterations`` times, their ``misfit / (2 s^2) + turned`` and
    ``(rotations, translations, misfit, turned)``."""
    rotations, translations, misfit = refine_poses(
        pf.bank.evaluate, classes, rotations, translations, pf.contact_positions, outside,
        iterations, trim=pf.params.outlier_probability, normals=pf.contact_normals,
        oriented=oriented, clearance=pf.scene.tip_radius, support=table_support(pf),
        below=pf.bank.below)
    turned = turned_cost(oriented, classes, rotations, translations, pf.contact_positions,
                         pf.contact_normals, normal_noise_deg)
    cost = np.where(np.isfinite(misfit), misfit / (2 * scale2) + turned, np.inf)
    return cost, (rotations, translations, misfit, turned)
