"""What a simulated trial measures against its ground truth (:class:`TruthEvaluator`,
outside the step), and the ground truth of a trial."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..explore.simulator import GroundTruth
from ..shape.metrics import (
    directed_hausdorff,
    pose_difference,
    pose_error as metric_pose_error,
    surface_hausdorff,
    surface_samples,
)
from ..shape.objects import ObjectModel
from ..shape.resting import resting_pose
from ..transforms import random_pose, transform_points


class TruthEvaluator:
    """What a simulated trial's steps measure against the object, outside the step: the
    session hands it each step's estimate and reports what it says beside the step
    (:class:`~.snapshot.Snapshot`'s error fields), untimed.

    Parameters
    ----------
    truth : GroundTruth
        The simulated object, placed in the world.
    samples : int
        Surface samples of the truth and of a reconstruction (``metric_samples``).

    Attributes
    ----------
    truth : GroundTruth
    samples : int
    points : (samples, 3) float, world frame
        The truth's surface samples.
    """

    def __init__(self, truth, samples):
        self.truth, self.samples = truth, int(samples)
        self.points = transform_points(surface_samples(truth.model, self.samples),
                                       truth.rotation, truth.translation)
        self._tree = self._placed = self._last_pose = self._last_recon = self._near = None

    def errors(self, model, rotation, translation, recon, contacts, final=False):
        """The snapshot's error fields of one step's estimate: ``pose_error``,
        ``recon_error`` (the paper's TWD on samples; None without a reconstruction),
        ``recon_surface_error`` (on the ``final`` step only: samples to the other surface,
        :func:`~..shape.metrics.surface_hausdorff`, 60-90 ms), ``truth_coverage`` (the
        truth's samples to the nearest contact) and, when the MAP is the truth's shape,
        ``rotation_error_deg`` and ``translation_error``.

        Parameters
        ----------
        model : ObjectModel
            The MAP shape.
        rotation : (3, 3) float
        translation : (3,) float, world frame
            Its pose (object to world).
        recon : Reconstruction or None
            The step's GPIS surface (its ``vertices`` and ``faces``), world frame.
        contacts : (n, 3) float, world frame
        final : bool

        Returns
        -------
        dict
        """
        recon_error = surface_error = None
        if recon is not None and len(recon.faces):
            samples, recon_error = self._recon_error(recon.vertices, recon.faces)
            if final:
                surface_error = surface_hausdorff(samples, (recon.vertices, recon.faces),
                                                  self.points, self._truth_surface())
        angle, distance = pose_difference(model, rotation, translation, self.truth)
        return {"pose_error": float(self._pose_error(model, rotation, translation)),
                "recon_error": recon_error, "recon_surface_error": surface_error,
                "truth_coverage": self._coverage(contacts),
                "rotation_error_deg": angle, "translation_error": distance}

    def _recon_error(self, vertices, faces):
        """The surface samples of a reconstruction and the paper's TWD from them to the
        truth's, remembered for the last surface (a surface held through checks is
        reported again, often unchanged)."""
        key = (np.asarray(vertices).tobytes(), np.asarray(faces).tobytes())
        if self._last_recon is None or self._last_recon[0] != key:
            mesh = trimesh.Trimesh(vertices, faces, process=False)
            samples, _ = trimesh.sample.sample_surface(mesh, self.samples, seed=0)
            error = max(directed_hausdorff(samples, self.points, self._truth_tree()),
                        directed_hausdorff(self.points, samples))
            self._last_recon = key, samples, error
        return self._last_recon[1:]

    def _coverage(self, contacts):
        """``truth_coverage``: the largest distance from the truth's samples to the nearest
        contact, the samples' distances kept and lowered by the contacts added since the
        last call (contacts are appended; anything else starts afresh)."""
        contacts = np.asarray(contacts, dtype=float).reshape(-1, 3)
        seen, nearest = self._near if self._near is not None else (np.zeros((0, 3)), None)
        if len(contacts) < len(seen) or not np.array_equal(contacts[:len(seen)], seen):
            seen, nearest = np.zeros((0, 3)), None
        added = contacts[len(seen):]
        if len(added):
            distance = cKDTree(added).query(self.points)[0]
            nearest = distance if nearest is None else np.minimum(nearest, distance)
        self._near = contacts.copy(), nearest
        return float("inf") if nearest is None else float(nearest.max())

    def _pose_error(self, model, rotation, translation):
        """:func:`~..shape.metrics.pose_error` of the MAP, remembered for the last pose (the
        MAP often stays where it was for many steps)."""
        key = (id(model), np.asarray(rotation).tobytes(), np.asarray(translation).tobytes())
        if self._last_pose is None or self._last_pose[0] != key:
            self._last_pose = key, metric_pose_error(model, rotation, translation,
                                                     self.truth, self.samples)
        return self._last_pose[1]

    def _truth_tree(self):
        """A KD-tree of the truth's samples, built once."""
        if self._tree is None:
            self._tree = cKDTree(self.points)
        return self._tree

    def _truth_surface(self):
        """The truth's vertices (world frame) and faces, placed once."""
        if self._placed is None:
            truth = self.truth
            self._placed = (transform_points(truth.model.mesh.vertices, truth.rotation,
                                             truth.translation), truth.model.mesh.faces)
        return self._placed


def make_truth(model: ObjectModel, rng=None, max_translation: float = 1.0,
               scene=None) -> GroundTruth:
    """The ground truth of a trial: ``model`` at a random pose, translated up to
    ``max_translation`` size units (a sixth of its longest side each); with a ``scene``
    that has a table, at a random stable pose on it
    (:func:`~..shape.resting.resting_pose`)."""
    if scene is not None and scene.has_table:
        rotation, translation = resting_pose(model, scene, rng, 0.5 * max_translation)
        return GroundTruth(model, rotation, translation)
    rotation, translation = random_pose(rng, max_translation * model.size_unit)
    return GroundTruth(model, rotation, translation)
