"""Building an :class:`~.sdf.SDFGrid` from an :class:`~.sdf.ExactDistance`: where its nodes
go, their distances and signs, and how fine a grid a shape's thin parts need.

Building a grid asks the winding number only where the sign can change: on a closed
surface (every edge in both directions) the winding number is the same all over a part
of nodes joined by segments that no surface crosses (:func:`sign_parts`), so one node
(two, as a check) of each part answers for all of it. A cup's grid took half its time
in winding numbers, in its cavity; the signs are those of asking every node (every
bundled object's grid and the tests' are the same bytes). With a band
(:func:`banded_distance`) only the nodes near the surface are asked their distance.
"""

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from .sdf import SDFGrid

# Grid nodes per distance query of a grid build: the query's closest points (24 bytes a
# node) are not kept, so a 2-million-node grid needs some 10 MB for them, not 50.
_GRID_BATCH = 1 << 18
# A banded grid's coarsest level is exact everywhere (16 voxels a side: 5,000 nodes or so).
_COARSEST = 17
_FAR_VOXELS = 1.001  # nodes farther than this from the surface share their region's sign
# A grid is fine enough when at most this share of surface points sees its gradient more
# than 60 degrees off the surface normal (the bundled objects: at most 0.5% at 64 voxels;
# a fork's 2 mm tines on a 20 cm fork: 11%, and 0 at 128).
THIN_MISSES = 0.01
MISS_COSINE = 0.5
# The finest grid a thin part may ask for: about 10 MB (a compact object at 128 voxels).
MAX_REFINED_NODES = 2_100_000
# Voxels from the surface within which a grid refined past an exact grid's resolution is
# exact; beyond, it holds the exact grid's own field (a trilinear field sampled at half its
# spacing and interpolated again is the same field), which every unrefined prior has.
REFINED_BAND = 4.0


def build_sdf_grid(exact, bounds, resolution=64, padding=1.0, band=0.0, exact_resolution=0):
    """Sample a signed distance on a regular grid over a padded box.

    Parameters
    ----------
    exact : ExactDistance
    bounds : (2, 3) float
        The object's axis-aligned bounding box.
    resolution : int
        Number of voxels along the longest side of the padded box.
    padding : float
        Margin added on every side of the box.
    band : float, voxels
        0: the exact distance at every node. Otherwise exact only at the nodes that may
        lie within ``band`` voxels of the surface, the rest interpolated
        (:func:`banded_distance`); the signs are exact either way.
    exact_resolution : int
        With a band, the voxels along the longest side of the coarsest level, which is
        exact at every node (0: 16). A grid refined for thin parts with this its unrefined
        resolution holds, beyond the band, the unrefined exact grid's field.

    Returns
    -------
    SDFGrid
    """
    origin, spacing, counts = grid_layout(bounds, resolution, padding)
    shape = tuple(int(n) for n in counts)
    nodes = _node_positions(origin, spacing, shape)
    if band > 0:
        coarsest = exact_resolution + 1 if exact_resolution > 0 else _COARSEST
        distance = banded_distance(exact, origin, spacing, shape, band,
                                   coarsest).reshape(-1)
    else:
        distance = _exact_distance(exact, nodes, np.arange(int(np.prod(shape))))
    # A band under a voxel leaves nodes within a voxel interpolated: none linked by them.
    inside = _grid_inside(exact, nodes, distance, shape, spacing,
                          linked=band == 0 or band >= _FAR_VOXELS)
    values = np.where(inside, -distance, distance).reshape(shape)
    return SDFGrid.from_values(origin, spacing, values)


def _node_positions(origin, spacing, shape):
    """``nodes(index)``: the (k, 3) positions of flat node indices (C order)."""
    axes = [origin[i] + spacing * np.arange(shape[i]) for i in range(3)]

    def nodes(index):
        index = np.unravel_index(index, shape)
        return np.column_stack([axis[i] for axis, i in zip(axes, index)])

    return nodes


def _exact_distance(exact, nodes, index):
    """Unsigned exact distances at the flat node indices ``index``, a batch at a time."""
    distance = np.empty(len(index))
    for start in range(0, len(index), _GRID_BATCH):
        batch = slice(start, start + _GRID_BATCH)
        squared = exact._closest(nodes(index[batch]))[0]  # the closest points not kept
        distance[batch] = np.sqrt(np.maximum(squared, 0.0))
    return distance


def banded_distance(exact, origin, spacing, shape, band, coarsest=_COARSEST):
    """Unsigned distance on a grid, exact within ``band`` voxels of the surface.

    A grid of twice the spacing is built first (the same way, down to ``coarsest`` voxels
    a side, which is exact everywhere) and interpolated trilinearly at this grid's nodes.
    A distance changes by at most the distance moved, so a node whose coarse neighbour's
    lower bound less the way to it is still ``band`` voxels or more is far from the surface
    and keeps the interpolated value; every other node is asked exactly. Far nodes cost
    the exact query the most (a thin-walled 16,000-face cup refined to 128 voxels: 6.2 s
    of closest points, 1.0 s with a band of 4); their values are off by up to some 15-25%
    of the distance where interpolation cuts a concave seam's corner (the less the wider
    the band), none within the band.

    Parameters
    ----------
    exact : ExactDistance
    origin : (3,) float
    spacing : float
    shape : (3,) int
    band : float, voxels
    coarsest : int
        Nodes along the longest side at or below which the grid is exact everywhere.

    Returns
    -------
    (nx, ny, nz) float
    """
    return _banded(exact, np.asarray(origin, float), float(spacing), tuple(shape), band,
                   coarsest)[0]


def _banded(exact, origin, spacing, shape, band, coarsest):
    """:func:`banded_distance` and a lower bound of the distance at each node."""
    nodes = _node_positions(origin, spacing, shape)
    if max(shape) <= coarsest:
        distance = _exact_distance(exact, nodes, np.arange(int(np.prod(shape))))
        distance = distance.reshape(shape)
        return distance, distance
    coarse_shape = tuple(n // 2 + 1 for n in shape)  # coarse node i is this grid's 2i
    coarse, coarse_low = _banded(exact, origin, 2 * spacing, coarse_shape, band, coarsest)
    value = _upsampled(coarse, shape)
    # The coarse node at (i // 2, j // 2, k // 2) lies one spacing away along each odd
    # index: the distance here is at least its lower bound less that way.
    odd = sum((np.arange(n, dtype=np.uint8) % 2).reshape([-1 if axis == a else 1
                                                          for a in range(3)])
              for axis, n in enumerate(shape))
    low = coarse_low[_halves(shape)] - spacing * np.sqrt(np.arange(4.0))[odd]
    near = np.flatnonzero(low < band * spacing)
    exact_values = _exact_distance(exact, nodes, near)
    value.reshape(-1)[near] = exact_values
    low.reshape(-1)[near] = exact_values
    return value, low


def _halves(shape):
    """Index arrays that pick coarse node (i // 2, j // 2, k // 2) for each node."""
    return np.ix_(*(np.arange(n) // 2 for n in shape))


def _upsampled(coarse, shape):
    """Trilinear values at the nodes of a grid of half the spacing, ``shape`` nodes: axis by
    axis, even nodes the coarse ones, odd nodes the mean of their two neighbours."""
    values = coarse
    for axis, n in enumerate(shape):
        lower = np.take(values, np.arange(n) // 2, axis=axis)
        upper = np.take(values, (np.arange(n) + 1) // 2, axis=axis)
        values = 0.5 * (lower + upper)
    return np.ascontiguousarray(values)


def _grid_inside(exact, nodes, distance, shape, spacing, linked=True):
    """Whether each grid node is inside (:meth:`ExactDistance.inside`): on a closed surface
    from winding numbers at two nodes of each part of nodes that share a sign
    (:func:`sign_parts`), a part whose two disagree asked node by node; on a surface that is
    not closed at every node."""
    inside = np.empty(len(distance), bool)

    def ask(index):
        answers = np.empty(len(index), bool)
        for start in range(0, len(index), _GRID_BATCH):
            answers[start:start + _GRID_BATCH] = exact.inside(
                nodes(index[start:start + _GRID_BATCH]))
        return answers

    if not exact.closed:
        inside[:] = ask(np.arange(len(distance)))
        return inside
    part, count = sign_parts(distance, shape, spacing, linked)
    order = np.argsort(part, kind="stable")
    sizes = np.bincount(part, minlength=count)
    ends = np.cumsum(sizes)
    first, last = order[ends - sizes], order[ends - 1]
    sign = ask(first)
    several = np.flatnonzero(sizes > 1)
    unsure = several[ask(last[several]) != sign[several]]
    inside[:] = sign[part]
    if len(unsure):
        index = np.flatnonzero(np.isin(part, unsure))
        inside[index] = ask(index)
    return inside


def sign_parts(distance, shape, spacing, linked=True):
    """Parts of a grid's nodes that share one side of a closed surface.

    Two neighbours (a voxel apart) with no surface point on the segment between them have
    the same winding number. There is none when their distances add up to more than the
    segment's length (``d(a) + d(b) > h``: a surface point on it would lie within ``t`` of
    one and ``h - t`` of the other); so the nodes farther than a voxel from the surface
    share their region's sign, and a node within a voxel joins every neighbour it is so
    linked to (``linked``; else each is a part of its own). A thin cup's grid at 128 voxels
    asked 87,000 winding numbers near its walls, and 26,000 so linked.

    Parameters
    ----------
    distance : (n,) float
        Unsigned distances at the nodes (C order of ``shape``): exact within a voxel of
        the surface, at least a voxel beyond it.
    shape : (3,) int
    spacing : float
    linked : bool

    Returns
    -------
    part : (n,) int
        Each node's part, ``0 <= part < count``.
    count : int
    """
    reach = _FAR_VOXELS * spacing
    far = distance > reach
    labels, regions = ndimage.label(far.reshape(shape))
    labels = labels.reshape(-1)
    near = np.flatnonzero(~far)
    part = labels - 1
    part[near] = regions + np.arange(len(near))
    count = regions + len(near)
    if not linked or not len(near):
        return part, count
    values, parts, close = (array.reshape(shape) for array in (distance, part, ~far))
    rows, columns = [], []
    for axis in range(3):
        low = tuple(slice(0, -1) if a == axis else slice(None) for a in range(3))
        high = tuple(slice(1, None) if a == axis else slice(None) for a in range(3))
        link = (close[low] | close[high]) & (values[low] + values[high] > reach)
        rows.append(parts[low][link])
        columns.append(parts[high][link])
    rows, columns = np.concatenate(rows), np.concatenate(columns)
    graph = sparse.coo_matrix((np.ones(len(rows), bool), (rows, columns)), (count, count))
    count, joined = csgraph.connected_components(graph, directed=False)
    return joined[part], int(count)


def missed_share(grid, points, normals):
    """Share of surface points at which a grid's gradient is more than 60 degrees off the
    surface normal: parts thinner than about two voxels, whose field the grid folds.

    Parameters
    ----------
    grid : SDFGrid
    points, normals : (n, 3) float, object frame
        Points on the surface and their outward unit normals.

    Returns
    -------
    float
    """
    _, gradients = grid.evaluate(points)
    return float(np.mean(np.einsum("ij,ij->i", gradients, normals) < MISS_COSINE))


def fitted_resolution(grid_at, bounds, padding, points, normals, resolution, max_resolution):
    """The coarsest grid resolution, doubling from ``resolution``, that resolves a shape's
    thin parts (:func:`missed_share` at most :data:`THIN_MISSES`), at most ``max_resolution``
    voxels and :data:`MAX_REFINED_NODES` nodes; the finest allowed if none does.

    Parameters
    ----------
    grid_at : callable
        ``grid_at(resolution) -> SDFGrid`` (built or read from a cache).
    bounds : (2, 3) float
    padding : float
    points, normals : (n, 3) float
        Surface samples and their outward unit normals, object frame.
    resolution, max_resolution : int

    Returns
    -------
    int
    """
    while missed_share(grid_at(resolution), points, normals) > THIN_MISSES:
        finer = 2 * resolution
        nodes = np.prod(grid_layout(bounds, finer, padding)[2])
        if finer > max_resolution or nodes > MAX_REFINED_NODES:
            break
        resolution = finer
    return resolution


def grid_layout(bounds, resolution=64, padding=1.0):
    """Where :func:`build_sdf_grid` puts its nodes: ``origin`` (3,), ``spacing`` and
    ``counts`` (3,) int."""
    low = np.asarray(bounds[0], dtype=float) - padding
    high = np.asarray(bounds[1], dtype=float) + padding
    spacing = float((high - low).max()) / int(resolution)
    counts = np.ceil((high - low) / spacing - 1e-9).astype(int) + 1
    # Centre the nodes on the box so the object sits symmetrically in the grid.
    origin = (low + high) / 2 - spacing * (counts - 1) / 2
    return origin, spacing, counts
