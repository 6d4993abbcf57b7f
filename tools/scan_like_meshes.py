"""Write scan-like test meshes: some 16,000 faces each, in metres, some 5-25 cm long.

Run from the repository's root::

    python tools/scan_like_meshes.py OUT 78            # 78 PLY files in OUT
    python tools/scan_like_meshes.py OUT 78 --seed 1   # another draw

Four in turn, as a scanned object set mixes solid and thin-walled objects: two bumpy blobs
(a UV sphere's 15,872 faces pushed in and out by random waves, stretched, with 0.1 mm of
scanner noise), a cup (a revolved profile, 15,552 faces, 2-4 mm walls) and a thin cup
(walls of 0.8-1.2 mm, which refine its SDF grid to 128 voxels). Nothing is downloaded; the
files are what ``python -m tactile_viz library build DIR OUT/*.ply --mesh-units m`` reads
(docs/journal/benchmarks.md, "A cold start", times a cold build of them).
"""

import argparse
from pathlib import Path

import numpy as np
import trimesh


def blob(rng):
    """A bumpy, stretched ball some 5-25 cm long."""
    sphere = trimesh.creation.uv_sphere(radius=1.0, count=[64, 64])
    directions = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    radius = np.ones(len(directions))
    for _ in range(6):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        radius += rng.uniform(0.05, 0.25) * np.cos(rng.uniform(1, 5) * (directions @ axis)
                                                   + rng.uniform(0, 6))
    radius += 0.002 * rng.normal(size=len(directions))  # scanner noise (0.1 mm)
    vertices = directions * radius[:, None] * rng.uniform(0.5, 1.5, size=3) * 0.05
    return trimesh.Trimesh(vertices, sphere.faces, process=False)


def cup(rng, wall=(0.002, 0.004)):
    """A cup 8-12 cm tall with walls of ``wall`` metres: a revolved closed profile."""
    height, radius = rng.uniform(0.08, 0.12), rng.uniform(0.03, 0.05)
    thickness = rng.uniform(*wall)
    z = np.linspace(thickness, height, 40)
    outer = np.column_stack([radius * (1 + 0.1 * np.sin(z / height * 3)), z])
    inner = np.column_stack([outer[::-1, 0] - thickness, z[::-1]])
    profile = np.vstack([[0, 0], [radius, 0], outer, inner, [0, thickness]])
    mesh = trimesh.creation.revolve(profile, sections=96)
    vertices = mesh.vertices + 0.0003 * rng.normal(size=mesh.vertices.shape)
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


def thin_cup(rng):
    return cup(rng, (0.0008, 0.0012))


KINDS = (blob, blob, cup, thin_cup)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="folder to write scan000.ply, scan001.ply, ... to")
    parser.add_argument("count", type=int, help="how many meshes")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for index in range(args.count):
        rng = np.random.default_rng([args.seed, index])
        mesh = KINDS[index % len(KINDS)](rng)
        mesh.export(out / f"scan{index:03d}.ply")
    print(f"wrote {args.count} meshes to {out}")


if __name__ == "__main__":
    main()
