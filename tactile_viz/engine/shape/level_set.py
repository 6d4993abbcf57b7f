"""The zero level set of a GPIS posterior mean on a grid (marching cubes), the grid's
nodes and the vertices where the surface closes at its box rather than where the mean
crosses zero."""

import numpy as np
from scipy.ndimage import binary_fill_holes, map_coordinates, maximum_filter, minimum_filter
from skimage.measure import marching_cubes


def zero_level_surface(fit, bounds, resolution=32, band=True, spacing=None, fill_voids=False):
    """Marching cubes on the posterior mean over a box.

    Parameters
    ----------
    fit : GPISFit
    bounds : (2, 3) float
        The box (world frame); it should contain the surface with some margin.
    resolution : int
        Cells along the longest side of the box.
    band : bool
        Evaluate the mean exactly only near the surface: on every second grid node first,
        then on the nodes whose interpolated value is within :data:`BAND_CELLS` coarse cell
        diagonals of zero (the mean is about a distance, so farther nodes cannot change
        sign); elsewhere the interpolated value stands. False evaluates every node.
    spacing : float, optional
        The grid's cell instead of the longest side over ``resolution`` (nodes at
        ``bounds[0] + spacing * index``).
    fill_voids : bool
        Fill the mean's voids, outside regions enclosed by inside ones (:func:`filled_voids`):
        the surface is then only the one a probe can reach from outside.

    Returns
    -------
    vertices : (v, 3) float, world frame
    faces : (f, 3) int
        Empty arrays when the mean has no zero crossing in the box.
    """
    low, spacing, counts = level_grid(bounds, resolution, spacing, band)
    if band:
        volume = _banded_mean(fit, low, spacing, counts)
    else:
        axes = [low[i] + spacing * np.arange(counts[i]) for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        volume = fit.mean_value(grid).reshape(tuple(counts))
    # Close the surface at the box: outside the box counts as outside the object.
    volume = np.pad(volume, 1, constant_values=max(float(volume.max()), spacing))
    if fill_voids:
        volume = filled_voids(volume)
    if not (volume.min() < 0 < volume.max()):
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices, faces, _, _ = marching_cubes(volume, 0.0, spacing=(spacing,) * 3,
                                           method="lewiner")
    return vertices + low - spacing, faces.astype(np.int64)


def level_grid(bounds, resolution=32, spacing=None, band=True):
    """The nodes :func:`zero_level_surface` evaluates: their low corner, cell and
    ``(3,)`` counts (odd with ``band``)."""
    low, high = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    spacing = float((high - low).max()) / resolution if spacing is None else float(spacing)
    counts = np.maximum(np.ceil((high - low) / spacing).astype(int) + 1, 2)
    if band:
        counts += (counts + 1) % 2  # odd: every second node spans the same box
    return low, spacing, counts


def box_closure(vertices, bounds, resolution=32, spacing=None, band=True):
    """Mask of the vertices of :func:`zero_level_surface` that close its surface at the
    box: beyond its outermost nodes, where the solid reaches the box and is cut off there.

    Such a vertex is not where the posterior mean crosses zero but where the grid ends (a
    thin-plate fit's solid can reach far past every contact); a probe sent there finds
    the object only if it reaches past the box.

    Parameters
    ----------
    vertices : (v, 3) float, world frame
    bounds, resolution, spacing, band
        As given to :func:`zero_level_surface`.

    Returns
    -------
    (v,) bool
    """
    low, spacing, counts = level_grid(bounds, resolution, spacing, band)
    top = low + spacing * (counts - 1)
    vertices = np.reshape(vertices, (-1, 3))
    slack = 1e-6 * spacing
    return ((vertices < low - slack) | (vertices > top + slack)).any(axis=1)


BAND_CELLS = 1.0


def filled_voids(volume):
    """A grid of signed values with its voids filled: every outside node (value >= 0) that
    no path of outside nodes joins to the grid's border gets the value ``-max(|v|, tiny)``.

    A prior with a cavity (a mug's inside) keeps that cavity's wall inside the estimate
    where contacts closed its opening (a ball's top): a surface no probe can reach, 4 cm
    inside a 10 cm ball, which no contact ever covers (the DHD stop never came) and which
    the reported, exported and learned surfaces carried.

    Parameters
    ----------
    volume : (a, b, c) float
        Values on a grid whose border nodes are outside.

    Returns
    -------
    (a, b, c) float
    """
    inside = volume < 0
    voids = binary_fill_holes(inside) & ~inside
    if not voids.any():
        return volume
    volume = volume.copy()
    volume[voids] = -np.maximum(np.abs(volume[voids]), 1e-12)
    return volume


def _in_crossing_cells(coarse):
    """Fine nodes (twice the resolution) on a coarse cell whose corners change sign: there
    the surface is, whatever the slope."""
    low = minimum_filter(coarse, size=2, origin=-1)[:-1, :-1, :-1]
    high = maximum_filter(coarse, size=2, origin=-1)[:-1, :-1, :-1]
    cells = (low < 0) & (high > 0)
    for axis in range(3):
        fine = np.repeat(cells, 2, axis=axis)  # fine cells
        pad = [(0, 0)] * 3
        pad[axis] = (1, 1)
        fine = np.pad(fine, pad)
        count = fine.shape[axis]
        # A node touches the fine cells before and after it.
        cells = (np.take(fine, range(count - 1), axis=axis)
                 | np.take(fine, range(1, count), axis=axis))
    return cells


def _banded_mean(fit, low, spacing, counts):
    """The posterior mean on the grid ``low + spacing * index`` (odd ``counts``), exact
    within a band around the zero level and interpolated from every second node
    elsewhere."""
    coarse_counts = (counts + 1) // 2
    axes = [low[i] + 2 * spacing * np.arange(coarse_counts[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    coarse = fit.mean_value(grid).reshape(tuple(coarse_counts))
    index = np.indices(tuple(counts), dtype=float).reshape(3, -1) / 2
    volume = map_coordinates(coarse, index, order=1).reshape(tuple(counts))
    near = (np.abs(volume) <= BAND_CELLS * 2 * spacing * np.sqrt(3)) | _in_crossing_cells(coarse)
    points = low + spacing * np.argwhere(near)
    volume[near] = fit.mean_value(points)
    return volume
