"""Feature points: evenly spread oriented points on an object's surface."""

import numpy as np
import trimesh


def poisson_disk_points(mesh, count=200, rng=None, oversample=20):
    """Pick ``count`` surface points that are evenly spread (a Poisson-disk set).

    Draws ``oversample * count`` area-uniform candidates and keeps them by farthest-point
    selection, which yields exactly ``count`` points whose smallest pairwise distance is as
    large as greedy selection allows: a maximal Poisson-disk sample of that radius.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    count : int
    rng : int, numpy.random.Generator or None
    oversample : int

    Returns
    -------
    points : (count, 3) float, object frame
    faces : (count,) int
        The face each point lies on.
    """
    rng = np.random.default_rng(rng)
    candidates, faces = trimesh.sample.sample_surface(mesh, count * oversample, seed=rng)
    chosen = farthest_point_order(candidates, count, start=int(rng.integers(len(candidates))))
    return candidates[chosen], faces[chosen]


def farthest_point_order(points, count, start=0):
    """Indices of ``count`` points picked greedily, each farthest from those before it.

    Parameters
    ----------
    points : (n, 3) float
    count : int
    start : int

    Returns
    -------
    (min(count, n),) int
    """
    count = min(count, len(points))
    chosen = np.empty(count, dtype=np.int64)
    chosen[0] = start
    nearest = np.linalg.norm(points - points[start], axis=1)
    for i in range(1, count):
        chosen[i] = int(np.argmax(nearest))
        nearest = np.minimum(nearest, np.linalg.norm(points - points[chosen[i]], axis=1))
    return chosen
