"""The table a hypothesis rests on, as residuals of its pose (beyond the paper).

An object at rest on a table lies in one of its stable poses: the face of its convex hull
it stands on (:func:`~..shape.resting.stable_rotations`) lies on the plane. A hypothesis
whose downward direction is within ``STABLE_ANGLE_DEG`` of a stable pose's is asked to
put that face's hull vertices on the table; any other only its lowest hull vertex. Each
such vertex adds the residual ``h = up . (R x + t - q)``, its height above the table
point ``q``, weighed as a contact: three or more pin the height and the tilt that
contacts on the top and the sides of a small block leave loose.
"""

import functools
from dataclasses import dataclass

import numpy as np

from ..shape.resting import hull_points, stable_rotations

STABLE_ANGLE_DEG = 20.0  # a hypothesis this near a stable pose rests on its face
FACE_TOLERANCE = 1e-4  # of the size: hull vertices this near the plane are its face


@functools.lru_cache(maxsize=64)
def resting_faces(model):
    """``(hull, downs, faces)`` of a model: its hull vertices (h, 3), object frame; the
    downward unit direction of each stable pose (s, 3), object frame; and for each the
    indices of the hull vertices on its face."""
    hull = hull_points(model)
    rotations, _ = stable_rotations(model)
    downs = -rotations[:, 2, :]  # R_s^T (0, 0, -1)
    heights = hull @ downs.T  # (h, s): depth below the centre along each down
    tolerance = FACE_TOLERANCE * model.length
    faces = tuple(np.flatnonzero(heights[:, s] >= heights[:, s].max() - tolerance)
                  for s in range(len(downs)))
    return hull, downs, faces


@functools.lru_cache(maxsize=64)
def _padded_faces(model):
    """Each stable face's hull vertices, padded with its first to the largest face's
    count: ``(s, w, 3)``, and the counts ``(s,)``."""
    hull, _, faces = resting_faces(model)
    width = max(len(face) for face in faces)
    padded = np.stack([hull[np.r_[face, np.repeat(face[:1], width - len(face))]]
                       for face in faces])
    return padded, np.array([len(face) for face in faces])


@dataclass(frozen=True, eq=False)
class Support:
    """A table under the hypotheses: its upward unit normal ``up`` and a point of it
    ``floor_point`` (world frame), and the library's ``models`` (by class index)."""

    up: np.ndarray
    floor_point: np.ndarray
    models: tuple

    def width(self, classes):
        """The most hull vertices any pose of these classes rests on."""
        return max(_padded_faces(self.models[int(c)])[0].shape[1] for c in np.unique(classes))

    def points(self, classes, rotations):
        """The hull vertices each hypothesis rests on, object frame.

        Parameters
        ----------
        classes : (k,) int
        rotations : (k, 3, 3) float
            ``object_to_world``.

        Returns
        -------
        points : (k, p, 3) float
            Padded with the first of each row's to the most vertices any pose of these
            classes rests on (the same width whatever the rotations).
        mask : (k, p) bool
            The real ones.
        """
        classes = np.asarray(classes).astype(np.int64)
        cos_limit = np.cos(np.radians(STABLE_ANGLE_DEG))
        down = -np.einsum("kji,j->ki", rotations, self.up)  # the table's down, object frame
        unique = np.unique(classes)
        width = self.width(unique)
        points = np.empty((len(classes), width, 3))
        counts = np.empty(len(classes), np.int64)
        for c in unique:  # one look-up a class, not a hypothesis
            rows = np.flatnonzero(classes == c)
            hull, downs, _ = resting_faces(self.models[int(c)])
            padded, sizes = _padded_faces(self.models[int(c)])
            dots = down[rows] @ downs.T  # (n, s)
            best = np.argmax(dots, axis=1)
            on_face = dots[np.arange(len(rows)), best] >= cos_limit
            lowest = hull[np.argmax(down[rows] @ hull.T, axis=1)]  # (n, 3)
            chosen = np.where(on_face[:, None, None], padded[best],
                              lowest[:, None, :])  # (n, w_c, 3)
            points[rows, :chosen.shape[1]] = chosen
            points[rows, chosen.shape[1]:] = chosen[:, :1]
            counts[rows] = np.where(on_face, sizes[best], 1)
        mask = np.arange(width)[None] < counts[:, None]
        return points, mask


def support_residuals(support, classes, rotations, translations, centre):
    """The heights above the table of the vertices each pose rests on, and their
    derivatives in :func:`~.pose_refinement.refine_poses`' parameters (a turn ``w`` about
    ``centre`` and a shift ``d``: ``dh = (a x up) . w + up . d``, ``a`` the vertex less the
    centre).

    Returns
    -------
    values : (k, p) float, scene units
        0 at padding.
    jacobian : (k, p, 6) float
    """
    local, mask = support.points(classes, rotations)
    world = np.einsum("kij,kpj->kpi", rotations, local) + translations[:, None]
    values = np.where(mask, (world - support.floor_point) @ support.up, 0.0)
    arm = world - centre
    up = np.broadcast_to(support.up, arm.shape)
    jacobian = np.concatenate([np.cross(arm, up), up], axis=2) * mask[..., None]
    return values, jacobian


def table_support(pf):
    """The :class:`Support` of a filter's scene, or None without a table."""
    scene = pf.scene
    if not scene.has_table:
        return None
    return Support(np.asarray(scene.up, float), np.asarray(scene.table_point, float),
                   tuple(pf.models))
