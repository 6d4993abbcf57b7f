"""What a decision carries to the next touch, so that a touch does not search afresh
(beyond the paper).

A decision refines some thirty hypotheses (the filter's modes and classes, look-alikes and
flips of the MAP, the rivals carried from the touch before) from their starts, ten
Levenberg-Marquardt steps each; it was most of what a known touch cost (issue 63). One new
contact moves every optimum little, so a touch starts from the last one's work:

- a candidate in the mode of a hypothesis the last touch refined (the same class, turned
  at most ``MODE_ANGLE_DEG`` and shifted at most the mode's distance from where that
  refinement started or ended: a particle that survived resampling, a flip of a MAP
  that moved little) is that hypothesis again, and it starts from its refined pose; between
  full searches it is left out (the plausible ones are carried and refined again; an
  implausible one is looked at again at the next full search). The MAP candidate is
  always refined from the filter's pose (started from the last refined pose of its mode,
  a mug's handle stayed unresolved for 70 touches more); of the candidates the
  last touch did not refine, ``decision_budget`` start afresh (the first: the filter's
  heaviest classes, then the MAP's other modes, its look-alikes and flips), the rest
  wait for the next full search;
- every fit stops once a step gains less than a small share of its squares (a warm one
  after a few steps).

An incremental touch also leaves the mesh fits (:mod:`.mesh_fit`) to the full searches: it
only aims at and carries rivals, which the grid's fit posterior does well enough (the
cups' and mugs' exact distances were half of such a touch).

A *full* search leaves nothing out. It comes every ``decision_refresh`` contacts, and
before any decision is reported: an incremental touch can only say "not yet" (what it
leaves out are rivals the last touch found implausible, and one that came back would
only be noticed late, never decided through); the touch after a decision is one too.
"""

from dataclasses import dataclass, field

import numpy as np

MODE_ANGLE_DEG = 10.0  # poses of one class closer than this (and a distance) are one mode


@dataclass(frozen=True, eq=False)
class Refined:
    """A decision's refined hypotheses, for the next touch's starts.

    Attributes
    ----------
    classes : (k,) int
    starts : ((k, 3, 3) float, (k, 3) float)
        Where each refinement started (``object_to_world`` rotation, translation).
    rotations : (k, 3, 3) float
        Where it ended.
    translations : (k, 3) float, scene units
    searched : int
        The contacts at the last full search.
    decided : bool
        Whether the decision was decided (the next touch then searches in full: it
        would, to confirm it).
    meshes : MeshFits or None
        The hypotheses it refined on their meshes (:mod:`.mesh_fit`).
    """

    classes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    starts: tuple = field(default_factory=lambda: (np.zeros((0, 3, 3)), np.zeros((0, 3))))
    rotations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    translations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    searched: int = -1
    decided: bool = False
    meshes: object = None


NOTHING = Refined()


def full_search_due(refined, contacts, every):
    """Whether a touch with ``contacts`` contacts searches afresh: every ``every`` contacts
    since the last full search (1 or less: always), when nothing was refined and after a
    decided touch."""
    return (every <= 1 or refined.searched < 0 or refined.decided
            or contacts - refined.searched >= every)


def in_mode(rotation, translation, rotations, translations, distance):
    """Which of ``rotations (k, 3, 3)``, ``translations (k, 3)`` lie in the mode of one
    pose: turned at most ``MODE_ANGLE_DEG`` from it and shifted at most ``distance``
    (scene units). (k,) bool."""
    cosine = (np.einsum("kij,ij->k", rotations, rotation) - 1) / 2  # cos of the turn between
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    gap = np.linalg.norm(translations - translation, axis=1)
    return (angle <= MODE_ANGLE_DEG) & (gap <= distance)


def starts(classes, rotations, translations, refined, distance, full, budget=np.inf):
    """Where a touch's fresh candidates start, and which it leaves out.

    Parameters
    ----------
    classes : (k,) int
        The fresh candidates, the MAP's first.
    rotations : (k, 3, 3) float
    translations : (k, 3) float, scene units
    refined : Refined
        The last touch's.
    distance : float, scene units
        How far apart two poses of one mode may lie.
    full : bool
        A full search: nothing is left out (refined starts are still used).
    budget : int
        Between full searches, the candidates besides the MAP's that start afresh at
        most (the first in order; the rest are left out).

    Returns
    -------
    rotations, translations
        The starts (copies).
    source : (k,) int
        The index in ``refined`` of the hypothesis each is (-1: none, and the MAP's; it
        starts afresh): one started or ended in its mode.
    kept : (k,) bool
        Which are refined (the MAP candidate always).
    """
    rotations, translations = np.array(rotations, float), np.array(translations, float)
    source, kept = np.full(len(classes), -1), np.ones(len(classes), bool)
    afresh = 0
    for index, c in enumerate(classes):
        if index == 0:  # the filter's MAP, refined from where the filter holds it
            continue
        found = _same(refined, c, rotations[index], translations[index], distance)
        if found is None:
            afresh += 1
            kept[index] = full or afresh <= budget
            continue
        source[index], kept[index] = found, full
        rotations[index], translations[index] = (refined.rotations[found],
                                                 refined.translations[found])
    return rotations, translations, source, kept


def _same(refined, class_index, rotation, translation, distance):
    """The index in ``refined`` of a hypothesis of the class that started or ended in the
    mode of a pose (None: none)."""
    mine = np.flatnonzero(refined.classes == class_index)
    if not len(mine):
        return None
    same = mine[in_mode(rotation, translation, refined.starts[0][mine],
                        refined.starts[1][mine], distance)
                | in_mode(rotation, translation, refined.rotations[mine],
                          refined.translations[mine], distance)]
    return int(same[0]) if len(same) else None


def remembered(refined, source, kept, begun, classes, ended, searched):
    """What a touch hands to the next.

    Parameters
    ----------
    refined : Refined
        The last touch's.
    source, kept : (f,) int, (f,) bool
        Of the touch's ``f`` fresh candidates (:func:`starts`).
    begun : ((f, 3, 3) float, (f, 3) float)
        The fresh candidates' own starts (before :func:`starts`).
    classes : (n,) int
        The hypotheses refined: the kept fresh candidates in order, then the carried.
    ended : ((n, 3, 3) float, (n, 3) float)
        Their refined poses.
    searched : int
        The contacts at the last full search.

    Returns
    -------
    Refined
        The hypotheses refined (each started where its fresh candidate did; a carried
        one where it ended at the last touch), and the last touch's hypothesis that each
        candidate left out is, started where that candidate did (one that is none
        waits for the next full search).
    """
    fresh = int(np.sum(kept))
    start_r = list(begun[0][kept]) + list(ended[0][fresh:])
    start_t = list(begun[1][kept]) + list(ended[1][fresh:])
    classes, end_r, end_t = list(classes), list(ended[0]), list(ended[1])
    for index in np.flatnonzero(~kept & (source >= 0)):
        old = source[index]
        classes.append(refined.classes[old])
        start_r.append(begun[0][index])
        start_t.append(begun[1][index])
        end_r.append(refined.rotations[old])
        end_t.append(refined.translations[old])
    return Refined(np.asarray(classes, np.int64),
                   (np.reshape(start_r, (-1, 3, 3)), np.reshape(start_t, (-1, 3))),
                   np.reshape(end_r, (-1, 3, 3)), np.reshape(end_t, (-1, 3)), searched)
