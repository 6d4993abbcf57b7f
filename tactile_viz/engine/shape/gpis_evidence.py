"""An object-agnostic GPIS prior mean and the evidence that chooses between prior means
(beyond the paper).

The paper's prior mean is the MAP shape. When the library holds nothing like the object
(a ball against a mug, a 2 cm block against 10 cm priors) that shape keeps what nothing
supports: the mug's cavity inside the ball. An ellipsoid fitted to the contacts is the
classic object-agnostic GPIS prior (Williams and Fitzgibbon 2007 used a sphere), and
superquadrics, from an ellipsoid to a box, are the object-agnostic shapes of grasping
(Vezzani et al. 2017). The GP's marginal likelihood of the contacts tells the priors
apart: with the same kernel, scale and noise, only the term ``-1/2 r^T K^-1 r`` of the
residual ``r = D - mu(X)`` depends on the prior mean ``mu``.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.optimize import nnls

from .metrics import first_per_cell

SHRINK_TOWARD_CENTROID = 0.05  # weight (per contact) pulling the centre to the centroid
MAX_RADIUS_FACTOR = 2.0  # a radius is at most this many times the contacts' extent
TINY = 1e-12
ROUNDNESS = (1.0, 0.5, 0.2)  # an ellipsoid, a rounded and a nearly sharp box
FACE_ITERATIONS = 5  # turns of a box's axes toward its contacts' normals
SAME_PLACE = 0.1  # of min_radius: contacts in one cell this wide are one normal line
# A box's face holds the contacts whose normals lie within this of its axis (degrees): a
# face's own lie along it within the sensor's noise, an edge's or a curved part's wider.
FACE_ANGLE = 20.0


@dataclass(frozen=True, eq=False)
class Superquadric:
    """A superellipsoid as a GPIS prior mean, ``prior(points) -> (values, gradients)``:
    ``F(y) = sum_k |y_k / r_k|^(2 / e) = 1`` in its frame, an ellipsoid at ``e = 1`` and
    a box with rounded edges as ``e`` goes to 0.

    Attributes
    ----------
    centre : (3,) float, world frame
    axes : (3, 3) float
        Columns are its principal directions (a rotation), world frame.
    radii : (3,) float, scene units
        Its semi-axes along ``axes``.
    roundness : float
        The exponent ``e`` in (0, 1].
    """

    centre: np.ndarray
    axes: np.ndarray
    radii: np.ndarray
    roundness: float = 1.0

    @property
    def kind(self):
        """``"ellipsoid"``, ``"rounded box"`` or ``"box"``, by its roundness."""
        if self.roundness >= 1.0:
            return "ellipsoid"
        return "rounded box" if self.roundness >= 0.4 else "box"

    @property
    def corners(self):
        """The eight corners of its bounding box (8, 3), world frame."""
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return self.centre + (signs * self.radii) @ self.axes.T

    def __call__(self, points):
        """Radial distances ``|y| (1 - F^(-e/2))`` (k,) (exact on a sphere, zero on the
        surface, negative inside) and unit outward gradients ``grad F / |grad F|`` (k, 3)
        at ``points`` (k, 3)."""
        local = (np.atleast_2d(np.asarray(points, dtype=float)) - self.centre) @ self.axes
        power = 2.0 / self.roundness
        scaled = np.abs(local) / self.radii
        inside_out = np.sum(scaled**power, axis=1)
        length = np.linalg.norm(local, axis=1)
        values = length * (1.0 - np.maximum(inside_out, TINY) ** (-self.roundness / 2))
        toward = np.sign(local) * scaled ** (power - 1) / self.radii
        size = np.linalg.norm(toward, axis=1)
        centred = size < TINY
        values[centred] = -self.radii.min()
        normals = toward / np.maximum(size, TINY)[:, None]
        normals[centred] = (0.0, 0.0, 1.0)
        return values, normals @ self.axes.T


def fit_superquadrics(points, normals, min_radius, roundness=ROUNDNESS, faces=False):
    """Superquadrics the contacts lie on, one for each ``roundness``, as GPIS prior means.

    The centre is the point nearest every contact's normal line (they meet at a sphere's
    centre), pulled toward the contacts' centroid where the normals leave it open (a flat
    face's all agree); contacts in one cell of ``SAME_PLACE x min_radius`` give one line
    (:func:`one_per_place`); the axes are the contacts' principal directions about it (for a box,
    turned toward the normals, :func:`face_axes`); for each roundness ``e`` the radii solve
    ``sum_k |y_k|^(2/e) / r_k^(2/e) = 1`` at the contacts by non-negative least squares in
    ``r_k^(-2/e)``, each within ``[min_radius, 2 x`` the contacts' extent along its axis
    ``+ min_radius]`` (an axis the contacts do not bound gets that extent); with
    ``faces``, a box's faces are then moved to where their contacts lie if that fits the
    contacts closer (:func:`box_faces`).

    Parameters
    ----------
    points, normals : (n, 3) float, world frame
        Contact positions and outward unit normals.
    min_radius : float, scene units
        The smallest semi-axis (> 0).
    roundness : sequence of float in (0, 1]
    faces : bool
        Place a box's faces by :func:`box_faces` too: for a noisy sensor, whose scatter
        pulls the least squares outward (noiseless, they are not biased).

    Returns
    -------
    list of Superquadric
        Empty with fewer than 4 contacts.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    if len(points) < 4:
        return []
    places = one_per_place(points, normals, SAME_PLACE * min_radius)
    centre = normal_lines_centre(*places)
    offsets = points - centre
    _, axes = np.linalg.eigh(offsets.T @ offsets)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    shapes = []
    for e in roundness:
        frame = axes if e == 1.0 else face_axes(normals, axes)
        local = np.abs(offsets @ frame)
        extent = local.max(axis=0)
        unit = max(float(extent.max()), TINY)  # powers of up to 10 of lengths near 1
        inverse_powers, _ = nnls((local / unit) ** (2.0 / e), np.ones(len(points)))
        radii = unit * np.where(inverse_powers > TINY,
                                np.maximum(inverse_powers, TINY) ** (-e / 2), extent / unit)
        radii = np.clip(radii, min_radius, MAX_RADIUS_FACTOR * extent + min_radius)
        shape = Superquadric(centre, frame, radii, float(e))
        if faces and e < 1.0:
            shape = _closer(shape, box_faces(shape, *places, min_radius,
                                             MAX_RADIUS_FACTOR * extent + min_radius), points)
        shapes.append(shape)
    return shapes


def box_faces(shape, points, normals, min_radius, max_radii):
    """``shape`` (a box's :class:`Superquadric`) with its faces where its contacts on them
    lie: along each axis touched on both faces (contacts whose outward normals lie within
    :data:`FACE_ANGLE` of it, on its side of the centre) the faces are their contacts'
    median offsets, and the radius half their distance (within ``[min_radius,
    max_radii]``). The least squares of the radii's powers are pulled outward by noise
    (a 2 cm block at 2 mm made a box of 2.9 cm, 36% of its size off; its faces' medians
    one of 2.0 cm, 9% off)."""
    local = (points - shape.centre) @ shape.axes
    cosines = normals @ shape.axes
    aligned = np.cos(np.radians(FACE_ANGLE))
    middle, radii = np.zeros(3), shape.radii.copy()
    for k in range(3):
        high = local[(cosines[:, k] > aligned) & (local[:, k] > 0), k]
        low = local[(cosines[:, k] < -aligned) & (local[:, k] < 0), k]
        if len(high) and len(low):
            middle[k] = 0.5 * (np.median(high) + np.median(low))
            radii[k] = 0.5 * (np.median(high) - np.median(low))
    radii = np.clip(radii, min_radius, max_radii)
    return Superquadric(shape.centre + shape.axes @ middle, shape.axes, radii, shape.roundness)


def _closer(first, second, points):
    """Of two superquadrics, the one whose values at the contacts ``points`` have the
    smaller mean square (the first on a tie)."""
    squares = [float(np.mean(shape(points)[0] ** 2)) for shape in (first, second)]
    return second if squares[1] < squares[0] else first


def one_per_place(points, normals, cell):
    """The first of the contacts ``points`` (n, 3) and their ``normals`` in each grid cell of
    size ``cell``: a probe that comes back to one spot (a 20 cm fork's tip, touched again
    at each given-up target) adds no surface, and its normal line, repeated, pulled a
    box's centre 3 cm off the fork's plane (a phantom 15 cm off it for 130 touches)."""
    first = first_per_cell(points, cell)
    return points[first], normals[first]


def normal_lines_centre(points, normals):
    """The point nearest every line through a contact along its normal, pulled toward the
    contacts' centroid by ``SHRINK_TOWARD_CENTROID`` per contact: ``(sum_k (I - n_k n_k^T)
    + w I) c = sum_k (I - n_k n_k^T) p_k + w p_mean``."""
    centroid = points.mean(axis=0)
    across = np.eye(3)[None] - normals[:, :, None] * normals[:, None, :]  # I - n n^T
    pull = SHRINK_TOWARD_CENTROID * len(points)
    matrix = across.sum(axis=0) + pull * np.eye(3)
    return np.linalg.solve(matrix, np.einsum("kij,kj->i", across, points) + pull * centroid)


def face_axes(normals, axes, iterations=FACE_ITERATIONS):
    """``axes`` (3, 3) turned so that the ``normals`` (n, 3) lie along them (a box's faces
    face its axes, which the principal directions of a few contacts miss by degrees): each
    normal is assigned its nearest signed axis, and the rotation taking the axes to the
    normals so assigned is the orthogonal Procrustes solution, a few times over."""
    for _ in range(iterations):
        cosines = normals @ axes
        nearest = np.argmax(np.abs(cosines), axis=1)
        targets = np.zeros_like(normals)
        rows = np.arange(len(normals))
        targets[rows, nearest] = np.sign(cosines[rows, nearest])
        left, _, right = np.linalg.svd(normals.T @ targets)
        turned = left @ np.diag([1.0, 1.0, np.linalg.det(left @ right)]) @ right
        if np.allclose(turned, axes, atol=1e-9):
            break
        axes = turned
    return axes


def contact_evidence(fit, prior, points, normals):
    """The part of the log marginal likelihood of the contacts that depends on the prior
    mean, ``-1/2 r^T K^-1 r`` with ``r`` their [value, gradient] observations less
    ``prior``, at ``fit``'s kernel, scale and noise (nats; comparable between priors for
    one fit only).

    The contacts are the first rows of ``fit`` and all four components of each are
    observed, so the leading block of its Cholesky factor is the factor of theirs.

    Parameters
    ----------
    fit : GPISFit
        Fitted to ``points`` (and maybe non-contacts after them).
    prior : callable
        ``prior(points) -> (values (n,), gradients (n, 3))``.
    points, normals : (n, 3) float, world frame
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    rows = 4 * len(points)
    if rows == 0:
        return 0.0
    values, gradients = prior(points)
    observed = np.column_stack([np.zeros(len(points)), normals])
    residual = (observed - np.column_stack([values, gradients])).ravel()
    whitened = solve_triangular(fit.factor[:rows, :rows], residual, lower=True,
                                check_finite=False)
    return float(-0.5 * whitened @ whitened)
