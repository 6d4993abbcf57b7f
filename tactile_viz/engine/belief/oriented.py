"""Contacts measured to the nearest surface that faces the way they do (beyond the paper).

A signed distance grid answers "how far is the nearest surface", whichever way that surface
faces. Near a thin wall that is the wrong question under noise: a contact pushed into a
2 mm wall by noise lies at most 1 mm from one of its faces, so a shape with a wall where
the object has none (the larger of two nested cups, a mug 4% larger than the truth) fits
noisy contacts *better* than the object itself: its residuals are folded. At 2 mm / 2
degrees that decided a cup for its nested twin and a mug for its larger copy.

A contact also reports its normal, and the folded fit explains it with a face turned
away: the grid's gradient there points against the measured normal. Such a contact (only
such: elsewhere the grid's distance is as good, and exact samples would make every flat
face of a library fit touches of one flat face alike) is matched to the surface sample
``(p, m)`` nearest in position and normal together,

    |x - p|^2 + lambda^2 |n - m|^2,        lambda = s / sigma_n,

the joint Gaussian of a position with noise ``s`` and a normal with noise ``sigma_n``
(small angles: ``|n - m| ~ angle``), and its residual is its distance to that sample's
tangent plane, ``r = m . (x - p)`` (point-to-plane: exact on planes, sampling-independent
to first order). A tangent plane says nothing far from its sample: when ``x`` lies
further than the samples' spacing ``h`` from ``p`` along the plane, the residual is
``sign(r) sqrt(r^2 + (t - h)^2)`` with ``t`` that tangential offset. A face turned away
costs ``2 lambda`` in position, so a contact on the outer face of a thin wall is measured
to the outer face, and the residual a right hypothesis leaves is the noise, unfolded.

The same match weighs the normals themselves (:func:`turned_cost`, for every contact): a
round rod's contacts face every way about its axis, a blade's only a few ways.
"""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..shape.meshes import bare_mesh
from ..transforms import inverse_transform_points_batch
from .prior_bank import kept_recent

SAMPLES = 20_000  # surface samples per class; point-to-plane forgives their spacing
MIN_NORMAL_NOISE_DEG = 10.0  # sample normals on curved parts and edges are this rough
NORMAL_CAP = 3.0  # a contact's normal costs at most this many stds (a scan's rough face)
# A grid's normal is this rough where the surface is flat (the pose fits add the turn of
# the normal across the position noise, :func:`~.pose_refinement.normal_weights`).
FIT_NORMAL_NOISE_DEG = 2.0
LEAF_SIZE = 32  # samples per leaf of a surface's tree
# What a bank keeps, least recently used dropped: a class's samples (about 1 MB) whatever
# the weight, and its tree for each weight (about 2 MB). The weight follows the MAP's size,
# so one class is asked at several; 16 surfaces thrashed in a 40-touch dragon trial (66
# built at 11 ms each).
_KEEP_SAMPLES = 64
_KEEP = 48  # trees, by class and weight


class SurfaceSamples:
    """A class's area-uniform surface samples and their face normals (deterministic).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The class's surface, object frame.
    count : int

    Attributes
    ----------
    points, normals : (count, 3) float, object frame
    spacing : float, length units
        ``sqrt(area / count)``: the samples' typical gap.
    """

    def __init__(self, mesh, count=SAMPLES):
        mesh = bare_mesh(mesh)
        points, faces = trimesh.sample.sample_surface(mesh, count, seed=0)
        self.points = np.asarray(points, float)
        self.normals = np.asarray(mesh.face_normals[faces], float)
        self.spacing = float(np.sqrt(max(mesh.area, 0.0) / count))


class OrientedSurface:
    """A class's surface samples in a tree over position and scaled normal.

    Parameters
    ----------
    mesh : trimesh.Trimesh or SurfaceSamples
        The class's surface, object frame, or its samples.
    weight : float, length units
        ``lambda``: the position a unit change of normal is worth.
    count : int
        Surface samples of a mesh (face normals; deterministic).
    """

    def __init__(self, mesh, weight, count=SAMPLES):
        samples = mesh if isinstance(mesh, SurfaceSamples) else SurfaceSamples(mesh, count)
        self.points, self.normals = samples.points, samples.normals
        self.spacing = samples.spacing
        self.weight = float(weight)
        # Larger leaves than cKDTree's 16: a turned-away contact's nearest sample in six
        # dimensions lies far off, and the search then visits fewer, fuller nodes faster
        # (1.4x at 2 mm noise; the same neighbours).
        self.tree = cKDTree(np.hstack([self.points, self.weight * self.normals]),
                            leafsize=LEAF_SIZE)

    def residuals(self, points, normals):
        """Point-to-plane residuals of ``points (m, 3)`` with measured ``normals (m, 3)``
        (object frame) and the matched samples' normals: ``(m,)``, ``(m, 3)``."""
        _, index = self.tree.query(np.hstack([points, self.weight * normals]))
        matched = self.normals[index]
        offset = points - self.points[index]
        along = np.einsum("ij,ij->i", matched, offset)
        across = np.linalg.norm(offset - along[:, None] * matched, axis=1)
        beyond = np.maximum(across - self.spacing, 0.0)
        return np.copysign(np.hypot(along, beyond), along), matched


class OrientedEvaluator:
    """``evaluate(classes (q,), points (q, 3), normals (q, 3))`` -> point-to-plane
    residuals ``(q,)`` and the matched outward normals ``(q, 3)``, each point in its
    class's object frame: ``oriented`` of :func:`~.pose_refinement.refine_poses`.

    Parameters
    ----------
    models : sequence of PriorModel
        Their meshes are sampled when a class is first evaluated.
    weight : float, length units
        ``lambda`` (:func:`normal_weight`).
    cache : dict, optional
        Where the surfaces' trees are kept between evaluators (by class and weight).
    samples : dict, optional
        Where the classes' samples are kept between evaluators (by class).
    fit_noise : (float, float), optional
        The position noise (length units) and normal noise (radians) with which the pose
        fits that use this evaluator weigh the contacts' normals too (``normal_noise`` of
        :func:`~.pose_refinement.refine_poses`); None: positions alone.
    """

    def __init__(self, models, weight, cache=None, samples=None, fit_noise=None):
        self.models, self.weight = models, float(weight)
        self.fit_noise = fit_noise
        self.cache = {} if cache is None else cache
        self.samples = {} if samples is None else samples

    def surface(self, class_index):
        c = int(class_index)
        return kept_recent(self.cache, (c, self.weight), lambda: OrientedSurface(
            kept_recent(self.samples, c, lambda: SurfaceSamples(self.models[c].mesh),
                        _KEEP_SAMPLES), self.weight), _KEEP)

    def __call__(self, classes, points, normals):
        classes = np.asarray(classes)
        values, gradients = np.empty(len(points)), np.empty((len(points), 3))
        for class_index in np.unique(classes):  # one look-up a class
            mine = classes == class_index
            values[mine], gradients[mine] = self.surface(class_index).residuals(
                points[mine], normals[mine])
        return values, gradients


def turned_cost(oriented, classes, rotations, translations, contacts, normals, noise_deg):
    """What the contacts' measured normals cost each pose, in nats: ``(k,)``.

    Each contact ``(x, n)`` is matched to its nearest sample ``(p, m)`` of the class (as
    in :class:`OrientedEvaluator`) and costs ``min(|n - m|, CAP sigma_n)^2 / (2 sigma_n^2)``,
    the log likelihood of a normal read with noise ``sigma_n`` (at least
    ``MIN_NORMAL_NOISE_DEG``: the samples' face normals are that rough on curved parts),
    bounded so that one rough face of a scan cannot outweigh every other contact. Positions
    alone cannot tell a pencil from a knife's blade at 2 mm noise (both fit a few touches of
    a 7 mm rod), but the rod's normals turn all the way round and the blade's do not.

    Parameters
    ----------
    oriented : OrientedEvaluator
    classes : (k,) int
    rotations : (k, 3, 3) float
        Object-to-world rotations.
    translations : (k, 3) float, world frame
    contacts, normals : (m, 3) float, world frame
        Contact positions and measured outward unit normals.
    noise_deg : float
        The sensor's normal noise (std, degrees).
    """
    return contact_turns(oriented, classes, rotations, translations, contacts, normals,
                         noise_deg).sum(axis=1)


def contact_turns(oriented, classes, rotations, translations, contacts, normals, noise_deg):
    """:func:`turned_cost` contact by contact: ``(k, m)`` nats, the same arguments."""
    sigma = np.radians(max(float(noise_deg), MIN_NORMAL_NOISE_DEG))
    rotations = np.asarray(rotations, float)
    local = inverse_transform_points_batch(contacts, rotations, translations)
    facing = inverse_transform_points_batch(normals, rotations)
    m = len(contacts)
    _, matched = oriented(np.repeat(classes, m), local.reshape(-1, 3), facing.reshape(-1, 3))
    apart = np.linalg.norm(facing.reshape(-1, 3) - matched, axis=1).reshape(-1, m)
    return 0.5 * np.square(np.minimum(apart / sigma, NORMAL_CAP))


def normal_weight(position_scale, normal_noise_deg):
    """``lambda = s / sigma_n``: scene units per unit of normal difference, with
    ``sigma_n`` at least ``MIN_NORMAL_NOISE_DEG``, rounded to a power of ``sqrt(2)`` (the
    samples are kept by it, and ``s`` follows the MAP's size from step to step)."""
    weight = float(position_scale) / np.radians(max(float(normal_noise_deg),
                                                    MIN_NORMAL_NOISE_DEG))
    return float(2.0 ** (np.round(2 * np.log2(max(weight, 1e-300))) / 2))


def oriented_evaluator(bank, models, position_scale, normal_noise_deg, in_fits=False):
    """An :class:`OrientedEvaluator` whose samples a prior bank keeps between steps; with
    ``in_fits`` the pose fits weigh the contacts' normals too, with a noise of at least
    ``FIT_NORMAL_NOISE_DEG``."""
    cache = bank.__dict__.setdefault("_oriented", {})
    samples = bank.__dict__.setdefault("_oriented_samples", {})
    fit_noise = (float(position_scale),
                 np.radians(max(float(normal_noise_deg), FIT_NORMAL_NOISE_DEG)))
    return OrientedEvaluator(models, normal_weight(position_scale, normal_noise_deg), cache,
                             samples, fit_noise if in_fits else None)
