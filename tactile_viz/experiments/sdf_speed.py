"""Benchmark: grid SDF queries per second and error against exact signed distance.

``python -m tactile_viz bench sdf [--points N] [--objects NAME ...] [--resolution R]``

For each object, the same random points within 1 size unit of the surface are queried
through the grid SDF (value and gradient), libigl's exact distance (AABB + fast winding
number) and trimesh's exact ``signed_distance``; the first table gives queries per second
and the grid's speed-up over trimesh. The second gives the grid's size (16-bit codes, 2
bytes a node) and its error against the exact distance: of the value, in size units (a
sixth of the object's longest side), and of the normal near the surface (within 0.1 size
units, against the mesh's interpolated normal at the closest point), in degrees.
"""

import argparse
import time

import numpy as np

from ..cli import ArgumentParser, ExtendList, bundled_object, int_range, seed_int


def near_surface_points(model, count, rng, band=1.0):
    """Points within ``band`` of the surface: surface samples moved along random directions.

    Returns
    -------
    (count, 3) float, object frame
    """
    import trimesh

    surface, _ = trimesh.sample.sample_surface(model.mesh, count, seed=rng)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return surface + directions * rng.uniform(0, band, size=(count, 1))


def _rate(function, points):
    start = time.perf_counter()
    function(points)
    return len(points) / (time.perf_counter() - start)


def _chunked(function, points, size=5000):
    """trimesh's query gathers candidate triangles for all points at once; in chunks its
    memory stays bounded (100k points on a 20k-face creature exhausted 24 GB at once)."""
    return np.concatenate([function(chunk) for chunk in np.array_split(
        points, max(1, len(points) // size))])


def accuracy(model, points):
    """Errors of the model's grid against the exact distance at ``(k, 3)`` points.

    Returns
    -------
    dict
        ``value_median``, ``value_p99`` (size units), ``normal_median``, ``normal_p95``
        (degrees, at points within 0.1 size units of the surface) and ``megabytes``.
    """
    values, gradients = model.sdf.evaluate(points)
    exact, closest, face = model.exact.query(points)
    normals = model.exact.surface_normal(closest, face)
    value_error = np.abs(values - exact) / model.size_unit
    near = np.abs(exact) < 0.1 * model.size_unit
    angle = np.degrees(np.arccos(np.clip(np.sum(gradients[near] * normals[near], axis=1),
                                         -1.0, 1.0)))
    return {"value_median": float(np.median(value_error)),
            "value_p99": float(np.percentile(value_error, 99)),
            "normal_median": float(np.median(angle)) if len(angle) else float("nan"),
            "normal_p95": float(np.percentile(angle, 95)) if len(angle) else float("nan"),
            "megabytes": model.sdf.nbytes / 1e6}


def main(argv=None):
    parser = ArgumentParser(prog="python -m tactile_viz bench sdf", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", type=int_range(1, 10**7), default=100_000,
                        help="query points (default 100000)")
    parser.add_argument("--objects", action=ExtendList, default=["mug_1", "armadillo"],
                        type=bundled_object(),
                        help="bundled objects to measure (default mug_1 armadillo)")
    # 256 cells a side already take about half a gigabyte.
    parser.add_argument("--resolution", type=int_range(8, 256), default=64,
                        help="SDF grid resolution (8 to 256)")
    parser.add_argument("--skip-trimesh", action="store_true",
                        help="leave out trimesh (needs rtree; slow on large point sets)")
    parser.add_argument("--seed", type=seed_int, default=0)
    args = parser.parse_args(argv)

    from ..engine.shape.objects import load_bundled

    print(f"{args.points} points within 1 size unit of the surface, SDF grid resolution "
          f"{args.resolution}")
    print(f"{'object':<14} {'faces':>6} {'grid q/s':>12} {'libigl q/s':>12} "
          f"{'trimesh q/s':>12} {'grid/trimesh':>13} {'grid/libigl':>12}")
    errors = []
    for name in args.objects:
        model = load_bundled(name).with_params(sdf_resolution=args.resolution)
        rng = np.random.default_rng(args.seed)
        points = near_surface_points(model, args.points, rng, band=model.size_unit)
        model.sdf  # noqa: B018 (built, or read from the cache, outside the timing)
        grid = _rate(model.sdf.evaluate, points)
        exact = _rate(model.exact.signed_distance, points)
        if args.skip_trimesh:
            trimesh_rate = float("nan")
        else:
            try:
                import trimesh

                trimesh_rate = _rate(lambda p: _chunked(
                    lambda c: trimesh.proximity.signed_distance(model.mesh, c), p), points)
            except ImportError as error:
                raise SystemExit(f"trimesh's signed_distance needs rtree: "
                                 f"pip install -e '.[bench]' ({error})") from error
        print(f"{name:<14} {len(model.mesh.faces):>6} {grid:>12.0f} {exact:>12.0f} "
              f"{trimesh_rate:>12.0f} {grid / trimesh_rate:>12.1f}x {grid / exact:>11.1f}x")
        errors.append((name, model.sdf.shape, accuracy(model, points)))
    print(f"\n{'object':<14} {'grid nodes':>14} {'MB':>6} {'value err median':>17} "
          f"{'p99':>7} {'normal err median':>18} {'p95':>6}")
    for name, shape, e in errors:
        print(f"{name:<14} {'x'.join(map(str, shape)):>14} {e['megabytes']:>6.2f} "
              f"{e['value_median']:>13.5f} su {e['value_p99']:>7.4f} "
              f"{e['normal_median']:>16.2f} deg {e['normal_p95']:>6.2f}")
    return 0
