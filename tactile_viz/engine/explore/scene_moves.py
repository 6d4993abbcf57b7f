"""The guarded moves of a robot's scene: every path a straight line of the tip's centre,
travelling within the reach cone and ended at the table (:class:`~..scene.Scene`).

The same procedures as :mod:`.exploration` (the first touch, contact enforcement with its
way back and surface following, a check line, an RRT step), each a generator that yields
paths and is sent their results, returning ``(paths, observations[, reached])``. Where the
free-space procedures move sideways across the surface or come back under an edge, these
lift the tip and come down again: a contact is always approached from within the cone.
Targets and contacts are surface points; a path aims the tip's centre at the point plus
the tip's radius along its normal. Table contacts never reach these procedures: the
session turns them into misses first.
"""

import functools

import numpy as np
from scipy.spatial import cKDTree

from .exploration import (
    follow_toward_moves,
    free_approach,
    lines_until_contact,
    sweep_directions,
)
from .observations import Contact

FIRST_SPREAD = 1.5  # size units: the first lines land within this of the table point


def first_moves(scene, centre, rng, radius=10.0, attempts=50, unit=1.0):
    """The random first touch: lines from random directions of the cone. On a table each
    comes down onto a random point of the table within ``FIRST_SPREAD unit`` of
    ``centre`` (the table point), so that it meets whatever rests there, however flat;
    without a table each passes through ``centre`` offset up to ``unit / 2``.

    Returns ``(paths, observations)``: the misses, then the contact.
    """
    def line():
        direction = scene.random_directions(1, rng)[0]
        if not scene.has_table:
            return scene.line(centre + rng.uniform(-0.5, 0.5, size=3) * unit, direction,
                              radius, radius)
        across = rng.normal(size=3)
        across -= (across @ scene.up) * scene.up
        across /= max(float(np.linalg.norm(across)), 1e-300)
        landing = (centre + FIRST_SPREAD * unit * np.sqrt(rng.uniform()) * across
                   + scene.tip_radius * scene.up)
        return scene.clip(np.stack([landing - radius * direction, landing]))

    return (yield from lines_until_contact(line, attempts, "random lines onto the table: is "
                                           "the object on the table near its point?"))


def reach_moves(scene, target, normal, contacts, contact_normals, depth=1.0, clearance=0.5,
                follow_step=0.1, spacing=0.3, max_follow=3.0, back_depth=0.04, anchors=1,
                estimate=None, unit=1.0):
    """Reach for a target from within the cone (the scene's
    :func:`~.exploration.enforce_contact_moves`): down onto the target along the cone's
    direction nearest its inward normal; after a miss, down onto the nearest contact (the
    next nearest when that touches nothing, up to ``anchors``), then surface following
    toward the target in lifted steps (:func:`follow_moves`).

    ``estimate`` (``(k, 3) -> (k,)``, positive outside the estimated object) shortens the
    approach to start short of what it predicts on the way (at least ``unit / 2``).

    Returns
    -------
    paths, observations, reached
        As :func:`~.exploration.enforce_contact_moves`.
    """
    direction = scene.approach(normal)
    if estimate is not None:  # come in short of what the estimate predicts on the way
        clearance = free_approach(estimate, target, -direction, clearance, unit)
    path = scene.line(scene.centre_of(target, normal), direction, clearance, depth)
    observation = yield path
    if isinstance(observation, Contact):
        return [path], [observation], True
    tree = cKDTree(contacts)
    paths, touched = [path], None
    for nearest in np.atleast_1d(tree.query(path[-1], k=min(anchors, len(contacts)))[1]):
        anchor, anchor_normal = contacts[nearest], contact_normals[nearest]
        back = scene.line(scene.centre_of(anchor, anchor_normal), scene.approach(anchor_normal),
                          clearance, back_depth)
        touched = yield back
        paths.append(back)
        if isinstance(touched, Contact):
            break
    if not isinstance(touched, Contact):
        return paths, [observation], False
    follow_paths, touched = yield from follow_moves(scene, touched, target, tree, follow_step,
                                                    spacing, max_follow)
    reached = bool(tree.query(touched.position)[0] >= spacing)
    return paths + follow_paths, [observation, touched], reached


def follow_moves(scene, contact, target, tree, step=0.1, spacing=0.3, max_follow=3.0):
    """Follow the surface from ``contact`` toward ``target`` as
    :func:`~.exploration.follow_toward_moves` does, each step coming down from within the
    cone onto the point ``step`` along the tangent plane; a miss (off an edge) ends it.

    Returns
    -------
    paths : list of (2, 3) arrays
    contact : Contact
    """
    return (yield from follow_toward_moves(contact, target, tree, step, spacing, max_follow,
                                           functools.partial(_come_down, scene)))


def _come_down(scene, moved, normal, position, step):
    return scene.line(scene.centre_of(moved, normal), scene.approach(normal), 2 * step,
                      2 * step)


def cone_directions(scene, count=64):
    """Spread directions of travel inside the cone (at least one: straight down),
    (k, 3) float."""
    candidates = -sweep_directions(count)
    inside = candidates[scene.in_reach(candidates, slack_deg=0.0)]
    return np.vstack([-scene.up[None], inside])


def check_line(scene, through, surface, used=(), reach=10.0, wanted=0.5, unit=1.0):
    """A check through ``through``: a straight line down from within the cone, from the
    direction that passes farthest from the estimated surface (least used among the clear
    ones), to the table.

    Returns
    -------
    path : (2, 3) float
    direction : (3,) float
        Its direction of travel.
    """
    candidates = cone_directions(scene)
    distances = np.linspace(0.3 * unit, reach, 40)
    samples = through - distances[None, :, None] * candidates[:, None, :]
    clearance = np.full(len(candidates), np.inf)
    if len(surface):
        clearance = cKDTree(surface).query(samples.reshape(-1, 3))[0].reshape(
            len(candidates), -1).min(1)
    used = np.reshape(used, (-1, 3))
    novelty = -(candidates @ used.T).max(axis=1) if len(used) else np.zeros(len(candidates))
    direction = candidates[int(np.argmax(np.minimum(clearance, wanted * unit) + 1e-3 * novelty))]
    return scene.line(through, direction, reach, reach), direction


def rrt_scene_moves(scene, contacts, contact_normals, workspace, rng, step=0.3, depth=1.0,
                    clearance=0.5, unit=1.0):
    """The RRT step of a scene: a random workspace sample, a step along the tangent plane
    of its nearest contact, touched from within the cone; off an edge, down onto the
    contact again."""
    low, high = workspace
    toward = rng.uniform(low, high)
    nearest = int(cKDTree(contacts).query(toward)[1])
    start, normal = contacts[nearest], contact_normals[nearest]
    tangent = toward - start
    tangent -= (tangent @ normal) * normal
    length = float(np.linalg.norm(tangent))
    if length < 1e-9:
        helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
        tangent, length = np.cross(normal, helper), 1.0
        length = float(np.linalg.norm(tangent))
    moved = start + min(step, max(length, 1e-3 * unit)) * tangent / length
    path = scene.line(scene.centre_of(moved, normal), scene.approach(normal), clearance, depth)
    observation = yield path
    if isinstance(observation, Contact):
        return [path], [observation]
    back = scene.line(scene.centre_of(start, normal), scene.approach(normal), clearance,
                      0.2 * unit)
    return [path, back], [(yield back)]
