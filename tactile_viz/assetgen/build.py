"""Turn the catalogue's distance functions into normalised, watertight meshes.

Usage: ``python -m tactile_viz.assetgen [--out assets] [--only NAME ...]``.
"""

import hashlib
import io
import json
import sys
import time
from pathlib import Path

import igl
import numpy as np
import trimesh
from skimage.measure import marching_cubes

from tactile_viz.assetgen.catalog import CATALOG, by_name
from tactile_viz.cli import ArgumentParser, ExtendList, output_dir
from tactile_viz.engine.io.files import write_atomic

LONGEST_SIDE = 6.0
SPACING = 0.055  # grid spacing in final units
MAX_FACES = 20000
COARSE_CELLS = 48
PAD_CELLS = 3
GENERATOR = "python -m tactile_viz.assetgen"
DEFAULT_OUT = Path("assets")


def sample(sdf, lo, spacing, shape):
    """Evaluate a distance function on a regular grid.

    Parameters
    ----------
    sdf : callable
        Maps ``(n, 3) float`` points to ``(n,) float`` distances.
    lo : (3,) float
        Position of grid node ``(0, 0, 0)``.
    spacing : float
    shape : (3,) int

    Returns
    -------
    (nx, ny, nz) float
    """
    axes = [lo[i] + spacing * np.arange(shape[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return np.asarray(sdf(grid), float).reshape(shape)


def surface_bounds(spec):
    """Bounding box of the surface from a coarse pass over ``spec.bounds``.

    Returns
    -------
    lo, hi : (3,) float
        Box that contains the zero level set with a margin.
    """
    lo, hi = (np.asarray(b, float) for b in spec.bounds)
    h = (hi - lo).max() / COARSE_CELLS
    shape = np.ceil((hi - lo) / h).astype(int) + 1
    vol = sample(spec.sdf, lo, h, shape)
    if (border(vol) <= h).any():
        raise RuntimeError(f"{spec.name}: surface reaches the declared bounds")
    # a surface point is within sqrt(3)/2 h of some node whose distance is below h
    near = np.argwhere(vol < h)
    return lo + (near.min(axis=0) - 2) * h, lo + (near.max(axis=0) + 2) * h


def border(vol):
    """All values on the six faces of a ``(nx, ny, nz) float`` grid, flattened."""
    return np.concatenate(
        [vol[[0, -1]].ravel(), vol[:, [0, -1]].ravel(), vol[:, :, [0, -1]].ravel()]
    )


def extract(spec, spacing_final=SPACING):
    """Marching-cubes mesh of one catalogue object, in design units.

    Parameters
    ----------
    spec : catalog.ObjectSpec
    spacing_final : float
        Grid spacing expressed in final units (longest side 6).

    Returns
    -------
    trimesh.Trimesh
    """
    lo, hi = surface_bounds(spec)
    h = spacing_final * (hi - lo).max() / LONGEST_SIDE
    lo = lo - PAD_CELLS * h
    shape = np.ceil((hi - lo) / h).astype(int) + PAD_CELLS + 1
    vol = sample(spec.sdf, lo, h, shape)
    if (border(vol) <= 0).any():
        raise RuntimeError(f"{spec.name}: surface touches the grid border")
    # an exact zero on a node makes coincident vertices and degenerate faces
    vol[vol == 0.0] = 1e-9
    verts, faces, _, _ = marching_cubes(vol, 0.0, spacing=(h, h, h), method="lewiner")
    mesh = trimesh.Trimesh(verts + lo, faces, process=True)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def decimate(mesh, max_faces):
    """Quadric edge-collapse decimation with libigl; ``None`` if it breaks the mesh.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    max_faces : int

    Returns
    -------
    trimesh.Trimesh or None
    """
    v = np.asfortranarray(mesh.vertices, dtype=np.float64)
    f = np.asfortranarray(mesh.faces, dtype=np.int32)
    u, g, _, _ = igl.qslim(v, f, max_faces, True)  # True: refuse self-intersecting collapses
    out = trimesh.Trimesh(np.asarray(u), np.asarray(g), process=True)
    out.update_faces(out.nondegenerate_faces())
    out.remove_unreferenced_vertices()
    return out if problems(out) == [] else None


def problems(mesh):
    """List of violated mesh invariants (empty when the mesh is valid).

    Parameters
    ----------
    mesh : trimesh.Trimesh

    Returns
    -------
    list of str
    """
    found = []
    if not mesh.is_watertight:
        found.append("not watertight")
    if not mesh.is_winding_consistent:
        found.append("winding inconsistent")
    bodies = len(mesh.split(only_watertight=False))
    if bodies != 1:
        found.append(f"{bodies} bodies")
    if not mesh.volume > 0:
        found.append("non-positive volume")
    return found


def normalise(mesh):
    """Centre the bounding box at the origin and scale its longest side to 6.

    Parameters
    ----------
    mesh : trimesh.Trimesh

    Returns
    -------
    trimesh.Trimesh
        New mesh.
    """
    lo, hi = mesh.bounds
    v = (mesh.vertices - (lo + hi) / 2) * (LONGEST_SIDE / (hi - lo).max())
    # recentre once more so rounding in the scale cannot shift the box
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = v - (lo + hi) / 2
    return trimesh.Trimesh(v, mesh.faces.copy(), process=False)


def build_mesh(spec):
    """Final normalised mesh for one catalogue object.

    Parameters
    ----------
    spec : catalog.ObjectSpec

    Returns
    -------
    trimesh.Trimesh
    """
    spacing = SPACING
    for _ in range(6):
        mesh = extract(spec, spacing)
        if mesh.volume < 0:
            mesh.invert()
        found = problems(mesh)
        if found:
            raise RuntimeError(f"{spec.name}: {', '.join(found)}")
        if len(mesh.faces) <= MAX_FACES:
            return normalise(mesh)
        small = decimate(mesh, MAX_FACES)
        if small is not None:
            return normalise(small)
        spacing *= 1.1
    raise RuntimeError(f"{spec.name}: could not reach {MAX_FACES} faces")


def ply_bytes(mesh):
    """Binary PLY encoding (float32 vertices, as trimesh writes them), no extra attributes."""
    return trimesh.exchange.ply.export_ply(
        mesh, encoding="binary", vertex_normal=False, include_attributes=False
    )


def check_ply(name, data):
    """Raise if the encoded mesh, as a reader will see it, breaks an invariant.

    Parameters
    ----------
    name : str
    data : bytes
        Output of :func:`ply_bytes`.
    """
    mesh = trimesh.load(io.BytesIO(data), file_type="ply", force="mesh")
    found = problems(mesh)
    lo, hi = mesh.bounds
    # float32 storage must not spoil the normalisation
    if abs((hi - lo).max() - LONGEST_SIDE) > 1e-6 or np.abs(hi + lo).max() / 2 > 1e-6:
        found.append("not normalised after float32 rounding")
    if found:
        raise RuntimeError(f"{name}: {', '.join(found)}")


def manifest_entry(spec, path):
    """Manifest record for an object whose PLY file exists at ``path``."""
    data = Path(path).read_bytes()
    mesh = trimesh.load(path, force="mesh")
    return {
        "name": spec.name,
        "set": spec.set,
        "variant_of": spec.variant_of,
        "file": Path(path).name,
        "faces": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "sha256": hashlib.sha256(data).hexdigest(),
    }


def build(out=DEFAULT_OUT, only=None, log=print):
    """Generate PLY files and ``manifest.json``.

    Parameters
    ----------
    out : str or Path
        Output folder (created if missing).
    only : list of str, optional
        Names to regenerate; others already in ``out`` are kept.
    log : callable or None

    Returns
    -------
    dict
        The manifest that was written. It lists every catalogue object whose
        PLY file exists in ``out``, in catalogue order.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    specs = CATALOG if not only else [by_name(n) for n in only]
    for spec in specs:
        t0 = time.perf_counter()
        mesh = build_mesh(spec)
        data = ply_bytes(mesh)
        check_ply(spec.name, data)
        write_atomic(out / f"{spec.name}.ply", data)
        if log:
            log(f"{spec.name:14s} {len(mesh.faces):6d} faces  {time.perf_counter() - t0:5.1f} s")
    entries = [manifest_entry(s, out / f"{s.name}.ply") for s in CATALOG
               if (out / f"{s.name}.ply").exists()]
    manifest = {"generator": GENERATOR, "units": "longest side 6", "objects": entries}
    write_atomic(out / "manifest.json", (json.dumps(manifest, indent=1) + "\n").encode())
    return manifest


def main(argv=None):
    """Command-line entry point."""
    parser = ArgumentParser(prog=GENERATOR, description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(DEFAULT_OUT), type=output_dir, help="output folder")
    parser.add_argument("--only", action=ExtendList, metavar="NAME",
                        choices=[s.name for s in CATALOG],
                        help="objects to regenerate (default: all; repeats add up)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    build(args.out, args.only)
    print(f"done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0
