"""Signed-distance primitives and operators (numpy only).

All functions take and return arrays: points are ``(n, 3) float``, distances
``(n,) float``; negative inside, positive outside. Most formulas follow Inigo
Quilez's catalogue of distance functions. Some results (ellipsoid, smooth
operators, displacement) are bounds rather than exact distances, which is all
that zero-level-set extraction needs.
"""

import numpy as np
from scipy.spatial.transform import Rotation


def _length(v):
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def rotation(axis, degrees):
    """Rotation matrix about an axis.

    Parameters
    ----------
    axis : (3,) float or {"x", "y", "z"}
        Rotation axis (normalised internally).
    degrees : float
        Angle, right-handed.

    Returns
    -------
    (3, 3) float
        Matrix ``R`` such that ``R @ v`` rotates ``v``.
    """
    if isinstance(axis, str):
        axis = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[axis]
    k = np.asarray(axis, float)
    return Rotation.from_rotvec(np.radians(degrees) * k / np.linalg.norm(k)).as_matrix()


def to_local(points, center, rot=None):
    """Express world points in a shape's local frame.

    Parameters
    ----------
    points : (n, 3) float
        World points.
    center : (3,) float
        Origin of the local frame.
    rot : (3, 3) float, optional
        Rotation taking local axes to world axes (columns are local axes).

    Returns
    -------
    (n, 3) float
        Local coordinates.
    """
    q = np.asarray(points, float) - np.asarray(center, float)
    return q if rot is None else q @ np.asarray(rot, float)


def sphere(points, center, radius):
    """Sphere.

    Parameters
    ----------
    points : (n, 3) float
    center : (3,) float
    radius : float

    Returns
    -------
    (n,) float
    """
    return _length(to_local(points, center)) - radius


def ellipsoid(points, center, radii, rot=None):
    """Ellipsoid (distance bound, exact on the surface).

    Parameters
    ----------
    points : (n, 3) float
    center : (3,) float
    radii : (3,) float
        Semi-axes along the local axes.
    rot : (3, 3) float, optional
        Local-to-world rotation.

    Returns
    -------
    (n,) float
    """
    r = np.asarray(radii, float)
    q = to_local(points, center, rot)
    k0 = _length(q / r)
    k1 = _length(q / (r * r))
    return k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)


def round_cone(points, a, b, ra, rb):
    """Round cone: convex hull of two spheres (a capsule if ``ra == rb``).

    Parameters
    ----------
    points : (n, 3) float
    a, b : (3,) float
        Sphere centres.
    ra, rb : float
        Radii at ``a`` and ``b``; ``|ra - rb|`` must be below ``|b - a|``.

    Returns
    -------
    (n,) float
    """
    a = np.asarray(a, float)
    ba = np.asarray(b, float) - a
    l2 = ba @ ba
    rr = ra - rb
    a2 = l2 - rr * rr
    if a2 <= 0:
        raise ValueError("one sphere contains the other")
    il2 = 1.0 / l2
    pa = np.asarray(points, float) - a
    y = pa @ ba
    z = y - l2
    x2 = np.einsum("ij,ij->i", pa * l2 - np.outer(y, ba), pa * l2 - np.outer(y, ba))
    y2 = y * y * l2
    z2 = z * z * l2
    k = np.sign(rr) * rr * rr * x2
    d_side = (np.sqrt(x2 * a2 * il2) + y * rr) * il2 - ra
    d_b = np.sqrt(x2 + z2) * il2 - rb
    d_a = np.sqrt(x2 + y2) * il2 - ra
    return np.where(np.sign(z) * a2 * z2 > k, d_b, np.where(np.sign(y) * a2 * y2 < k, d_a, d_side))


def capsule(points, a, b, radius):
    """Capsule (segment swept by a sphere).

    Parameters
    ----------
    points : (n, 3) float
    a, b : (3,) float
        Segment end points.
    radius : float

    Returns
    -------
    (n,) float
    """
    a = np.asarray(a, float)
    ba = np.asarray(b, float) - a
    pa = np.asarray(points, float) - a
    h = np.clip(pa @ ba / (ba @ ba), 0.0, 1.0)
    return _length(pa - np.outer(h, ba)) - radius


def polyline_tube(points, path, radii):
    """Chain of round cones through a polyline.

    Parameters
    ----------
    points : (n, 3) float
    path : (m, 3) float
        Polyline vertices, ``m >= 2``.
    radii : (m,) float
        Radius at each vertex.

    Returns
    -------
    (n,) float
    """
    d = np.full(len(points), np.inf)
    for i in range(len(path) - 1):
        d = np.minimum(d, round_cone(points, path[i], path[i + 1], radii[i], radii[i + 1]))
    return d


def round_box(points, center, half, radius=0.0, rot=None):
    """Box with rounded edges.

    Parameters
    ----------
    points : (n, 3) float
    center : (3,) float
    half : (3,) float
        Half extents including the rounding.
    radius : float
        Edge rounding radius.
    rot : (3, 3) float, optional
        Local-to-world rotation.

    Returns
    -------
    (n,) float
    """
    q = np.abs(to_local(points, center, rot)) - np.asarray(half, float) + radius
    outside = _length(np.maximum(q, 0.0))
    inside = np.minimum(q.max(axis=1), 0.0)
    return outside + inside - radius


def capped_cylinder(points, a, b, radius):
    """Flat-ended cylinder between two points.

    Parameters
    ----------
    points : (n, 3) float
    a, b : (3,) float
        Centres of the end caps.
    radius : float

    Returns
    -------
    (n,) float
    """
    a = np.asarray(a, float)
    ba = np.asarray(b, float) - a
    pa = np.asarray(points, float) - a
    baba = ba @ ba
    paba = pa @ ba
    x = _length(pa * baba - np.outer(paba, ba)) - radius * baba
    y = np.abs(paba - baba * 0.5) - baba * 0.5
    x2 = x * x
    y2 = y * y * baba
    d = np.where(
        np.maximum(x, y) < 0.0,
        -np.minimum(x2, y2),
        np.where(x > 0.0, x2, 0.0) + np.where(y > 0.0, y2, 0.0),
    )
    return np.sign(d) * np.sqrt(np.abs(d)) / baba


def torus(points, center, major, minor, rot=None):
    """Torus around the local z axis.

    Parameters
    ----------
    points : (n, 3) float
    center : (3,) float
    major : float
        Distance from the centre to the tube axis.
    minor : float
        Tube radius.
    rot : (3, 3) float, optional
        Local-to-world rotation.

    Returns
    -------
    (n,) float
    """
    q = to_local(points, center, rot)
    ring = np.hypot(q[:, 0], q[:, 1]) - major
    return np.hypot(ring, q[:, 2]) - minor


def polygon2d(q, vertices):
    """Exact signed distance to a simple closed polygon.

    Parameters
    ----------
    q : (n, 2) float
        Query points.
    vertices : (m, 2) float
        Polygon vertices in order (either orientation), not repeated at the end.

    Returns
    -------
    (n,) float
    """
    v = np.asarray(vertices, float)
    q = np.asarray(q, float)
    d2 = np.sum((q - v[0]) ** 2, axis=1)
    s = np.ones(len(q))
    j = len(v) - 1
    for i in range(len(v)):
        e = v[j] - v[i]
        w = q - v[i]
        t = np.clip(w @ e / (e @ e), 0.0, 1.0)
        b = w - np.outer(t, e)
        d2 = np.minimum(d2, np.einsum("ij,ij->i", b, b))
        c1 = q[:, 1] >= v[i, 1]
        c2 = q[:, 1] < v[j, 1]
        c3 = e[0] * w[:, 1] > e[1] * w[:, 0]
        flip = (c1 & c2 & c3) | (~c1 & ~c2 & ~c3)
        s = np.where(flip, -s, s)
        j = i
    return s * np.sqrt(d2)


def circle2d(q, center, radius):
    """Circle in 2D.

    Parameters
    ----------
    q : (n, 2) float
    center : (2,) float
    radius : float

    Returns
    -------
    (n,) float
    """
    return _length(np.asarray(q, float) - np.asarray(center, float)) - radius


def revolve(points, profile, center=(0.0, 0.0, 0.0)):
    """Solid of revolution about the vertical axis through ``center``.

    Parameters
    ----------
    points : (n, 3) float
    profile : (m, 2) float
        Outline as ``(r, z)`` pairs with ``r >= 0``, running from a point on
        the axis to another point on the axis.
    center : (3,) float
        Point on the axis; profile ``z`` is measured from it.

    Returns
    -------
    (n,) float
    """
    prof = np.asarray(profile, float)
    # Close the outline far out at negative r rather than along the axis, so
    # the axis carries no boundary; queries have r >= 0, so the extra edges
    # are never nearest.
    far = 10.0 * (np.abs(prof).max() + 1.0)
    polygon = np.vstack([prof, [(-far, prof[-1, 1]), (-far, prof[0, 1])]])
    q = to_local(points, center)
    return polygon2d(np.column_stack([np.hypot(q[:, 0], q[:, 1]), q[:, 2]]), polygon)


def extrude(d2, h, half_height):
    """Extrude a 2D distance along the third local axis.

    Parameters
    ----------
    d2 : (n,) float
        2D signed distance of each point's in-plane coordinates.
    h : (n,) float
        Each point's coordinate along the extrusion axis (0 at mid-plane).
    half_height : float

    Returns
    -------
    (n,) float
    """
    w = np.column_stack([d2, np.abs(h) - half_height])
    return np.minimum(w.max(axis=1), 0.0) + _length(np.maximum(w, 0.0))


def union(*ds):
    """Sharp union of any number of ``(n,) float`` distances."""
    return np.minimum.reduce(ds)


def smooth_union(a, b, k):
    """Polynomial smooth minimum.

    Parameters
    ----------
    a, b : (n,) float
    k : float
        Blend radius; 0 gives the sharp union.

    Returns
    -------
    (n,) float
    """
    if k <= 0:
        return np.minimum(a, b)
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b + (a - b) * h - k * h * (1.0 - h)


def smooth_union_all(ds, k):
    """Fold :func:`smooth_union` over a sequence of ``(n,) float`` distances."""
    ds = list(ds)
    out = ds[0]
    for d in ds[1:]:
        out = smooth_union(out, d, k)
    return out


def subtract(a, b):
    """``a`` minus ``b``; both ``(n,) float``."""
    return np.maximum(a, -b)


def smooth_subtract(a, b, k):
    """``a`` minus ``b`` with a rounded crease of radius ``k``."""
    return -smooth_union(-a, b, k)


def intersect(a, b):
    """Intersection of ``a`` and ``b``; both ``(n,) float``."""
    return np.maximum(a, b)


def shell(d, thickness):
    """Hollow shell of given thickness centred on the surface of ``d`` (``(n,) float``)."""
    return np.abs(d) - 0.5 * thickness


def bumps(points, amplitude, wavelength, seed, waves=32):
    """Deterministic smooth noise for surface displacement.

    A sum of plane waves with random directions and phases, normalised so its
    standard deviation is about ``amplitude``. Add it to a distance to
    perturb the surface.

    Parameters
    ----------
    points : (n, 3) float
    amplitude : float
    wavelength : float
        Typical bump spacing.
    seed : int
    waves : int

    Returns
    -------
    (n,) float
    """
    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(waves, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    freqs = 2 * np.pi / wavelength * rng.uniform(0.7, 1.3, size=waves)
    phases = rng.uniform(0, 2 * np.pi, size=waves)
    arg = np.asarray(points, float) @ (dirs * freqs[:, None]).T + phases
    return amplitude * np.sqrt(2.0 / waves) * np.sin(arg).sum(axis=1)
