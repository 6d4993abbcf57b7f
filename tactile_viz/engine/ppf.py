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

from .sdf import normalise_rows

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
    steps = np.array([distance_step, angle_step, angle_step, angle_step])
    return np.rint(np.asarray(features) / steps).astype(np.int64)


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
    """All ordered pairs of an object's feature points, sorted by quantised feature key.

    Attributes
    ----------
    keys : (m,) int64
        Sorted packed keys of the non-degenerate ordered pairs.
    first, second : (m,) int
        Feature-point indices of each pair, in key order.
    distance_step, angle_step : float
        The quantisation the keys were made with.
    """

    keys: np.ndarray
    first: np.ndarray
    second: np.ndarray
    distance_step: float
    angle_step: float

    @classmethod
    def build(cls, points, normals, distance_step=0.1, angle_step=np.radians(12.0)):
        """Table of the ``n (n - 1)`` ordered pairs of ``(n, 3)`` points and normals."""
        n = len(points)
        first, second = np.nonzero(~np.eye(n, dtype=bool))
        keep = ~is_degenerate(points[first], normals[first], points[second], normals[second])
        first, second = first[keep], second[keep]
        features = pair_features(points[first], normals[first], points[second], normals[second])
        keys = pack_keys(quantise(features, distance_step, angle_step))
        order = np.argsort(keys, kind="stable")
        return cls(keys[order], first[order], second[order], float(distance_step),
                   float(angle_step))

    def to_arrays(self):
        return {"keys": self.keys, "first": self.first, "second": self.second,
                "steps": np.array([self.distance_step, self.angle_step])}

    @classmethod
    def from_arrays(cls, arrays):
        steps = arrays["steps"]
        return cls(arrays["keys"], arrays["first"], arrays["second"], float(steps[0]),
                   float(steps[1]))

    def lookup(self, features, neighbours=0):
        """Model pairs whose key matches each observed feature's (or a neighbouring) bin.

        Parameters
        ----------
        features : (q, 4) float
            Observed pair features.
        neighbours : int
            0 looks up the bin itself; 1 also the 80 bins that differ by one step in any
            component (tolerates noise at 81 times the look-ups).

        Returns
        -------
        query : (r,) int
            Index of the observed pair of each match.
        first, second : (r,) int
            Feature-point indices of the matching model pair.
        """
        bins = quantise(features, self.distance_step, self.angle_step)
        offsets = np.array(list(product(range(-neighbours, neighbours + 1), repeat=4)))
        shifted = (bins[:, None, :] + offsets[None]).reshape(-1, 4)
        valid = (shifted >= 0).all(axis=1)
        query = np.repeat(np.arange(len(bins)), len(offsets))[valid]
        keys = pack_keys(shifted[valid])
        low = np.searchsorted(self.keys, keys, side="left")
        high = np.searchsorted(self.keys, keys, side="right")
        counts = high - low
        total = int(counts.sum())
        if total == 0:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, empty
        query = np.repeat(query, counts)
        starts = np.repeat(low - np.cumsum(counts) + counts, counts)
        positions = starts + np.arange(total)
        return query, self.first[positions], self.second[positions]
