"""The robot's world around the object: a support plane, the reach of the arm, the size of
the fingertip.

A :class:`Scene` is known geometry, not evidence about the object. Without a table and with
a reach of 180 degrees and a point tip it is the paper's free space (:data:`FREE`), and
nothing in a session changes.

Contract at the sensor's boundary (one convention everywhere)
-------------------------------------------------------------
- A planned path is the path of the **tip's centre** (world frame, scene units).
- A :class:`~.explore.observations.Contact` reports the **surface point** the tip touched:
  its centre minus ``tip_radius`` times the outward normal. A robot that measures the tip's
  centre converts once with :meth:`Scene.surface_point`.
- A :class:`~.explore.observations.NonContact` reports where the tip's centre ended.
- With a table, every segment of every planned path travels within ``reach_angle_deg`` of
  straight down (the arm reaches from above) and no waypoint's centre lies below the
  table by more than a rounding error. Between two guarded moves the robot moves freely
  (it lifts the tip and travels above the object); that motion is its own.
- A contact with the table (a point on the plane, the normal up) is recognised here and
  kept out of the object's belief: it ends the move as a miss of the object.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import ParameterError

REACH_TOLERANCE_DEG = 0.01  # rounding slack of the cone test on planned segments
TABLE_NORMAL_COSINE = np.cos(np.radians(30.0))  # a table contact's normal is this near up


def _unit(vector, what):
    vector = np.asarray(vector, dtype=float).reshape(-1)
    if vector.shape != (3,) or not np.isfinite(vector).all():
        raise ParameterError(f"{what} must be 3 finite numbers, got {vector.tolist()}")
    length = float(np.linalg.norm(vector))
    if not length > 1e-12:
        raise ParameterError(f"{what} must not be zero")
    return vector / length


@dataclass(frozen=True, eq=False)
class Scene:
    """What a robot's world adds to the object: a table, a reach cone and a tip radius.

    Attributes
    ----------
    table_point : (3,) float or None, world frame, scene units
        A point of the support plane under the object; None: no table (held in a vise or
        a hand, or the paper's floating object).
    up : (3,) float, world frame
        The plane's upward unit normal; also the axis of the reach cone.
    reach_angle_deg : float, degrees, (0, 180]
        The half-angle of the cone about straight down in which the tip may travel; 180:
        any direction.
    tip_radius : float, scene units, >= 0
        The radius of the spherical fingertip; 0 is the paper's point sensor.
    """

    table_point: np.ndarray | None = None
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    reach_angle_deg: float = 180.0
    tip_radius: float = 0.0

    def __post_init__(self):
        if self.table_point is not None:
            point = np.asarray(self.table_point, dtype=float).reshape(-1)
            if point.shape != (3,) or not np.isfinite(point).all():
                raise ParameterError(f"the table point must be 3 finite numbers, got "
                                     f"{point.tolist()}")
            object.__setattr__(self, "table_point", point)
        object.__setattr__(self, "up", _unit(self.up, "the table's up direction"))
        angle = float(self.reach_angle_deg)
        if not (np.isfinite(angle) and 0 < angle <= 180):
            raise ParameterError(f"the reach angle must lie in (0, 180] degrees, got {angle!r}")
        radius = float(self.tip_radius)
        if not (np.isfinite(radius) and radius >= 0):
            raise ParameterError(f"the tip radius must be a finite number >= 0, got {radius!r}")
        object.__setattr__(self, "reach_angle_deg", angle)
        object.__setattr__(self, "tip_radius", radius)

    @classmethod
    def on_table(cls, height=0.0, reach_angle_deg=180.0, tip_radius=0.0):
        """A horizontal table at ``height`` (scene units) under the origin, z up."""
        return cls(np.array([0.0, 0.0, float(height)]), np.array([0.0, 0.0, 1.0]),
                   reach_angle_deg, tip_radius)

    @property
    def has_table(self):
        return self.table_point is not None

    @property
    def limited_reach(self):
        return self.reach_angle_deg < 180.0

    @property
    def is_free(self):
        """The paper's free space: no table, any direction, a point tip."""
        return not self.has_table and not self.limited_reach and self.tip_radius == 0

    def as_dict(self):
        """The scene as plain numbers (a JSON record, a saved session)."""
        return {"table_point": None if self.table_point is None else self.table_point.tolist(),
                "up": self.up.tolist(), "reach_angle_deg": self.reach_angle_deg,
                "tip_radius": self.tip_radius}

    @classmethod
    def from_dict(cls, record):
        return cls(record.get("table_point"), record.get("up", (0.0, 0.0, 1.0)),
                   record.get("reach_angle_deg", 180.0), record.get("tip_radius", 0.0))

    # ------------------------------------------------------------------ geometry
    def height(self, points):
        """Signed height above the table, (k,) float, scene units (inf without a table)."""
        points = np.atleast_2d(points)
        if self.table_point is None:
            return np.full(len(points), np.inf)
        return (points - self.table_point) @ self.up

    def surface_point(self, centre, normal):
        """The touched surface point of a tip whose centre is ``centre`` ((3,) or (k, 3))
        and outward normal ``normal``: ``centre - tip_radius * normal``."""
        return np.asarray(centre, float) - self.tip_radius * np.asarray(normal, float)

    def centre_of(self, point, normal):
        """The tip's centre touching ``point`` with outward ``normal``."""
        return np.asarray(point, float) + self.tip_radius * np.asarray(normal, float)

    def in_reach(self, directions, slack_deg=REACH_TOLERANCE_DEG):
        """Whether each direction of travel ((k, 3), any length > 0) lies in the cone."""
        directions = np.atleast_2d(directions)
        if not self.limited_reach:
            return np.ones(len(directions), bool)
        lengths = np.linalg.norm(directions, axis=1)
        cosine = -(directions @ self.up) / np.maximum(lengths, 1e-300)
        return cosine >= np.cos(np.radians(min(self.reach_angle_deg + slack_deg, 180.0)))

    def approach(self, normal):
        """The direction of travel for touching a surface whose outward normal is
        ``normal`` ((3,)): ``-normal`` when it lies in the cone, else the cone's direction
        nearest to it (its rim, turned toward ``-normal``)."""
        return self.approaches(np.asarray(normal, dtype=float)[None])[0]

    def approaches(self, normals):
        """:meth:`approach` of each of ``normals`` ((k, 3) unit), (k, 3)."""
        wanted = -np.atleast_2d(np.asarray(normals, dtype=float))
        wanted = wanted / np.maximum(np.linalg.norm(wanted, axis=1, keepdims=True), 1e-300)
        inside = self.in_reach(wanted, slack_deg=0.0)
        if inside.all():
            return wanted
        down = -self.up
        across = wanted - (wanted @ down)[:, None] * down
        length = np.linalg.norm(across, axis=1)
        helper = np.eye(3)[int(np.argmin(np.abs(down)))]
        sideways = np.cross(down, helper)
        across = np.where(length[:, None] < 1e-9, sideways, across)  # straight up: any side
        across /= np.linalg.norm(across, axis=1, keepdims=True)
        angle = np.radians(self.reach_angle_deg)
        rim = np.cos(angle) * down + np.sin(angle) * across
        return np.where(inside[:, None], wanted, rim)

    def random_directions(self, count, rng):
        """``count`` directions of travel drawn uniformly over the cone (over a table, its
        part that goes down), (count, 3)."""
        rng = np.random.default_rng(rng)
        angle = min(self.reach_angle_deg, 90.0) if self.has_table else self.reach_angle_deg
        cos_max = np.cos(np.radians(angle))
        cosine = rng.uniform(cos_max, 1.0, size=count)
        azimuth = rng.uniform(0.0, 2 * np.pi, size=count)
        sine = np.sqrt(np.clip(1.0 - cosine**2, 0.0, None))
        down = -self.up
        helper = np.eye(3)[int(np.argmin(np.abs(down)))]
        first = np.cross(down, helper)
        first /= np.linalg.norm(first)
        second = np.cross(down, first)
        return (cosine[:, None] * down + sine[:, None] * (np.cos(azimuth)[:, None] * first
                                                          + np.sin(azimuth)[:, None] * second))

    def line(self, through, direction, before, after):
        """A straight path of the tip's centre along ``direction`` through ``through``:
        from ``before`` ahead of it to ``after`` past it, ended where the tip meets the
        table. (2, 3) float."""
        direction = np.asarray(direction, float)
        start, end = through - before * direction, through + after * direction
        return self.clip(np.stack([start, end]))

    def clip(self, path):
        """``path`` ((k, 3), centre positions) cut where the tip first meets the table
        (its centre at ``tip_radius`` above it); unchanged without a table. A path that
        starts below that height is raised onto it."""
        path = np.array(path, dtype=float)
        if self.table_point is None:
            return path
        floor = self.tip_radius
        heights = self.height(path) - floor
        if heights[0] < 0:
            path[0] += -heights[0] * self.up
            heights[0] = 0.0
        below = np.flatnonzero(heights < 0)
        if len(below) == 0:
            return path
        k = below[0]
        fraction = heights[k - 1] / (heights[k - 1] - heights[k])
        end = path[k - 1] + fraction * (path[k] - path[k - 1])
        end += max(0.0, floor - float(self.height(end[None])[0])) * self.up
        return np.vstack([path[:k], end[None]])

    def check_path(self, path, tolerance):
        """Raise :class:`~.errors.ParameterError` when a planned path breaks the scene:
        a centre below the table by more than ``tolerance``, or a segment travelling
        outside the reach cone."""
        path = np.atleast_2d(np.asarray(path, dtype=float))
        if self.table_point is not None:
            low = self.height(path) - self.tip_radius
            if low.min() < -tolerance:
                raise ParameterError(
                    f"a planned path passes {-low.min():.3g} below the table (the tip's "
                    "centre must stay at least its radius above the plane)")
        if self.limited_reach and len(path) > 1:
            steps = np.diff(path, axis=0)
            moving = np.linalg.norm(steps, axis=1) > tolerance
            outside = moving & ~self.in_reach(steps)
            if outside.any():
                step = steps[np.flatnonzero(outside)[0]]
                angle = np.degrees(np.arccos(np.clip(-(step @ self.up) / np.linalg.norm(step),
                                                     -1, 1)))
                raise ParameterError(
                    f"a planned path travels {angle:.1f} degrees from straight down, outside "
                    f"the reach cone of {self.reach_angle_deg:g} degrees")

    def is_table_contact(self, position, normal, tolerance):
        """Whether a reported contact (surface point, outward normal) is the table: on the
        plane within ``tolerance`` and its normal within 30 degrees of up."""
        if self.table_point is None:
            return False
        height = float(self.height(np.asarray(position, float)[None])[0])
        return (abs(height) <= tolerance
                and float(np.asarray(normal) @ self.up) >= TABLE_NORMAL_COSINE)

    def reachable(self, vertices, normals, outside=None, margin=0.0, fit=0.7, clear=0.0,
                  samples=6):
        """Mask of the surface points a probe of this scene can touch.

        Parameters
        ----------
        vertices, normals : (v, 3) float, world frame
            Surface points and their outward normals.
        outside : callable, optional
            ``(k, 3) -> (k,)``: the estimate's signed distance (or anything positive
            outside it). A point then counts only where the tip's sphere fits beside it
            (the estimate at the tip's centre at least ``fit`` radii: not in gaps
            narrower than the tip) and, with ``clear > 0``, where the way in along its
            approach (:meth:`approaches`) is free of the estimate for ``clear``.
        margin : float
            Scene units: points where the tip's centre would be lower than
            ``tip_radius + margin`` above the table are not counted (the tip rests on the
            table before it reaches them: the underside, a side lower than the radius).
        clear : float
            Scene units: how far back along the approach the way must be free (0: not
            asked).
        samples : int
            Points of the way in that are tested.

        Returns
        -------
        (v,) bool
        """
        vertices = np.atleast_2d(vertices)
        keep = np.ones(len(vertices), bool)
        if self.table_point is not None:
            # The tip's centre must clear the table by its radius: a face turned up is
            # reachable however low (a knife lying flat), a side only a radius up.
            centre_height = self.height(vertices) + self.tip_radius * (normals @ self.up)
            keep &= centre_height > self.tip_radius + margin
        if self.limited_reach:
            # A tip travelling within the cone touches a face only against its travel.
            limit = np.cos(np.radians(min(90.0 + self.reach_angle_deg - 5.0, 180.0)))
            keep &= normals @ self.up > limit
        if outside is None or not keep.any():
            return keep
        index = np.flatnonzero(keep)
        centres = vertices[index] + self.tip_radius * normals[index]
        if self.tip_radius > 0:
            keep[index] = outside(centres) >= fit * self.tip_radius
            index = index[keep[index]]
            centres = vertices[index] + self.tip_radius * normals[index]
        if clear > 0 and len(index):
            back = np.linspace(clear / samples, clear, samples)
            way = (centres[:, None, :]
                   - back[None, :, None] * self.approaches(normals[index])[:, None, :])
            free = outside(way.reshape(-1, 3)).reshape(len(index), samples)
            keep[index] = free.min(axis=1) > fit * self.tip_radius
        return keep


FREE = Scene()
