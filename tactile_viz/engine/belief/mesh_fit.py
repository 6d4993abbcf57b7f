"""Hypotheses fitted on their meshes rather than their grids (beyond the paper).

The grids the filter and the decision's refinement read err most inside thin parts, where
a thin shape's noisy readings lie. :func:`mesh_misfit` refits one hypothesis on its
class's mesh (exact distance); :func:`weighed_on_meshes` weighs the few plausible
hypotheses of a decision so.
"""

from dataclasses import dataclass, field

import numpy as np

from .incremental import in_mode
from .outside import dense_below
from .pose_refinement import POSE_PARAMETERS, refine_poses
from .support import table_support

MESH_NATS = 9.2  # hypotheses within this of the most probable are weighed on their meshes,
MESH_HYPOTHESES = 4  # this many at most


@dataclass(frozen=True, eq=False)
class MeshFits:
    """Hypotheses refined on their meshes at one touch, for the next's starts.

    Attributes
    ----------
    classes : (k,) int
    rotations : (k, 3, 3) float
    translations : (k, 3) float
        Their poses on the grid (where the mesh's refinement started).
    mesh_rotations : (k, 3, 3) float
    mesh_translations : (k, 3) float
        Where it ended.
    """

    classes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    rotations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    translations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    mesh_rotations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    mesh_translations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


NO_FITS = MeshFits()


def mesh_misfit(pf, class_index, rotation, translation, outside, oriented, tolerance=0.0):
    """The squared residuals (squared scene units) of a class posed at ``rotation (3, 3)``,
    ``translation (3,)`` (world frame), refined on its mesh (exact distance) from there, as
    :func:`~.pose_refinement.refine_poses` sums them on the grid: the filter's contacts,
    and ``outside (q, 3)`` that lie inside; ``tolerance`` as
    :func:`~.pose_refinement.refine_poses`'."""
    return mesh_fit(pf, class_index, rotation, translation, outside, oriented,
                    tolerance=tolerance)[0]


def mesh_fit(pf, class_index, rotation, translation, outside, oriented, iterations=None,
             tolerance=0.0):
    """:func:`mesh_misfit` and the refined pose: ``(misfit, rotation (3, 3), translation
    (3,))``, refined in ``iterations`` steps (None: ``refine_iterations``)."""
    exact = pf.exact_distance(class_index)
    clearance = pf.scene.tip_radius
    low, high = exact.bounds
    last = {}  # the points of the last look-up and a lower bound of their distances

    def evaluate(classes, points):
        distance, _, face = exact.query_near(points.reshape(-1, 3))
        return distance.reshape(points.shape[:-1]), exact.face_normal(face).reshape(points.shape)

    def bounded(classes, points):
        # A free-space point farther than the tip's radius from the shape has residual 0
        # (refine_poses) whatever its exact distance, so a lower bound above the radius
        # stands in for it: its distance to the mesh's box, or its distance at the last
        # look-up less how far it moved since (a distance is 1-Lipschitz; a fit's steps
        # move the points little). Most points are spared the mesh's look-up.
        flat = points.reshape(-1, 3)
        bound = np.linalg.norm(np.maximum(np.maximum(low - flat, flat - high), 0.0), axis=1)
        if "points" in last and last["points"].shape == flat.shape:
            moved = np.linalg.norm(flat - last["points"], axis=1)
            bound = np.maximum(bound, last["bound"] - moved)
        asked = bound <= clearance
        distance, normals = bound, np.zeros_like(flat)
        normals[:, 2] = 1.0
        if asked.any():
            distance[asked], _, face = exact.query_near(flat[asked])
            normals[asked] = exact.face_normal(face)
        last.update(points=flat.copy(), bound=distance.copy())
        return distance.reshape(points.shape[:-1]), normals.reshape(points.shape)

    rotations, translations, misfit = refine_poses(
        evaluate, [class_index], rotation[None], translation[None], pf.contact_positions,
        outside, pf.params.refine_iterations if iterations is None else iterations,
        trim=pf.params.outlier_probability, normals=pf.contact_normals, oriented=oriented,
        clearance=pf.scene.tip_radius, support=table_support(pf), tolerance=tolerance,
        below=dense_below(bounded))
    return float(misfit[0]), rotations[0], translations[0]


def weighed_on_meshes(pf, classes, rotations, translations, log_p, charges, outside,
                      oriented, floor, warm=NO_FITS, distance=0.0, tolerance=0.0):
    """A fit posterior with its plausible hypotheses weighed again on their meshes.

    The plausible ones are those within ``MESH_NATS`` of the most probable
    (``MESH_HYPOTHESES`` at most, and at least two): their squared residuals on the grid
    are replaced by :func:`mesh_misfit`'s, and they keep their share of the whole. At
    2 mm a flat screwdriver at its true pose misfitted its grid twice as much as the
    cross screwdriver did (whose tip has no blade for the grid to err in), and the cross
    was decided.

    Parameters
    ----------
    pf : ParticleFilter
    classes : (k,) int
    rotations : (k, 3, 3) float
    translations : (k, 3) float, world frame
    log_p : (k,) float
        The fit posterior on the grids (unnormalised log).
    charges : (k,) float
        What each costs besides its residuals (the normals' and Occam's, nats), kept.
    outside : (q, 3) float, world frame
    oriented : OrientedEvaluator or None
    floor : float, scene units
        Least noise scale of the residuals.
    warm : MeshFits
        The last touch's: a hypothesis in the mode of one of its grid poses
        (:func:`~.incremental.in_mode` within ``distance``) starts from its mesh pose and
        (one new contact moves the optimum little: with a ``tolerance`` it converges in a
        few steps).
    tolerance : float
        As :func:`~.pose_refinement.refine_poses`'.

    Returns
    -------
    log_p : (k,) float
    fits : MeshFits
        This touch's, for the next.
    """
    plausible = np.flatnonzero(log_p >= log_p.max() - MESH_NATS)
    plausible = plausible[np.argsort(-log_p[plausible], kind="stable")][:MESH_HYPOTHESES]
    if len(plausible) < 2:
        return log_p, warm
    fitted = [_fitted(pf, int(classes[k]), rotations[k], translations[k], outside, oriented,
                      warm, distance, tolerance) for k in plausible]
    fits = MeshFits(classes[plausible], rotations[plausible], translations[plausible],
                    np.reshape([f[1] for f in fitted], (-1, 3, 3)),
                    np.reshape([f[2] for f in fitted], (-1, 3)))
    exact = np.array([f[0] for f in fitted])
    exact = np.where(np.isfinite(exact), exact, np.inf)
    if not np.isfinite(exact).any():
        return log_p, fits
    dof = max(len(pf.contact_positions) - POSE_PARAMETERS, 1)
    scale2 = max(exact.min() / dof, floor**2, 1e-300)
    weighed = -(exact - exact.min()) / (2 * scale2) - charges[plausible]  # as decide's log p
    log_p = log_p.copy()
    log_p[plausible] = (weighed - np.logaddexp.reduce(weighed)
                        + np.logaddexp.reduce(log_p[plausible]))
    return log_p, fits


def _fitted(pf, class_index, rotation, translation, outside, oriented, warm, distance,
            tolerance):
    """:func:`mesh_fit` from the grid's pose, or warm from the last touch's mesh pose of
    the same hypothesis (see :func:`weighed_on_meshes`)."""
    mine = np.flatnonzero(warm.classes == class_index)
    same = mine[in_mode(rotation, translation, warm.rotations[mine], warm.translations[mine],
                        distance)] if len(mine) else mine
    if not len(same):
        return mesh_fit(pf, class_index, rotation, translation, outside, oriented,
                        tolerance=tolerance)
    return mesh_fit(pf, class_index, warm.mesh_rotations[same[0]],
                    warm.mesh_translations[same[0]], outside, oriented, tolerance=tolerance)
