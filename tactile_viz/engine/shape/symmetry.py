"""Rotational symmetries of a shape, found from the shape itself.

A rotation ``S`` about the centre ``c`` (the surface's area centroid, fixed by every symmetry)
is a symmetry when ``x -> S (x - c) + c`` maps the surface onto itself: surface samples moved
by it lie within ``SYMMETRY_TOLERANCE`` of the longest side of the surface (mean and 90th
percentile of their exact distances to the mesh).

Candidate turns come from the shape: with three distinct second moments of the surface only
half turns about the principal axes can be symmetries; when two or three are (near) equal the
axes are also taken from the shape (directions to the corners of its convex hull and their
pairwise sums and cross products), each tried with every fold up to ``MAX_FOLD``. A continuous
axis is the direction of least "slippage" (surface normals perpendicular to the turning
motion) when turns about it by odd angles are symmetric. The group the accepted turns
generate is closed and each element of the closure checked.
"""

from dataclasses import dataclass

import igl
import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from .meshes import bare_mesh

SYMMETRY_TOLERANCE = 0.02  # of the longest side: a turn moving the surface this close is a symmetry
MAX_FOLD = 12
EQUAL_MOMENTS = 0.05  # second moments this close (relative to the largest) count as equal
_ODD_TURNS = 2 * np.pi * np.array([0.1093, 0.2871, 0.4393])  # no n-fold turn for small n
_SAME_ELEMENT_DEG = 15.0  # distinct elements of a group with folds <= 12 are >= 30 degrees apart
_MAX_ORDER = 60  # the icosahedral group's
_MAX_FEATURES = 24
_MAX_MISSES = 12
_SCREENS, _TEST_COUNT = (12, 48), 600  # samples of the quick screens, of the full test


@dataclass(frozen=True)
class SymmetryGroup:
    """The rotational symmetries of a shape, object frame.

    Attributes
    ----------
    rotations : (k, 3, 3) float
        The discrete group, the identity first: turns about ``centre``. With a continuous
        axis, its discrete part (a cylinder's flip of the axis).
    axis : (3,) float or None
        Unit direction of a continuous symmetry axis through ``centre``.
    is_sphere : bool
        Every rotation about ``centre`` is a symmetry.
    centre : (3,) float, object frame
        The point every symmetry keeps (the surface's area centroid).
    roughness : float, object units
        RMS distance to the surface of surface samples turned about a continuous axis or
        the sphere's centre (0 without one): the detail, below the tolerance, that alone
        fixes the pose about it (a bumpy ball's bumps), which a local fit may not find.
    """

    rotations: np.ndarray
    axis: np.ndarray | None
    is_sphere: bool
    centre: np.ndarray
    roughness: float = 0.0

    def __iter__(self):
        """``rotations, axis, is_sphere, centre = group`` unpacks it."""
        return iter((self.rotations, self.axis, self.is_sphere, self.centre))

    @property
    def name(self):
        """Schoenflies-like name: C1, C4, D2, D6, T, O, I, C∞ (cone), D∞ (cylinder), SO(3)."""
        if self.is_sphere:
            return "SO(3)"
        if self.axis is not None:
            return "C∞" if len(self.rotations) == 1 else "D∞"
        return group_name(self.rotations)


def rotation(axis, angle):
    """(3, 3) turn by ``angle`` radians about the unit ``axis``."""
    return Rotation.from_rotvec(angle * np.asarray(axis, float)).as_matrix()


def rotation_angles(matrices):
    """Angles of (..., 3, 3) rotations, radians."""
    matrices = np.asarray(matrices)
    cosine = (np.trace(matrices, axis1=-2, axis2=-1) - 1) / 2
    return np.arccos(np.clip(cosine, -1.0, 1.0))


def group_name(rotations):
    """Name of a finite rotation group given as (k, 3, 3): Cn, Dn, T, O or I."""
    k = len(rotations)
    if k == 1:
        return "C1"
    turns = rotations[1:]
    axes = Rotation.from_matrix(turns).as_rotvec()
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    if np.all(np.abs(axes @ axes[0]) > np.cos(np.radians(_SAME_ELEMENT_DEG))):
        return f"C{k}"
    top = int(round(2 * np.pi / rotation_angles(turns).min()))
    named = {(12, 3): "T", (24, 4): "O", (60, 5): "I"}
    return named.get((k, top), f"D{k // 2}")


def surface_moments(mesh):
    """Area centroid and second moment of a surface, exactly from its triangles.

    Returns
    -------
    centre : (3,) float
    moment : (3, 3) float
        ``mean (x - c)(x - c)^T`` over the surface, squared units.
    """
    triangles = mesh.triangles
    areas = mesh.area_faces
    total = areas.sum()
    centre = (areas @ triangles.mean(axis=1)) / total
    corners = triangles - centre
    summed = corners.sum(axis=1)
    moment = (np.einsum("f,fvi,fvj->ij", areas, corners, corners)
              + np.einsum("f,fi,fj->ij", areas, summed, summed)) / (12 * total)
    return centre, moment


class _SurfaceTest:
    """Distances of surface samples moved by candidate turns to the mesh (libigl AABB)."""

    def __init__(self, mesh, centre, tolerance, seed):
        self.vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        self.tree = igl.AABB()
        self.tree.init(self.vertices, self.faces)
        points, faces = trimesh.sample.sample_surface(mesh, _TEST_COUNT,
                                                      seed=np.random.default_rng(seed))
        self.centred = points - centre
        self.normals = mesh.face_normals[faces]
        self.centre = centre
        self.tolerance = tolerance

    def distances(self, rotations, count):
        """(k, count) distances to the surface of the first ``count`` samples moved by each
        of the (k, 3, 3) turns about the centre."""
        moved = np.einsum("kij,nj->kni", rotations, self.centred[:count]) + self.centre
        squared = self.tree.squared_distance(self.vertices, self.faces,
                                             np.ascontiguousarray(moved.reshape(-1, 3)))[0]
        return np.sqrt(np.maximum(squared, 0.0)).reshape(len(rotations), count)

    def scores(self, rotations, count=_TEST_COUNT, slack=1.0):
        """(k,) mean distance, relative to the tolerance, of ``count`` samples moved by each
        of the (k, 3, 3) turns; inf where the 90th percentile is beyond ``slack`` times the
        tolerance."""
        rotations = np.asarray(rotations).reshape(-1, 3, 3)
        if len(rotations) == 0:
            return np.zeros(0)
        distance = self.distances(rotations, count) / self.tolerance
        return np.where(np.quantile(distance, 0.9, axis=1) <= slack, distance.mean(axis=1),
                        np.inf)

    def rms(self, rotations):
        """RMS distance of all samples moved by the (k, 3, 3) turns, mesh units."""
        return float(np.sqrt(np.mean(np.square(self.distances(np.asarray(rotations),
                                                                len(self.centred))))))

    def passes(self, rotations):
        """(k,) bool: which turns map the surface onto itself within the tolerance (mean
        distance within half of it, 90th percentile within it)."""
        return self.scores(rotations) <= 0.5

    def screen(self, rotations):
        """The (k, 3, 3) turns that may pass, the likeliest first: quick tests on a few
        samples, lenient enough that a turn :meth:`passes` rejects only few symmetries."""
        for count in _SCREENS:
            score = self.scores(rotations, count, slack=2.0)
            rotations = rotations[score <= 1.0]
            score = score[score <= 1.0]
        return rotations[np.argsort(score, kind="stable")]


def _unit(vectors):
    vectors = np.atleast_2d(vectors)
    norms = np.linalg.norm(vectors, axis=1)
    keep = norms > 1e-9 * max(norms.max(initial=0.0), 1e-300)
    return vectors[keep] / norms[keep, None]


def _distinct_axes(axes, degrees=1.0):
    """Rows of (n, 3) unit ``axes`` with the near-parallel (or antiparallel) later ones dropped."""
    parallel = np.abs(axes @ axes.T) >= np.cos(np.radians(degrees))
    kept = np.zeros(len(axes), bool)
    for i in range(len(axes)):
        kept[i] = not (parallel[i] & kept).any()
    return axes[kept]


def hull_corners(mesh, centre, length):
    """Directions-and-radii features: the convex hull's vertices farthest from the centre
    within 0.15 of the longest side, each near-tied cluster averaged.

    Returns
    -------
    (f, 3) float
        Corner positions relative to ``centre``, farthest first, at most ``_MAX_FEATURES``.
    """
    try:
        points = mesh.convex_hull.vertices - centre
    except Exception:  # a flat or degenerate shape: qhull refuses it
        points = np.asarray(mesh.vertices) - centre
    radius = np.linalg.norm(points, axis=1)
    # The farthest point of each cell of a 0.04-length grid: a fine scan's rounded corner
    # has thousands of hull vertices.
    order = np.argsort(-radius)
    _, first = np.unique(np.floor(points[order] / (0.04 * length)), axis=0, return_index=True)
    points, radius = points[order[first]], radius[order[first]]
    tree = cKDTree(points)
    neighbours = tree.query_ball_point(points, 0.15 * length)
    highest = np.array([radius[group].max() for group in neighbours])
    seeds = np.flatnonzero(radius >= highest - 0.01 * length)
    pairs = cKDTree(points[seeds]).query_pairs(0.05 * length, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(seeds), len(seeds)))
    count, label = connected_components(graph, directed=False)
    corners = np.array([points[seeds[label == i]].mean(axis=0) for i in range(count)])
    order = np.argsort(-np.linalg.norm(corners, axis=1))
    return corners[order][:_MAX_FEATURES]


def _shape_axes(corners):
    """Candidate axes from corners: their directions, pairwise sums and cross products."""
    i, j = np.triu_indices(len(corners), 1)
    candidates = [corners, corners[i] + corners[j], np.cross(corners[i], corners[j])]
    return _unit(np.concatenate(candidates))


def _fold_turns(axes, folds=tuple(range(MAX_FOLD, 1, -1))):
    """(a * f, 3, 3) turns by 2 pi / n about each of (a, 3) axes for each of f folds ``n``."""
    folds = np.asarray(folds)
    rotvecs = (axes[:, None, :] * (2 * np.pi / folds)[None, :, None]).reshape(-1, 3)
    return Rotation.from_rotvec(rotvecs).as_matrix()


def _contains(group, element):
    difference = rotation_angles(np.einsum("kji,jl->kil", group, element))
    return bool(difference.min() < np.radians(_SAME_ELEMENT_DEG))


def closure(generators, limit=_MAX_ORDER):
    """The group (k, 3, 3) that (g, 3, 3) turns generate, the identity first; None when it
    exceeds ``limit`` elements (the turns are not exact symmetries of one finite group)."""
    group = [np.eye(3)]
    frontier = [np.asarray(g) for g in generators]
    while frontier:
        element = frontier.pop()
        if _contains(np.array(group), element):
            continue
        group.append(element)
        if len(group) > limit:
            return None
        frontier += [element @ g for g in generators]
    return np.array(group)


class _GroupBuilder:
    """Accepts candidate turns one by one, keeping the generated group verified."""

    def __init__(self, test):
        self.test = test
        self.generators = []
        self.group = np.eye(3)[None]
        self.misses = 0  # candidates rejected in a row

    def offer(self, turn):
        """Add (3, 3) ``turn`` to the generators if it and the whole group it then generates
        are symmetries."""
        if _contains(self.group, turn):
            return
        group = closure(self.generators + [turn]) if self.test.passes(turn[None])[0] else None
        if group is not None:
            new = np.array([g for g in group if not _contains(self.group, g)])
            if len(self.test.screen(new)) == len(new) and all(
                    self.test.passes(new[i:i + 4]).all() for i in range(0, len(new), 4)):
                self.generators.append(turn)
                self.group, self.misses = group, 0
                return
        self.misses += 1


def _perpendicular(axis):
    other = np.eye(3)[np.argmin(np.abs(axis))]
    return _unit(np.cross(axis, other))[0]


def _continuous_axis(test, candidates):
    """The first candidate axis about which odd turns are symmetric, else None."""
    for axis in candidates:
        if test.passes([rotation(axis, angle) for angle in _ODD_TURNS]).all():
            return axis
    return None


def _slippage_axis(test):
    """The axis about which turning moves the surface least along its normals (unit (3,))."""
    motion = np.cross(test.centred, test.normals)
    return np.linalg.eigh(motion.T @ motion)[1][:, 0]


def find_symmetry_group(vertices, faces, tolerance=SYMMETRY_TOLERANCE, seed=1):
    """The rotational symmetries of a triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    tolerance : float
        Fraction of the longest side of the bounding box within which a turned surface must
        lie on the surface (mean distance within half of it, 90% of the samples within it).
    seed : int
        Seed of the surface samples.

    Returns
    -------
    SymmetryGroup
    """
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    length = float(mesh.extents.max())
    centre, moment = surface_moments(mesh)
    test = _SurfaceTest(mesh, centre, tolerance * length, seed)
    values, vectors = np.linalg.eigh(moment)
    equal = np.abs(np.diff(values)) <= EQUAL_MOMENTS * values[-1]
    turns = Rotation.random(3, random_state=seed).as_matrix()
    if equal.all() and test.passes(turns).all():
        return SymmetryGroup(np.eye(3)[None], None, True, centre, test.rms(turns))
    unique = vectors[:, 2 if equal[0] else 0]  # the distinct moment's axis when two are equal
    continuous = [_slippage_axis(test)] + ([unique] if equal.sum() == 1 else [])
    axis = _continuous_axis(test, continuous)
    builder = _GroupBuilder(test)
    if axis is not None:
        builder.offer(rotation(_perpendicular(axis), np.pi))
        roughness = test.rms([rotation(axis, angle) for angle in _ODD_TURNS])
        return SymmetryGroup(builder.group, axis, False, centre, roughness)
    turns = _candidate_turns(mesh, centre, length, vectors, equal)
    for turn in test.screen(turns):  # the likeliest first
        builder.offer(turn)
        if builder.misses >= _MAX_MISSES:  # a rough scan's near misses: the rest are worse
            break
    return SymmetryGroup(builder.group, None, False, centre)


def _candidate_turns(mesh, centre, length, vectors, equal):
    """(k, 3, 3) turns that may be symmetries, given the principal axes (columns of
    ``vectors``, moments ascending) and which neighbouring moments are ``equal`` (2,)."""
    if not equal.any():  # only half turns about the principal axes can be symmetries
        return _fold_turns(vectors.T, (2,))
    shape_axes = _shape_axes(hull_corners(mesh, centre, length))
    if equal.all():  # no axis stands out: every fold about every axis from the shape
        return _fold_turns(_distinct_axes(np.concatenate([vectors.T, shape_axes])))
    # Turns about the distinct moment's axis, half turns about axes across it.
    unique = vectors[:, 2 if equal[0] else 0]
    across = _unit(np.concatenate([vectors.T, shape_axes - np.outer(shape_axes @ unique, unique)]))
    return np.concatenate([_fold_turns(unique[None]), _fold_turns(_distinct_axes(across), (2,))])


def symmetry_group(model):
    """:func:`find_symmetry_group` of an ``ObjectModel``'s mesh, cached on the model and on
    disk by its content (a decision may weigh many classes, each once)."""
    if "_symmetry_group" not in model.__dict__:
        arrays = model.cache.get_or_build("symmetry1", model.content_hash,
                                          {"tolerance": SYMMETRY_TOLERANCE},
                                          lambda: _group_arrays(model))
        axis = arrays["axis"]
        model.__dict__["_symmetry_group"] = SymmetryGroup(
            arrays["rotations"], None if np.isnan(axis).any() else axis,
            bool(arrays["is_sphere"]), arrays["centre"], float(arrays["roughness"]))
    return model.__dict__["_symmetry_group"]


def _group_arrays(model):
    mesh = bare_mesh(model.mesh)
    group = find_symmetry_group(mesh.vertices, mesh.faces)
    return {"rotations": group.rotations,
            "axis": np.full(3, np.nan) if group.axis is None else group.axis,
            "is_sphere": np.array(group.is_sphere), "centre": group.centre,
            "roughness": np.array(group.roughness)}
