"""What a simulated trial measures against its ground truth (a mixin of
:class:`~.loop.Session`), and the ground truth of a trial."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..explore.simulator import GroundTruth
from ..shape.metrics import (
    directed_hausdorff,
    pose_difference,
    pose_error as metric_pose_error,
    surface_hausdorff,
)
from ..shape.objects import ObjectModel
from ..shape.resting import resting_pose
from ..transforms import random_pose, transform_points


class TruthMetrics:
    """Errors against ``self.truth`` (None without a simulated object)."""

    def _pose_difference(self, model, rotation, translation):
        """``rotation_error_deg`` and ``translation_error`` of the MAP against the simulated
        object (None without one, or when the MAP is another shape)."""
        if self.truth is None:
            return {}
        angle, distance = pose_difference(model, rotation, translation, self.truth)
        return {"rotation_error_deg": angle, "translation_error": distance}

    def _truth_tree(self):
        """A KD-tree of the truth's samples, built once (not pickled: a session pickles
        as its setup)."""
        if self.__dict__.get("_truth_kdtree") is None:
            self._truth_kdtree = cKDTree(self._truth_samples)
        return self._truth_kdtree

    def _pose_error(self, model, rotation, translation):
        """:func:`~..shape.metrics.pose_error` of the MAP, remembered for the last pose (the
        MAP often stays where it was for many steps)."""
        key = (id(model), np.asarray(rotation).tobytes(), np.asarray(translation).tobytes())
        last = self.__dict__.get("_last_pose_error")
        if last is None or last[0] != key:
            last = self._last_pose_error = key, metric_pose_error(
                model, rotation, translation, self.truth, self._p.metric_samples)
        return last[1]

    def _truth_metrics(self, model, rotation, translation, recon, contacts, final=False):
        """Pose error, reconstruction error (the paper's TWD on samples, and on the
        ``final`` step only, from samples to the other surface:
        :func:`~..shape.metrics.surface_hausdorff`, 60-90 ms) and truth coverage against
        the simulated object (None without one; the reconstruction errors None without a
        reconstruction)."""
        if self.truth is None:
            return None, None, None, None
        pose_error = self._pose_error(model, rotation, translation)
        recon_error = surface_error = None
        if recon is not None and len(recon.faces):
            mesh = trimesh.Trimesh(recon.vertices, recon.faces, process=False)
            samples, _ = trimesh.sample.sample_surface(mesh, self._p.metric_samples, seed=0)
            recon_error = max(directed_hausdorff(samples, self._truth_samples,
                                                 self._truth_tree()),
                              directed_hausdorff(self._truth_samples, samples))
            if final:
                surface_error = surface_hausdorff(samples, (recon.vertices, recon.faces),
                                                  self._truth_samples, self._truth_surface())
        return (float(pose_error), recon_error,
                directed_hausdorff(self._truth_samples, contacts), surface_error)

    def _truth_surface(self):
        """The truth's vertices (world frame) and faces, placed once."""
        if self.__dict__.get("_truth_placed") is None:
            truth = self.truth
            self._truth_placed = (transform_points(truth.model.mesh.vertices, truth.rotation,
                                                   truth.translation), truth.model.mesh.faces)
        return self._truth_placed


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
