"""The contact simulator: a point sensor moving against a ground-truth object.

As in the paper's experiment setup, the sensor moves along a path in small steps (1/300 of
the object's longest side); a contact is detected when the ground-truth signed distance
crosses zero and located by bisection to within the zero-level tolerance; it reports the
position and the true outward normal. A start inside the object follows the gradient of
the exact signed distance out to the surface, which ends at the closest surface point.

With a :class:`~..scene.Scene` the sensor is a robot's: the path is the centre of a sphere
of the tip's radius, which touches where the object's distance falls to that radius or the
tip reaches the table (reported as a contact on the plane, normal up, without the
object's contact noise); a contact reports the touched surface point; a path below the
table or outside the reach cone is an error.
"""

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from ..errors import ParameterError
from ..scene import FREE
from ..shape.meshes import bare_mesh
from ..shape.sdf import normalise_rows
from ..transforms import inverse_transform_points, transform_points
from .observations import Contact, NonContact

# A sample's distance d lets the next d / step samples be skipped; this much of d, against
# rounding (a sample within d of one at d could touch).
_LIPSCHITZ_SLACK = 1.0 - 1e-9


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """An object model placed in the world.

    Attributes
    ----------
    model : ObjectModel
    rotation : (3, 3) float
        ``object_to_world`` rotation.
    translation : (3,) float
        ``object_to_world`` translation.
    """

    model: object
    rotation: np.ndarray
    translation: np.ndarray

    def signed_distance(self, points):
        """Exact signed distance at (k, 3) world points: (k,) float."""
        return self.model.exact.signed_distance(self.to_object(points))

    def closest(self, points):
        """Signed distance, closest surface point and outward normal, all world frame.

        Returns
        -------
        distance : (k,) float
        closest : (k, 3) float
        normal : (k, 3) float
        """
        distance, closest, face = self.model.exact.query(self.to_object(points))
        normal = self.model.exact.surface_normal(closest, face)
        return distance, self.to_world(closest), normal @ self.rotation.T

    def to_object(self, points):
        return inverse_transform_points(np.atleast_2d(points), self.rotation, self.translation)

    def to_world(self, points):
        return transform_points(np.atleast_2d(points), self.rotation, self.translation)

    def surface_points(self, count, rng=None):
        """Area-uniform points on the surface, world frame: (count, 3)."""
        # A bare copy: the sampling's triangles and areas stay off the library's mesh.
        points, _ = trimesh.sample.sample_surface(bare_mesh(self.model.mesh), count,
                                                  seed=np.random.default_rng(rng))
        return self.to_world(points)


class ContactSimulator:
    """Moves a point sensor along paths and reports what it touches.

    Parameters
    ----------
    truth : GroundTruth
    step : float, optional
        Step length, scene units; defaults to 1/300 of the object's longest side.
    tolerance : float, optional
        A reported contact lies within this distance of the true surface, scene units;
        defaults to 1/600 of the object's longest side (the paper's 0.01 on 6 units).
    position_noise : float
        Standard deviation of Gaussian noise added to reported positions, scene units.
    normal_noise_deg : float
        Standard deviation, in degrees, of the angle by which reported normals are tilted.
    outlier_fraction : float
        The chance that a recorded contact is a wrong reading (:meth:`finish_step`): moved
        ``outlier_distance`` in a random direction, with a random normal.
    outlier_distance : float, optional
        Scene units; default a third of the object's longest side (3 cm on a 10 cm object).
    rng : int, numpy.random.Generator or None
        Seeds the noise.
    scene : Scene, optional
        The table, the reach cone and the tip's radius (default: the paper's free space).
    """

    def __init__(self, truth, step=None, tolerance=None, position_noise=0.0,
                 normal_noise_deg=0.0, rng=None, outlier_fraction=0.0, outlier_distance=None,
                 scene=FREE):
        for name, value in (("step", step), ("tolerance", tolerance)):
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
        for name, value in (("position_noise", position_noise),
                            ("normal_noise_deg", normal_noise_deg)):
            if not (np.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a finite number >= 0, got {value!r}")
        self.truth = truth
        self.step = float(step) if step is not None else truth.model.length / 300
        self.tolerance = float(tolerance) if tolerance is not None else truth.model.length / 600
        self.position_noise = float(position_noise)
        self.normal_noise_deg = float(normal_noise_deg)
        if not 0 <= outlier_fraction < 1:
            raise ParameterError(f"outlier_fraction must lie in [0, 1), got {outlier_fraction!r}")
        self.outlier_fraction = float(outlier_fraction)
        self.outlier_distance = (float(outlier_distance) if outlier_distance is not None
                                 else truth.model.length / 3)
        self.rng = np.random.default_rng(rng)
        self.scene = FREE if scene is None else scene

    def probe(self, path):
        """Move along a polyline until the first contact or its end.

        Parameters
        ----------
        path : (k, 3) float, world frame
            Waypoints; ``k >= 1`` (a single point only checks whether it is inside).

        Returns
        -------
        Contact or NonContact
            A non-contact is reported at the end of the path.

        Raises
        ------
        ParameterError
            With a scene, for a path below the table or outside the reach cone.
        """
        if not self.scene.is_free:
            return self._probe_in_scene(path)
        samples = sample_path(path, self.step)
        hit, before = self._first_inside(samples)
        if hit == 0:
            _, closest, normal = self.truth.closest(samples[:1])
            return self._contact(closest[0], normal[0])
        if hit is None:
            return NonContact(self._noisy_position(samples[-1]))
        position = self._bisect(samples[hit - 1], samples[hit], before)
        _, _, normal = self.truth.closest(position[None])
        return self._contact(position, normal[0])

    def _probe_in_scene(self, path):
        """:meth:`probe` of a tip of the scene's radius over its table."""
        scene = self.scene
        scene.check_path(path, self.tolerance)
        samples = sample_path(path, self.step)
        hit, before = self._first_inside(samples, self._gap)
        if hit is None:
            return NonContact(self._noisy_position(samples[-1]))
        if hit == 0:
            centre = samples[0]
        else:
            centre = self._bisect(samples[hit - 1], samples[hit], before, self._gap)
        distance, closest, normal = self.truth.closest(centre[None])
        table = scene.height(centre[None])[0] if scene.has_table else np.inf
        if table < distance[0]:  # the tip met the table first: a known, rigid plane, so
            # the arm's own kinematics place it; the contact noise is the object's
            return Contact(centre - table * scene.up, scene.up.copy())
        # The closest surface point: where the sphere touches (from a start inside the
        # object too, as without a scene).
        return self._contact(closest[0], normal[0])

    def _gap(self, points):
        """How far the tip's sphere at ``points`` is from touching the object or the table
        (<= 0: touching), scene units."""
        scene = self.scene
        gap = self.truth.signed_distance(points) - scene.tip_radius
        if scene.has_table:
            gap = np.minimum(gap, scene.height(points) - scene.tip_radius)
        return gap

    def _first_inside(self, samples, field=None):
        """The index of the first sample on or inside the surface (``None`` if none) and
        the signed distance of the one before it. The path's samples are evaluated in
        batches, from 32, that double near the object: a probe mostly stops early, and a
        sample's distance does not depend on its batch. Samples are at most ``step`` apart
        and the field is 1-Lipschitz (a distance, less the tip's radius, or the height over
        the table), so the ``ceil(d / step) - 1`` samples after one at ``d > 0`` lie
        outside and are skipped: a line far from a small object (a 2 unit sphere in an
        80 unit workspace) asked 60,000 samples of its distance."""
        field = self.truth.signed_distance if field is None else field
        start, size, last = 0, 32, None  # last: the index and value of the last sample asked
        while start < len(samples):
            distance = field(samples[start:start + size])
            if start == 0 and distance[0] < 0:
                return 0, None
            crossing = np.flatnonzero(distance <= 0)
            if len(crossing):
                hit = start + crossing[0]
                if crossing[0]:
                    return hit, distance[crossing[0] - 1]
                if last is None:  # the path starts on the surface
                    return hit, None
                if last[0] == hit - 1:
                    return hit, last[1]
                return hit, field(samples[hit - 1:hit])[0]
            last = start + len(distance) - 1, distance[-1]
            skip = max(1, int(np.ceil(_LIPSCHITZ_SLACK * distance[-1] / self.step)))
            start, size = last[0] + skip, (32 if skip > size else 2 * size)
        return None, None

    def _bisect(self, outside, inside, outside_distance, field=None):
        """A point within ``tolerance`` of the surface between an outside and an inside point."""
        field = self.truth.signed_distance if field is None else field
        if outside_distance <= self.tolerance:
            return outside
        for _ in range(64):
            middle = (outside + inside) / 2
            value = field(middle[None])[0]
            if abs(value) <= self.tolerance:
                return middle
            if value > 0:
                outside = middle
            else:
                inside = middle
        return outside

    def _contact(self, position, normal):
        return Contact(self._noisy_position(position), self._noisy_normal(normal))

    def finish_step(self, observations):
        """The observations a step records, each contact replaced by a wrong reading with
        probability ``outlier_fraction`` (the moves that led to them are not: a wrong
        reading is what the sensor reports, not where it went). A session calls it once a
        step's guarded moves are done (the optional part of its sensor contract)."""
        if not self.outlier_fraction:
            return observations
        out = []
        for observation in observations:
            if isinstance(observation, Contact) and self.rng.random() < self.outlier_fraction:
                away = normalise_rows(self.rng.normal(size=(2, 3)))
                observation = Contact(observation.position + self.outlier_distance * away[0],
                                      away[1])
            out.append(observation)
        return out

    def _noisy_position(self, position):
        if self.position_noise == 0:
            return position
        return position + self.rng.normal(0.0, self.position_noise, size=3)

    def _noisy_normal(self, normal):
        if self.normal_noise_deg == 0:
            return normal
        return tilt(normal, np.radians(self.normal_noise_deg), self.rng)


def sample_path(path, step):
    """Points along a polyline at most ``step`` apart, including every waypoint.

    Parameters
    ----------
    path : (k, 3) float
    step : float

    Returns
    -------
    (m, 3) float
    """
    path = np.atleast_2d(np.asarray(path, dtype=float))
    if path.ndim != 2 or path.shape[1] != 3 or len(path) == 0:
        raise ParameterError(f"a path must have shape (k, 3) with k >= 1, got {path.shape}")
    if not np.isfinite(path).all():
        raise ParameterError("a path must have finite coordinates")
    pieces = [path[:1]]
    for start, end in zip(path[:-1], path[1:]):
        count = max(1, int(np.ceil(np.linalg.norm(end - start) / step)))
        fractions = np.arange(1, count + 1)[:, None] / count
        pieces.append(start + fractions * (end - start))
    return np.vstack(pieces)


def tilt(normal, sigma, rng):
    """Tilt a unit vector by a Gaussian angle (std ``sigma`` radians) about a random axis."""
    normal = np.asarray(normal, dtype=float)
    axis = np.cross(normal, rng.normal(size=3))
    axis = normalise_rows(axis[None], fallback=_any_perpendicular(normal))[0]
    angle = rng.normal(0.0, sigma)
    return Rotation.from_rotvec(angle * axis).apply(normal)


def _any_perpendicular(vector):
    helper = np.eye(3)[int(np.argmin(np.abs(vector)))]
    return np.cross(vector, helper)


def random_touch(truth, rng=None, approach=1.0):
    """A straight path that touches a random surface point from outside along its normal.

    Parameters
    ----------
    truth : GroundTruth
    rng : int, numpy.random.Generator or None
    approach : float
        How far outside the path starts (and inside it ends).

    Returns
    -------
    (2, 3) float, world frame
    """
    point = truth.surface_points(1, rng)[0]
    _, _, normal = truth.closest(point[None])
    return np.stack([point + approach * normal[0], point - approach * normal[0]])


def segment_points(segments, spacing):
    """Points along each segment, at most ``spacing`` apart, ends included.

    Parameters
    ----------
    segments : (k, 2, 3) float
    spacing : float, > 0

    Returns
    -------
    (m, 3) float
    """
    if len(segments) == 0:
        return np.zeros((0, 3))
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    counts = np.maximum(np.ceil(lengths / spacing).astype(int), 1) + 1
    fractions = np.concatenate([np.linspace(0.0, 1.0, c) for c in counts])
    starts = np.repeat(segments[:, 0], counts, axis=0)
    ends = np.repeat(segments[:, 1], counts, axis=0)
    return starts + fractions[:, None] * (ends - starts)
