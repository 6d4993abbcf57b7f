"""Objects made to be hard to tell apart, for ``bench decide``: pairs that differ in one small
part, same-size balls that differ in surface detail, a copy a few percent larger, thin long
objects (a knife, a pencil, a fork, a spatula), a thin-walled cup and its nested copy, and
two symmetric blocks, 2 cm to 33 cm.

Each is a distance function of :mod:`tactile_viz.assetgen.sdf`, meshed like the bundled
objects (:func:`~tactile_viz.assetgen.build.build_mesh`, longest side 6) and then scaled to
its real size in metres (:data:`HARD_SIZES_M`). Nothing is downloaded: the meshes are made
here, once per folder, and cached as PLY files.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..engine.io.files import write_atomic
from . import sdf as s
from .build import build_mesh, ply_bytes
from .catalog import ObjectSpec, by_name

HANDLE_TOP = 2.6  # design units (z up, longest side about 6)


def _screwdriver(tip):
    def sdf(p):
        handle = s.capped_cylinder(p, (0, 0, 0.0), (0, 0, HANDLE_TOP), 0.45)
        shaft = s.capped_cylinder(p, (0, 0, HANDLE_TOP), (0, 0, 5.6), 0.14)
        return s.smooth_union(s.union(handle, shaft), tip(p), 0.04)
    return sdf


def _flat_tip(p):
    return s.round_box(p, (0, 0, 5.75), (0.32, 0.08, 0.25), 0.02)


def _cross_tip(p):
    return s.union(s.round_box(p, (0, 0, 5.75), (0.24, 0.08, 0.25), 0.02),
                   s.round_box(p, (0, 0, 5.75), (0.08, 0.24, 0.25), 0.02))


def _ball(bumpy):
    def sdf(p):
        d = s.sphere(p, (0, 0, 3.0), 3.0)
        return d + s.bumps(p, 0.06, 0.9, seed=5) if bumpy else d
    return sdf


def _knife(p):
    blade = s.round_box(p, (0, 0, 3.9), (0.35, 0.05, 2.0), 0.03)
    handle = s.round_box(p, (0, 0, 0.95), (0.28, 0.16, 0.95), 0.1)
    return s.union(blade, handle)


def _pencil(p):
    hexagon = [(0.22 * np.cos(a), 0.22 * np.sin(a)) for a in np.radians(np.arange(0, 360, 60))]
    body = s.extrude(s.polygon2d(p[:, :2], np.array(hexagon)), p[:, 2] - 2.6, 2.6)
    tip = s.round_cone(p, (0, 0, 5.2), (0, 0, 6.0), 0.2, 0.02)
    return s.union(body, tip)


def _cup(p):
    outer = s.capped_cylinder(p, (0, 0, 0.0), (0, 0, 6.0), 2.6)
    inner = s.capped_cylinder(p, (0, 0, 0.2), (0, 0, 7.0), 2.45)
    return s.subtract(outer, inner)


def _fork(p):
    handle = s.round_box(p, (0, 0, 1.6), (0.18, 0.05, 1.6), 0.03)
    palm = s.round_box(p, (0, 0, 3.45), (0.34, 0.035, 0.3), 0.02)
    tines = [s.round_box(p, (x, 0, 4.8), (0.055, 0.035, 1.1), 0.02)
             for x in (-0.27, -0.09, 0.09, 0.27)]
    return s.union(handle, palm, *tines)


def _spatula(p):
    handle = s.round_box(p, (0, 0, 1.5), (0.2, 0.12, 1.5), 0.05)
    blade = s.round_box(p, (0, 0, 4.5), (0.8, 0.03, 1.5), 0.02)
    return s.union(handle, blade)


def _block(p):
    return s.round_box(p, (0, 0, 1.5), (1.5, 1.5, 1.5), 0.08)


def _plank(p):
    return s.round_box(p, (0, 0, 0.5), (3.0, 1.5, 0.5), 0.05)


WIDE = (-4.5, -4.5, -1.5), (4.5, 4.5, 7.5)
HARD_SPECS = (
    ObjectSpec("screwdriver_flat", "known", None, _screwdriver(_flat_tip), WIDE),
    ObjectSpec("screwdriver_cross", "known", None, _screwdriver(_cross_tip), WIDE),
    ObjectSpec("ball_smooth", "known", None, _ball(False), WIDE),
    ObjectSpec("ball_bumpy", "known", None, _ball(True), WIDE),
    ObjectSpec("knife", "known", None, _knife, WIDE),
    ObjectSpec("pencil", "known", None, _pencil, WIDE),
    ObjectSpec("cup", "known", None, _cup, WIDE),
    ObjectSpec("fork", "known", None, _fork, WIDE),
    ObjectSpec("spatula", "known", None, _spatula, WIDE),
    ObjectSpec("block", "known", None, _block, WIDE),
    ObjectSpec("plank", "known", None, _plank, WIDE),
)

# Longest sides in metres, 2 cm (a die-sized block) to 33 cm. mug_1_large is the bundled
# mug_1 4% larger than its 10 cm copy in the known set (a scaled twin); cup_nested the cup 6%
# smaller, as nested cups are. The
# fork's tines (2.3 mm) are thinner than two voxels of a 64-voxel grid.
HARD_SIZES_M = {
    "screwdriver_flat": 0.20, "screwdriver_cross": 0.20, "ball_smooth": 0.10,
    "ball_bumpy": 0.10, "knife": 0.25, "pencil": 0.18, "cup": 0.08, "block": 0.02,
    "plank": 0.33, "mug_1_large": 0.104, "fork": 0.20, "spatula": 0.30, "cup_nested": 0.075,
}
# Which pairs are twins (for the table): each name's hard counterpart, if any.
COUNTERPARTS = {"screwdriver_flat": "screwdriver_cross", "screwdriver_cross": "screwdriver_flat",
                "ball_smooth": "ball_bumpy", "ball_bumpy": "ball_smooth",
                "mug_1_large": "mug_1", "mug_1": "mug_1_large",
                "cup": "cup_nested", "cup_nested": "cup"}


def hard_meshes(folder):
    """Write the hard objects as PLY files (longest side 1, to be scaled to
    :data:`HARD_SIZES_M`) into ``folder`` once; returns ``{name: path}``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {}
    copies = (replace(by_name("mug_1"), name="mug_1_large"),
              ObjectSpec("cup_nested", "known", None, _cup, WIDE))
    for spec in HARD_SPECS + copies:
        path = folder / f"{spec.name}.ply"
        if not path.exists():
            mesh = build_mesh(spec)
            write_atomic(path, ply_bytes(mesh))
        paths[spec.name] = path
    return paths
