"""Point-pair features (Drost et al. 2010) and the alignment of oriented point pairs.

For two oriented points ``(p1, n1), (p2, n2)`` with ``d = p2 - p1`` the feature is
``F = (|d|, angle(n1, d), angle(n2, d), angle(n1, n2))``. Quantised features key a hash
table of all ordered pairs of an object's feature points; an observed pair looks up the
model pairs that look alike, and aligning each model pair onto the observed pair gives a
full 6-DOF pose hypothesis.
"""

from dataclasses import dataclass
from itertools import product

import numpy as np
from scipy.spatial.transform import Rotation

from ..shape.sdf import normalise_rows

# A pair whose difference vector is within this angle of either normal fixes no rotation
# about that normal, so its alignment is undefined.
DEGENERATE_ANGLE = np.radians(3.0)
_KEY_BITS = 15  # per quantised component; 4 components packed into one int64


def angle_between(a, b):
    """Angle in [0, pi] between vectors, robust near 0 and pi: (...,) for (..., 3) inputs."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.arctan2(cross, np.einsum("...i,...i->...", a, b))


def pair_features(p1, n1, p2, n2):
    """Point-pair features of ordered oriented pairs.

    Parameters
    ----------
    p1, n1, p2, n2 : (..., 3) float
        Positions and unit normals of the first and second points.

    Returns
    -------
    (..., 4) float
        Distance and the three angles (radians).
    """
    d = np.asarray(p2, dtype=float) - p1
    return np.stack([np.linalg.norm(d, axis=-1), angle_between(n1, d),
                     angle_between(n2, d), angle_between(n1, n2)], axis=-1)


def is_degenerate(p1, n1, p2, n2, min_distance=1e-6):
    """True where the pair cannot fix a pose: coincident points or d parallel to a normal."""
    features = pair_features(p1, n1, p2, n2)
    near_parallel = lambda angle: np.minimum(angle, np.pi - angle) < DEGENERATE_ANGLE  # noqa: E731
    return ((features[..., 0] < min_distance) | near_parallel(features[..., 1])
            | near_parallel(features[..., 2]))


def quantise(features, distance_step=0.1, angle_step=np.radians(12.0)):
    """Integer bins of features: distance and angles rounded to the nearest step.

    Returns
    -------
    (..., 4) int64
    """
    return np.rint(_scaled(features, distance_step, angle_step)).astype(np.int64)


def _scaled(features, distance_step, angle_step):
    """Features in units of their key steps: (..., 4) float."""
    steps = np.array([distance_step, angle_step, angle_step, angle_step])
    return np.asarray(features) / steps


def neighbour_bins(features, distance_step=0.1, angle_step=np.radians(12.0), neighbours=0):
    """The key bins each observed feature looks up.

    Parameters
    ----------
    features : (q, 4) float
    distance_step, angle_step : float
        The key steps (scene units, radians).
    neighbours : int
        0: the own bin only; 1: both neighbouring bins of the distance and, per angle,
        the neighbouring bin on the side the feature lies closest to: the 3 x 2^3 = 24
        bins that hold every model pair whose feature lies within one step of the observed
        one in distance and half a step in each angle (noise tolerance at 24 times the
        look-ups); 2: every bin within one step, 3^4 = 81.

    Returns
    -------
    (q, b, 4) int64
        ``b`` = 1, 24 or 81 bins per feature (some may be negative, i.e. hold no key); with
        24 the own bin is the first.
    """
    scaled = _scaled(features, distance_step, angle_step).reshape(-1, 4)
    bins = np.rint(scaled).astype(np.int64)
    if neighbours == 1:
        # Each angle's neighbour on the side of its bin's centre the feature lies on (rint
        # rounds halves to even: a feature at a centre looks to the upper side); the
        # distance, which carries two positions' noise, both neighbours.
        side = np.where(scaled >= bins, 1, -1)
        side[:, 0] = 1
        offsets = np.array(list(product((0, 1, -1), (0, 1), (0, 1), (0, 1))))
        return bins[:, None, :] + offsets[None] * side[:, None, :]
    reach = 1 if neighbours else 0
    offsets = np.array(list(product(range(-reach, reach + 1), repeat=4)))
    return bins[:, None, :] + offsets[None]


def pack_keys(bins):
    """One int64 key per (..., 4) bin vector (components must lie in [0, 2**15))."""
    bins = np.asarray(bins, dtype=np.int64)
    return ((bins[..., 0] << (3 * _KEY_BITS)) | (bins[..., 1] << (2 * _KEY_BITS))
            | (bins[..., 2] << _KEY_BITS) | bins[..., 3])


def rotation_to_x(normals):
    """Rotations taking unit normals onto +x: (k, 3, 3) for (k, 3)."""
    normals = normalise_rows(np.atleast_2d(normals))
    x = np.array([1.0, 0.0, 0.0])
    axis = np.cross(normals, x)
    sin = np.linalg.norm(axis, axis=1)
    cos = normals[:, 0]
    # Near -x the axis vanishes; any perpendicular axis (here z) rotates by pi.
    axis = np.where(sin[:, None] > 1e-9, axis / np.maximum(sin, 1e-300)[:, None], [0.0, 0.0, 1.0])
    sin = np.where(sin > 1e-9, sin, 0.0)
    cos = np.where(sin > 0, cos, np.sign(cos) + (cos == 0))
    return Rotation.from_rotvec(axis * np.arctan2(sin, cos)[:, None]).as_matrix()


def rotation_about_x(angles):
    """Rotations about +x by angles: (k, 3, 3)."""
    angles = np.atleast_1d(np.asarray(angles, dtype=float))
    return Rotation.from_rotvec(angles[:, None] * [1.0, 0.0, 0.0]).as_matrix()


def local_frames(p1, n1, p2):
    """The canonical frame of ordered pairs: ``T_g`` and the angle ``alpha``.

    ``T_g = (R_g, -R_g p1)`` moves ``p1`` to the origin and turns ``n1`` onto +x; ``alpha``
    is the rotation about x that brings ``T_g p2`` into the half plane ``y > 0, z = 0``.

    Returns
    -------
    rotation : (k, 3, 3)
    translation : (k, 3)
    alpha : (k,)
    """
    rotation = rotation_to_x(n1)
    translation = -np.einsum("kij,kj->ki", rotation, np.atleast_2d(p1))
    moved = np.einsum("kij,kj->ki", rotation, np.atleast_2d(p2)) + translation
    alpha = -np.arctan2(moved[:, 2], moved[:, 1])
    return rotation, translation, alpha


def align_pairs(model_pairs, observed_pairs):
    """Poses ``object_to_world`` that put model pairs onto observed pairs.

    Parameters
    ----------
    model_pairs : tuple of (k, 3) float
        ``(p1, n1, p2)`` in the object frame.
    observed_pairs : tuple of (k, 3) float
        ``(p1, n1, p2)`` in the world frame.

    Returns
    -------
    rotation : (k, 3, 3)
    translation : (k, 3)
    """
    rm, tm, alpha_m = local_frames(*model_pairs)
    rs, ts, alpha_s = local_frames(*observed_pairs)
    # object_to_world = T_g(s)^-1  R_x(alpha_m - alpha_s)  T_g(m)
    rx = rotation_about_x(alpha_m - alpha_s)
    rs_inv = np.transpose(rs, (0, 2, 1))
    rotation = rs_inv @ rx @ rm
    translation = np.einsum("kij,kj->ki", rs_inv @ rx, tm) - np.einsum("kij,kj->ki", rs_inv, ts)
    return rotation, translation


@dataclass(frozen=True, eq=False)
class PairTable:
    """Ordered pairs of feature points of one or many priors, grouped by quantised key.

    One table serves every prior of a library, as Drost et al. keep one for all models: a
    look-up costs the same for ten priors or a thousand, and the pairs are stored in
    compact integer types (4 bytes a pair for fewer than 65,536 priors of at most 256
    feature points each).

    Attributes
    ----------
    keys : (u,) int64
        The distinct packed keys, sorted.
    starts : (u + 1,) int64
        The pairs of ``keys[i]`` are entries ``starts[i]`` to ``starts[i + 1]``.
    classes : (m,) unsigned int
        The prior of each pair (0 in a single object's table).
    first, second : (m,) unsigned int
        Feature-point indices of each pair.
    distance_step, angle_step : float
        The quantisation the keys were made with (scene units, radians).
    """

    keys: np.ndarray
    starts: np.ndarray
    classes: np.ndarray
    first: np.ndarray
    second: np.ndarray
    distance_step: float
    angle_step: float

    def __len__(self):
        return len(self.first)

    @property
    def nbytes(self):
        return sum(a.nbytes for a in (self.keys, self.starts, self.classes, self.first,
                                      self.second))

    @classmethod
    def build(cls, points, normals, distance_step=0.1, angle_step=np.radians(12.0)):
        """Table of the non-degenerate ordered pairs of one object's ``(n, 3)`` points and
        normals."""
        n = len(points)
        first, second = np.nonzero(~np.eye(n, dtype=bool))
        keep = ~is_degenerate(points[first], normals[first], points[second], normals[second])
        first, second = first[keep], second[keep]
        features = pair_features(points[first], normals[first], points[second], normals[second])
        keys = pack_keys(quantise(features, distance_step, angle_step))
        order = np.argsort(keys, kind="stable")
        keys, first, second = keys[order], first[order], second[order]
        distinct, starts = _groups(keys)
        index = np.min_scalar_type(max(n - 1, 0))
        return cls(distinct, starts, np.zeros(len(keys), np.uint8), first.astype(index),
                   second.astype(index), float(distance_step), float(angle_step))

    @classmethod
    def combine(cls, tables):
        """One table over single-object tables (class ``i`` is the ``i``-th), filled in
        place by key without a sort of all pairs."""
        tables = list(tables)
        if not tables:
            raise ValueError("no pair tables to combine")
        steps = {(t.distance_step, t.angle_step) for t in tables}
        if len(steps) > 1:
            raise ValueError(f"pair tables of different key steps {sorted(steps)}")
        keys = np.unique(np.concatenate([t.keys for t in tables]))
        counts = np.zeros(len(keys), np.int64)
        for table in tables:
            counts[np.searchsorted(keys, table.keys)] += np.diff(table.starts)
        starts = np.concatenate([[0], np.cumsum(counts)])
        total = int(starts[-1])
        classes = np.empty(total, np.min_scalar_type(max(len(tables) - 1, 0)))
        index = np.result_type(*(t.first.dtype for t in tables))
        first, second = np.empty(total, index), np.empty(total, index)
        fill = starts[:-1].copy()
        for c, table in enumerate(tables):
            slots, sizes = np.searchsorted(keys, table.keys), np.diff(table.starts)
            # Each key's pairs go after those of the tables before this one.
            target = np.repeat(fill[slots] - table.starts[:-1], sizes) + np.arange(len(table))
            classes[target] = c
            first[target], second[target] = table.first, table.second
            fill[slots] += sizes
        return cls(keys, starts, classes, first, second, *steps.pop())

    def to_arrays(self):
        return {"keys": self.keys, "starts": self.starts, "classes": self.classes,
                "first": self.first, "second": self.second,
                "steps": np.array([self.distance_step, self.angle_step])}

    @classmethod
    def from_arrays(cls, arrays):
        steps = arrays["steps"]
        return cls(arrays["keys"], arrays["starts"], arrays["classes"], arrays["first"],
                   arrays["second"], float(steps[0]), float(steps[1]))

    def lookup(self, features, neighbours=0):
        """Pairs whose key matches each observed feature's (or a neighbouring) bin.

        Parameters
        ----------
        features : (q, 4) float
            Observed pair features.
        neighbours : int
            0 looks up the bin itself; 1 also the distance's two neighbouring bins and
            each angle's on the side the feature lies closest to (24 bins: every pair
            within one step in distance and half a step in the angles); 2 every bin within
            one step (81 bins). See :func:`neighbour_bins`.

        Returns
        -------
        query : (r,) int
            Index of the observed pair of each match.
        classes : (r,) int
            The prior of each match.
        first, second : (r,) int
            Feature-point indices of the matching pair.
        """
        bins = neighbour_bins(features, self.distance_step, self.angle_step, neighbours)
        shifted = bins.reshape(-1, 4)
        valid = (shifted >= 0).all(axis=1)
        query = np.repeat(np.arange(len(bins)), bins.shape[1])[valid]
        keys = pack_keys(shifted[valid])
        slot = np.minimum(np.searchsorted(self.keys, keys), max(len(self.keys) - 1, 0))
        found = self.keys[slot] == keys if len(self.keys) else np.zeros(len(keys), bool)
        query, slot = query[found], slot[found]
        low, counts = self.starts[slot], self.starts[slot + 1] - self.starts[slot]
        total = int(counts.sum())
        if total == 0:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, empty, empty
        positions = np.repeat(low - np.cumsum(counts) + counts, counts) + np.arange(total)
        return (np.repeat(query, counts), self.classes[positions].astype(np.int64),
                self.first[positions].astype(np.int64), self.second[positions].astype(np.int64))


def _groups(sorted_keys):
    """Distinct keys of a sorted array and the start of each one's run (plus the end)."""
    if len(sorted_keys) == 0:
        return sorted_keys, np.zeros(1, np.int64)
    new = np.flatnonzero(np.diff(sorted_keys)) + 1
    starts = np.concatenate([[0], new, [len(sorted_keys)]]).astype(np.int64)
    return sorted_keys[starts[:-1]], starts
