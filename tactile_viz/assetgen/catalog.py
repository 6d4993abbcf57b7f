"""The 20 bundled objects as signed-distance functions.

Shapes are designed z-up with a longest side of roughly 6 so that thickness
limits (radius >= 0.12, mug walls >= 0.35 in final units) can be checked by
eye; :mod:`.build` rescales them exactly. Every function maps
``(n, 3) float`` points to ``(n,) float`` distances.
"""

from dataclasses import dataclass
from typing import Callable

import numpy as np

from tactile_viz.assetgen import sdf as s
from tactile_viz.assetgen.sdf import rotation as rot


@dataclass(frozen=True)
class ObjectSpec:
    """One catalogue entry.

    Attributes
    ----------
    name : str
    set : {"known", "novel"}
    variant_of : str or None
        For a novel object, the known object it is a variant of.
    sdf : callable
        ``(n, 3) float -> (n,) float``.
    bounds : tuple of (3,) float
        Box that must strictly contain the shape (used for a coarse search).
    """

    name: str
    set: str
    variant_of: str | None
    sdf: Callable
    bounds: tuple = ((-4.5, -4.5, -1.5), (4.5, 4.5, 7.5))


def chaikin(points, iterations=2):
    """Corner-cutting smoothing of an open polyline, keeping its end points.

    Parameters
    ----------
    points : (m, d) float
    iterations : int

    Returns
    -------
    (k, d) float
    """
    p = np.asarray(points, float)
    for _ in range(iterations):
        a, b = p[:-1], p[1:]
        cut = np.empty((2 * len(a), p.shape[1]))
        cut[0::2] = 0.75 * a + 0.25 * b
        cut[1::2] = 0.25 * a + 0.75 * b
        p = np.vstack([p[:1], cut[1:-1], p[-1:]])
    return p


def tube(p, path, radii, iterations=2):
    """Smoothed chain of round cones through control points (see :func:`chaikin`)."""
    path = np.column_stack([np.asarray(path, float), np.asarray(radii, float)])
    smooth = chaikin(path, iterations)
    return s.polyline_tube(p, smooth[:, :3], smooth[:, 3])


def mirrored(fn, p, *args):
    """Union of ``fn(p, side, *args)`` for ``side`` in (-1, 1); for left/right pairs."""
    return np.minimum(fn(p, -1.0, *args), fn(p, 1.0, *args))


def revolved(p, control, iterations=2, center=(0, 0, 0)):
    """Solid of revolution from a smoothed ``(r, z)`` control polygon."""
    return s.revolve(p, chaikin(control, iterations), center)


# ---------------------------------------------------------------- known


def armadillo(p):
    def ear(p, side):
        return s.ellipsoid(p, (side * 0.5, 0.12, 4.85), (0.16, 0.36, 0.62), rot("y", side * 25))

    def arm(p, side):
        x = side
        return np.minimum.reduce([
            tube(p, [(x * 0.7, 0.05, 3.4), (x * 1.4, 0.3, 2.9), (x * 1.75, 0.65, 3.3)], [0.32, 0.24, 0.19], 1),
            s.ellipsoid(p, (x * 1.85, 0.78, 3.45), (0.24, 0.26, 0.3)),
            *[s.capsule(p, (x * 1.9, 0.85, 3.5), (x * 2.12, 0.95 + dy, 3.75 + dz), 0.12)
              for dy, dz in ((-0.2, 0.1), (0.05, 0.15), (0.25, 0.0))],
        ])

    def leg(p, side):
        x = side
        return s.smooth_union_all([
            s.ellipsoid(p, (x * 0.52, 0.08, 1.6), (0.42, 0.45, 0.55)),
            tube(p, [(x * 0.5, 0.0, 1.9), (x * 0.78, 0.38, 1.05), (x * 0.72, -0.05, 0.35)], [0.36, 0.27, 0.2], 1),
            s.ellipsoid(p, (x * 0.74, 0.2, 0.17), (0.32, 0.52, 0.17)),
        ], 0.12)

    tail = tube(p, [(0, -0.45, 1.9), (0, -1.2, 1.35), (0, -1.75, 0.7), (0, -2.25, 0.38), (0, -2.8, 0.32)],
                [0.32, 0.25, 0.2, 0.16, 0.13])
    body = s.smooth_union_all([
        s.ellipsoid(p, (0, 0, 2.75), (0.85, 0.62, 1.0), rot("x", -10)),
        s.ellipsoid(p, (0, 0.22, 3.05), (0.78, 0.5, 0.65)),
        s.ellipsoid(p, (0, -0.05, 1.95), (0.8, 0.6, 0.55)),
        s.capsule(p, (0, 0.05, 3.6), (0, 0.25, 4.05), 0.32),
        s.ellipsoid(p, (0, 0.3, 4.2), (0.46, 0.5, 0.42)),
        s.ellipsoid(p, (0, 0.76, 4.05), (0.28, 0.36, 0.23)),
    ], 0.25)
    return s.smooth_union_all(
        [body, mirrored(ear, p), mirrored(arm, p), mirrored(leg, p), tail], 0.15
    )


def asian_dragon(p):
    spine = [(-3.0, 0.9, 0.3), (-2.5, 0.5, 0.38), (-2.0, 0.0, 0.7), (-1.5, -0.3, 1.3), (-0.9, -0.2, 1.65),
             (-0.4, 0.2, 1.2), (0.0, 0.5, 0.62), (0.5, 0.5, 0.5), (1.0, 0.2, 0.85), (1.4, -0.1, 1.5),
             (1.6, -0.1, 2.2), (1.85, 0.0, 2.7)]
    radii = [0.13, 0.17, 0.24, 0.3, 0.36, 0.4, 0.42, 0.42, 0.4, 0.36, 0.32, 0.3]
    body = tube(p, spine, radii)
    head = s.smooth_union_all([
        s.ellipsoid(p, (2.15, 0, 2.88), (0.5, 0.36, 0.34), rot("y", 15)),
        s.ellipsoid(p, (2.65, 0, 2.78), (0.45, 0.27, 0.2), rot("y", 10)),
        s.ellipsoid(p, (2.55, 0, 2.5), (0.42, 0.2, 0.13), rot("y", 25)),
    ], 0.1)
    horns = mirrored(lambda p, side: tube(
        p, [(2.0, side * 0.2, 3.1), (1.7, side * 0.35, 3.45), (1.3, side * 0.42, 3.6)], [0.15, 0.14, 0.13], 1), p)
    whiskers = mirrored(lambda p, side: tube(
        p, [(2.85, side * 0.18, 2.75), (3.05, side * 0.45, 2.6), (3.15, side * 0.7, 2.25)], [0.13, 0.13, 0.13], 1), p)
    path = chaikin(np.column_stack([spine, radii]), 2)
    spikes = [s.round_cone(p, path[i, :3], path[i, :3] + (0, 0, path[i, 3] + 0.25), 0.14, 0.13)
              for i in range(8, 36, 3)]
    legs = []
    for hip, foot in [((1.0, 0.2, 0.85), (1.25, -0.45, 0.12)), ((1.0, 0.2, 0.85), (1.1, 0.85, 0.12)),
                      ((-1.5, -0.3, 1.3), (-1.35, -0.95, 0.12)), ((-1.5, -0.3, 1.3), (-1.65, 0.35, 0.12))]:
        knee = (np.add(hip, foot) / 2) + (0.15, 0, 0.2)
        legs.append(tube(p, [hip, knee, foot], [0.2, 0.15, 0.13], 1))
        legs.append(s.ellipsoid(p, np.add(foot, (0.12, 0, 0)), (0.24, 0.16, 0.13)))
    return s.smooth_union_all([body, head, horns, whiskers, *spikes, *legs], 0.1)


def elephant(p):
    legs = [s.smooth_union(
        s.round_cone(p, (x * 1.05, y * 0.55, 2.0), (x * 1.05, y * 0.6, 0.35), 0.46, 0.4),
        s.capped_cylinder(p, (x * 1.05, y * 0.6, 0.0), (x * 1.05, y * 0.6, 0.35), 0.44), 0.1)
        for x in (-1, 1) for y in (-1, 1)]
    trunk = tube(p, [(2.45, 0, 2.75), (2.78, 0, 2.2), (2.88, 0, 1.5), (2.88, 0, 0.9), (3.05, 0, 0.5), (3.32, 0, 0.56)],
                 [0.33, 0.27, 0.22, 0.19, 0.16, 0.14])
    ears = mirrored(lambda p, side: s.ellipsoid(
        p, (1.55, side * 0.85, 2.85), (0.14, 0.72, 0.82), rot("z", side * 25)), p)
    tusks = mirrored(lambda p, side: tube(
        p, [(2.35, side * 0.3, 2.35), (2.75, side * 0.38, 1.95), (3.05, side * 0.35, 1.95)], [0.15, 0.13, 0.12], 1), p)
    tail = np.minimum(s.round_cone(p, (-1.6, 0, 2.65), (-2.0, 0, 1.55), 0.13, 0.12),
                      s.ellipsoid(p, (-2.02, 0, 1.45), (0.16, 0.16, 0.22)))
    body = s.smooth_union_all([
        s.ellipsoid(p, (0, 0, 2.3), (1.7, 1.1, 1.15)),
        s.ellipsoid(p, (1.95, 0, 2.95), (0.7, 0.62, 0.72)),
        s.ellipsoid(p, (1.35, 0, 2.75), (0.6, 0.55, 0.6)),
    ], 0.3)
    return s.smooth_union_all([body, *legs, trunk, ears, tusks, tail], 0.15)


def bottle_1(p):
    profile = [(0, 0), (0.9, 0), (1.0, 0.08), (1.0, 3.0), (0.97, 3.4), (0.72, 3.9), (0.45, 4.3),
               (0.38, 4.6), (0.38, 5.0), (0.5, 5.02), (0.5, 5.62), (0.44, 5.7), (0, 5.7)]
    return revolved(p, profile, 2)


def mug_1(p):
    outer = s.capped_cylinder(p, (0, 0, 0.1), (0, 0, 3.1), 1.4) - 0.1
    cavity = s.capped_cylinder(p, (0, 0, 0.45), (0, 0, 5.0), 1.1)
    handle = s.torus(p, (1.5, 0, 1.6), 0.8, 0.22, rot("x", 90))
    return s.smooth_subtract(s.smooth_union(outer, handle, 0.15), cavity, 0.08)


def ice_cream_1(p):
    cone = revolved(p, [(0, 0), (0.15, 0.12), (1.0, 3.5), (1.12, 3.55), (1.12, 3.85), (0, 3.85)], 1)
    scoop = s.smooth_union(s.sphere(p, (0, 0, 4.5), 1.2),
                           s.torus(p, (0, 0, 3.98), 0.95, 0.25), 0.2)
    scoop = scoop + s.bumps(p, 0.02, 0.7, seed=11)
    return s.smooth_union(cone, scoop, 0.1)


def guitar(p, lower=1.25, upper=0.95, gap=1.55, half_thick=0.4, neck_end=4.6, head_len=0.85):
    """Acoustic guitar lying flat (top face +z), neck along +x, roughly centred."""
    p = p + (2.1, 0.0, 0.0)
    q = p[:, :2]
    outline = s.smooth_union(s.circle2d(q, (0, 0), lower), s.circle2d(q, (gap, 0), upper), 0.45)
    body = s.extrude(outline + 0.08, p[:, 2], half_thick - 0.08) - 0.08
    hole = s.capped_cylinder(p, (gap * 0.62, 0, half_thick - 0.15), (gap * 0.62, 0, 2.0), 0.36)
    bridge = s.round_box(p, (-0.45, 0, half_thick), (0.14, 0.5, 0.09), 0.05)
    neck = s.round_box(p, ((gap + neck_end) / 2, 0, 0.12), ((neck_end - gap) / 2, 0.26, 0.17), 0.08)
    head = s.round_box(p, (neck_end + head_len / 2, 0, 0.12), (head_len / 2, 0.36, 0.15), 0.08, rot("y", -8))
    pegs = [s.capsule(p, (neck_end + t * head_len, -0.5, 0.14), (neck_end + t * head_len, 0.5, 0.14), 0.135)
            for t in (0.25, 0.55, 0.85)]
    return s.smooth_union_all([s.subtract(body, hole), bridge, neck, head, *pegs], 0.06)


def guitar_1(p):
    return guitar(p)


def vase_1(p):
    profile = [(0, 0), (0.8, 0), (0.9, 0.1), (1.3, 0.6), (1.6, 1.5), (1.5, 2.4), (1.0, 3.2), (0.55, 3.7),
               (0.55, 4.0), (0.8, 4.35), (1.05, 4.5), (0.98, 4.6), (0.45, 4.4), (0.3, 3.9), (0, 3.9)]
    return revolved(p, profile, 2)


def office_chair(p):
    parts = [
        s.round_box(p, (0, 0, 2.45), (1.25, 1.2, 0.22), 0.15),
        s.round_box(p, (0, -1.35, 3.95), (1.15, 0.18, 1.0), 0.15, rot("x", 10)),
        tube(p, [(0, -0.7, 2.3), (0, -1.3, 2.35), (0, -1.38, 3.1)], [0.14, 0.14, 0.14], 1),
        s.round_box(p, (0, 0, 2.15), (0.45, 0.45, 0.13), 0.05),
        s.capped_cylinder(p, (0, 0, 0.45), (0, 0, 2.2), 0.16),
        s.capped_cylinder(p, (0, 0, 1.25), (0, 0, 2.2), 0.24),
        s.capped_cylinder(p, (0, 0, 0.35), (0, 0, 0.68), 0.3),
    ]
    for i in range(5):
        t = np.radians(90 + 72 * i)
        c, d = np.array([np.cos(t), np.sin(t)]), np.array([-np.sin(t), np.cos(t)])
        end = (*(1.35 * c), 0.45)
        parts.append(s.round_cone(p, (0, 0, 0.52), end, 0.17, 0.13))
        parts.append(s.capsule(p, end, (*(1.45 * c), 0.2), 0.12))
        frame = np.column_stack([(*d, 0), (*c, 0), (0, 0, 1)])
        parts.append(s.ellipsoid(p, (*(1.45 * c), 0.17), (0.13, 0.17, 0.17), frame))
    for x in (-1, 1):
        parts.append(s.capsule(p, (x * 1.0, -0.1, 2.5), (x * 1.2, -0.1, 3.2), 0.12))
        parts.append(s.round_box(p, (x * 1.2, -0.05, 3.28), (0.17, 0.55, 0.13), 0.08))
    return s.smooth_union_all(parts, 0.06)


def sofa_1(p):
    parts = [
        s.round_box(p, (0, 0.1, 0.65), (2.6, 1.1, 0.35), 0.1),
        s.round_box(p, (0, -0.85, 1.55), (2.6, 0.35, 0.95), 0.2),
        *[s.round_box(p, (x * 2.75, 0.05, 1.2), (0.3, 1.2, 0.58), 0.2) for x in (-1, 1)],
        *[s.round_box(p, (x * 1.2, 0.28, 1.18), (1.18, 0.88, 0.2), 0.15) for x in (-1, 1)],
        *[s.round_box(p, (x * 1.2, -0.38, 1.85), (1.15, 0.2, 0.5), 0.18, rot("x", 8)) for x in (-1, 1)],
        *[s.capped_cylinder(p, (x * 2.7, y * 0.95 + 0.1, 0.0), (x * 2.7, y * 0.95 + 0.1, 0.4), 0.14)
          for x in (-1, 1) for y in (-1, 1)],
    ]
    return s.smooth_union_all(parts, 0.04)


# ---------------------------------------------------------------- novel


def neptune(p):
    def leg(p, side):
        x = side * 0.3
        return s.smooth_union(
            tube(p, [(x, 0, 2.9), (x * 1.15, 0.06, 1.6), (x * 1.15, 0, 0.3)], [0.3, 0.22, 0.17], 1),
            s.ellipsoid(p, (x * 1.15, 0.15, 0.13), (0.17, 0.32, 0.13)), 0.1)

    trident_x, trident_y = 1.35, 0.2
    trident = np.minimum.reduce([
        s.capsule(p, (trident_x, trident_y, 0.25), (trident_x, trident_y, 5.0), 0.12),
        s.capsule(p, (trident_x - 0.45, trident_y, 5.0), (trident_x + 0.45, trident_y, 5.0), 0.12),
        *[s.round_cone(p, (trident_x + dx, trident_y, 5.0), (trident_x + dx, trident_y, 5.75), 0.13, 0.12)
          for dx in (-0.45, 0.0, 0.45)],
    ])
    right_arm = np.minimum(
        tube(p, [(0.6, 0, 4.3), (1.05, 0.1, 3.75), (1.3, trident_y, 4.15)], [0.19, 0.15, 0.13], 1),
        s.ellipsoid(p, (trident_x, trident_y, 4.2), (0.2, 0.19, 0.22)))
    left_arm = np.minimum(
        tube(p, [(-0.6, 0, 4.3), (-0.82, 0.02, 3.5), (-0.88, 0.12, 2.85)], [0.19, 0.15, 0.13], 1),
        s.ellipsoid(p, (-0.9, 0.14, 2.7), (0.15, 0.15, 0.2)))
    body = s.smooth_union_all([
        s.ellipsoid(p, (0, 0, 3.75), (0.6, 0.35, 0.75)),
        s.ellipsoid(p, (0, 0, 3.0), (0.48, 0.32, 0.38)),
        s.capsule(p, (0, 0, 4.4), (0, 0, 4.7), 0.17),
        s.ellipsoid(p, (0, 0, 4.95), (0.3, 0.32, 0.36)),
        s.ellipsoid(p, (0, 0.2, 4.7), (0.24, 0.16, 0.3)),
    ], 0.12)
    return s.smooth_union_all([body, mirrored(leg, p), right_arm, left_arm, trident], 0.08)


def dragon(p):
    def wing(p, side):
        span = np.array([-0.25, side * np.cos(np.radians(35)), np.sin(np.radians(35))])
        span /= np.linalg.norm(span)
        chord = np.array([1.0, 0, 0]) - span[0] * span
        chord /= np.linalg.norm(chord)
        frame = np.column_stack([span, chord, np.cross(span, chord)])
        q = s.to_local(p, (0.3, side * 0.3, 2.0), frame)
        flat = np.column_stack([q[:, :2], np.zeros(len(q))])
        outline = s.subtract(
            s.smooth_union(s.ellipsoid(flat, (1.35, -0.45, 0), (1.35, 0.75, 1)),
                           s.ellipsoid(flat, (0.6, -0.6, 0), (0.7, 0.85, 1)), 0.2),
            np.minimum(s.sphere(flat, (1.05, -1.35, 0), 0.42), s.sphere(flat, (2.0, -1.05, 0), 0.38)))
        membrane = s.extrude(outline + 0.06, q[:, 2], 0.13 - 0.06) - 0.06
        bone = tube(q, [(0, 0.05, 0), (1.3, 0.15, 0.05), (2.75, -0.1, 0)], [0.18, 0.15, 0.13], 1)
        return s.smooth_union(bone, membrane, 0.08)

    def legs(p, side):
        hind = tube(p, [(-0.6, side * 0.4, 1.3), (-0.3, side * 0.55, 0.7), (-0.55, side * 0.55, 0.15)],
                    [0.28, 0.2, 0.16], 1)
        fore = tube(p, [(0.75, side * 0.35, 1.35), (0.95, side * 0.45, 0.7), (0.85, side * 0.45, 0.15)],
                    [0.22, 0.17, 0.14], 1)
        feet = np.minimum(s.ellipsoid(p, (-0.45, side * 0.55, 0.12), (0.28, 0.17, 0.13)),
                          s.ellipsoid(p, (0.95, side * 0.45, 0.12), (0.25, 0.15, 0.13)))
        return np.minimum.reduce([hind, fore, feet])

    body = s.smooth_union_all([
        s.ellipsoid(p, (0, 0, 1.5), (1.1, 0.6, 0.6), rot("y", -10)),
        s.ellipsoid(p, (0.7, 0, 1.65), (0.6, 0.5, 0.55)),
        tube(p, [(0.9, 0, 1.8), (1.35, 0, 2.4), (1.5, 0, 3.0), (1.75, 0, 3.35)], [0.38, 0.3, 0.26, 0.24]),
        s.ellipsoid(p, (1.95, 0, 3.4), (0.46, 0.32, 0.3)),
        s.round_cone(p, (2.05, 0, 3.38), (2.65, 0, 3.22), 0.25, 0.15),
        mirrored(lambda p, side: s.round_cone(p, (1.85, side * 0.15, 3.55), (1.45, side * 0.32, 3.92), 0.14, 0.13), p),
        tube(p, [(-1.0, 0, 1.5), (-1.7, 0, 1.2), (-2.3, 0.3, 0.8), (-2.8, 0.7, 0.55), (-3.1, 1.1, 0.5)],
             [0.4, 0.3, 0.22, 0.16, 0.13]),
        s.ellipsoid(p, (-3.2, 1.3, 0.5), (0.3, 0.3, 0.13), rot("z", 50)),
    ], 0.15)
    return s.smooth_union_all([body, mirrored(wing, p), mirrored(legs, p)], 0.1)


def noisy_dino(p):
    legs = [s.smooth_union(
        s.round_cone(p, (x, y * 0.45, 1.75), (x, y * 0.5, 0.3), 0.32, 0.24),
        s.capped_cylinder(p, (x, y * 0.5, 0.0), (x, y * 0.5, 0.3), 0.27), 0.08)
        for x in (-0.75, 0.75) for y in (-1, 1)]
    body = s.smooth_union_all([
        s.ellipsoid(p, (0, 0, 1.9), (1.3, 0.75, 0.8)),
        s.ellipsoid(p, (-0.6, 0, 2.0), (0.8, 0.7, 0.75)),
        tube(p, [(0.9, 0, 2.1), (1.5, 0, 2.8), (1.9, 0, 3.6), (2.1, 0, 4.2)], [0.5, 0.36, 0.28, 0.23]),
        s.ellipsoid(p, (2.35, 0, 4.3), (0.4, 0.24, 0.24), rot("y", 15)),
        tube(p, [(-1.1, 0, 2.0), (-1.9, 0, 1.7), (-2.6, 0.3, 1.2), (-3.1, 0.8, 0.8), (-3.4, 1.3, 0.6)],
             [0.55, 0.4, 0.3, 0.23, 0.19]),
        *legs,
    ], 0.2)
    return body + s.bumps(p, 0.03, 0.6, seed=7)


def bottle_2(p):
    profile = [(0, 0), (0.78, 0), (0.85, 0.08), (0.85, 3.2), (0.8, 3.55), (0.55, 3.95), (0.34, 4.3),
               (0.3, 4.8), (0.3, 5.55), (0.36, 5.6), (0.36, 5.85), (0.3, 5.9), (0, 5.9)]
    base_dimple = s.sphere(p, (0, 0, -0.35), 0.6)
    return s.subtract(revolved(p, profile, 2), base_dimple)


def mug_2(p):
    outer = s.capped_cylinder(p, (0, 0, 0.1), (0, 0, 3.9), 1.05) - 0.1
    cavity = s.capped_cylinder(p, (0, 0, 0.45), (0, 0, 6.0), 0.77)
    # square-ish loop in the xz-plane, extruded along y
    loop_xz = np.column_stack([p[:, 0] - 1.25, p[:, 2] - 2.1])
    ring = np.abs(s.round_box(np.column_stack([loop_xz, np.zeros(len(p))]), (0, 0, 0), (0.5, 1.0, 1), 0.3)) - 0.18
    handle = s.extrude(ring + 0.06, p[:, 1], 0.26 - 0.06) - 0.06
    return s.smooth_subtract(s.smooth_union(outer, handle, 0.15), cavity, 0.08)


def ice_cream_2(p):
    cone = revolved(p, [(0, 0), (0.15, 0.12), (1.1, 3.3), (1.2, 3.35), (1.2, 3.65), (0, 3.65)], 1)
    scoop = s.smooth_union(s.ellipsoid(p, (0, 0, 4.45), (1.28, 1.28, 1.15)),
                           s.torus(p, (0, 0, 3.8), 1.02, 0.26), 0.2)
    scoop = scoop + s.bumps(p, 0.02, 0.7, seed=12)
    return s.smooth_union(cone, scoop, 0.1)


def guitar_2(p):
    return guitar(p, lower=1.32, upper=0.9, gap=1.62, half_thick=0.44, neck_end=4.45, head_len=0.8)


def vase_2(p):
    profile = [(0, 0), (0.65, 0), (0.72, 0.1), (0.85, 0.8), (0.95, 1.6), (0.8, 2.6), (0.5, 3.8), (0.4, 4.6),
               (0.5, 5.2), (0.7, 5.6), (0.62, 5.68), (0.28, 5.4), (0.2, 4.9), (0, 4.9)]
    return revolved(p, profile, 2)


def home_chair(p):
    def post_y(z):
        return -0.9 - 0.15 * (z - 1.9) / 2.8

    parts = [s.round_box(p, (0, 0, 2.0), (1.1, 1.05, 0.13), 0.05)]
    for x in (-0.95, 0.95):
        parts.append(s.capped_cylinder(p, (x, 0.9, 0.0), (x, 0.9, 1.95), 0.13))
        parts.append(s.capped_cylinder(p, (x, -0.9, 0.0), (x, -0.9, 1.95), 0.13))
        parts.append(s.capped_cylinder(p, (x, -0.9, 1.9), (x * 1.02, post_y(4.75), 4.75), 0.13))
        parts.append(s.capsule(p, (x, -0.9, 0.6), (x, 0.9, 0.6), 0.11))
    parts.append(s.capsule(p, (-0.95, 0.9, 0.75), (0.95, 0.9, 0.75), 0.11))
    for z in (2.75, 3.35, 3.95, 4.55):
        parts.append(s.round_box(p, (0, post_y(z), z), (0.97, 0.11, 0.1 if z < 4.5 else 0.16), 0.05))
    return s.smooth_union_all(parts, 0.04)


def sofa_2(p):
    parts = [
        s.round_box(p, (0, 0.1, 0.78), (2.7, 1.0, 0.28), 0.1),
        s.round_box(p, (0, -0.85, 1.75), (2.55, 0.22, 0.85), 0.15, rot("x", 12)),
        *[s.capped_cylinder(p, (x * 2.75, -0.85, 1.38), (x * 2.75, 1.08, 1.38), 0.35) for x in (-1, 1)],
        *[s.round_box(p, (x * 2.75, 0.1, 0.98), (0.26, 0.98, 0.42), 0.08) for x in (-1, 1)],
        *[s.round_box(p, (x * 1.66, 0.2, 1.2), (0.8, 0.86, 0.17), 0.13) for x in (-1, 0, 1)],
        *[s.round_cone(p, (x * 2.6, y * 0.8 + 0.1, 0.55), (x * 2.68, y * 0.85 + 0.1, 0.0), 0.16, 0.13)
          for x in (-1, 1) for y in (-1, 1)],
    ]
    return s.smooth_union_all(parts, 0.04)


CATALOG = [
    ObjectSpec("armadillo", "known", None, armadillo),
    ObjectSpec("asian_dragon", "known", None, asian_dragon),
    ObjectSpec("elephant", "known", None, elephant),
    ObjectSpec("bottle_1", "known", None, bottle_1),
    ObjectSpec("mug_1", "known", None, mug_1),
    ObjectSpec("ice_cream_1", "known", None, ice_cream_1),
    ObjectSpec("guitar_1", "known", None, guitar_1),
    ObjectSpec("vase_1", "known", None, vase_1),
    ObjectSpec("office_chair", "known", None, office_chair),
    ObjectSpec("sofa_1", "known", None, sofa_1),
    ObjectSpec("neptune", "novel", "armadillo", neptune),
    ObjectSpec("dragon", "novel", "asian_dragon", dragon),
    ObjectSpec("noisy_dino", "novel", "elephant", noisy_dino),
    ObjectSpec("bottle_2", "novel", "bottle_1", bottle_2),
    ObjectSpec("mug_2", "novel", "mug_1", mug_2),
    ObjectSpec("ice_cream_2", "novel", "ice_cream_1", ice_cream_2),
    ObjectSpec("guitar_2", "novel", "guitar_1", guitar_2),
    ObjectSpec("vase_2", "novel", "vase_1", vase_2),
    ObjectSpec("home_chair", "novel", "office_chair", home_chair),
    ObjectSpec("sofa_2", "novel", "sofa_1", sofa_2),
]


# Longest sides in metres: plausible for the objects, within 5 to 40 cm (a novel object
# near its known twin's size, as real variants are). The catalogue's shapes are made at
# the paper's size (6 units); these are what a robot would meet.
SIZES_M = {
    "armadillo": 0.20, "asian_dragon": 0.30, "elephant": 0.15, "bottle_1": 0.25,
    "mug_1": 0.10, "ice_cream_1": 0.18, "guitar_1": 0.40, "vase_1": 0.30,
    "office_chair": 0.12, "sofa_1": 0.35,
    "neptune": 0.24, "dragon": 0.26, "noisy_dino": 0.17, "bottle_2": 0.22, "mug_2": 0.11,
    "ice_cream_2": 0.16, "guitar_2": 0.36, "vase_2": 0.27, "home_chair": 0.13,
    "sofa_2": 0.33,
}


def by_name(name):
    """Catalogue entry with the given name; ``KeyError`` if there is none."""
    for spec in CATALOG:
        if spec.name == name:
            return spec
    raise KeyError(f"unknown object {name!r}; known: {[s_.name for s_ in CATALOG]}")
