"""The Screened Poisson baseline (Kazhdan and Hoppe 2013) through pymeshlab.

pymeshlab is an optional dependency (the ``bench`` extra); :func:`require_poisson` gives a
clear message naming the extra when it is missing.
"""

import time

import numpy as np
import trimesh

from ..engine.errors import TactileVizError
from ..engine.shape.metrics import two_way_hausdorff

INSTALL_HINT = ("the Screened Poisson baseline needs pymeshlab: pip install "
                "'tactile_viz[bench]' (or pip install pymeshlab), or pass --no-poisson")


class MissingDependency(TactileVizError):
    """An optional package a benchmark needs is not installed."""


def require_poisson():
    """Import and return ``pymeshlab`` or raise :class:`MissingDependency` naming the extra."""
    try:
        import pymeshlab
    except ImportError as error:
        raise MissingDependency(f"{INSTALL_HINT} ({error})") from None
    return pymeshlab


def screened_poisson(points, normals, depth=9):
    """Screened Poisson surface of an oriented point cloud.

    Parameters
    ----------
    points, normals : (n, 3) array_like
        Contact positions and outward unit normals (world frame).
    depth : int
        Octree depth (the paper uses 9).

    Returns
    -------
    vertices : (k, 3) ndarray
    faces : (m, 3) ndarray of int
    """
    pymeshlab = require_poisson()
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    if len(points) < 4:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=points, v_normals_matrix=normals))
    # One thread: the multithreaded solver is not bit-reproducible.
    meshes.generate_surface_reconstruction_screened_poisson(depth=int(depth), preclean=True,
                                                            threads=1)
    mesh = meshes.current_mesh()
    return (np.asarray(mesh.vertex_matrix(), dtype=np.float64),
            np.asarray(mesh.face_matrix(), dtype=np.int64))


def poisson_error(points, normals, truth_samples, samples=3000, depth=9):
    """Reconstruct with :func:`screened_poisson` and measure the TWD to the truth.

    Parameters
    ----------
    points, normals : (n, 3) array_like
    truth_samples : (k, 3) ndarray
        Surface samples of the ground truth at its pose.
    samples : int
        Surface samples drawn on the reconstruction (seeded, area-uniform).
    depth : int

    Returns
    -------
    dict
        ``recon_error`` (None when the reconstruction is empty), ``n_vertices``, ``n_faces``,
        ``depth`` and ``seconds``.
    """
    start = time.perf_counter()
    vertices, faces = screened_poisson(points, normals, depth)
    error = None
    if len(faces):
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        drawn, _ = trimesh.sample.sample_surface(mesh, samples, seed=0)
        error = float(two_way_hausdorff(drawn, truth_samples))
    return {"recon_error": error, "n_vertices": int(len(vertices)), "n_faces": int(len(faces)),
            "depth": int(depth), "seconds": time.perf_counter() - start}
