"""The GPIS posterior variance at surface vertices from a cache of grid nodes (beyond the
paper, which solves against the whole factor at every vertex every step).

A marching-cubes vertex lies on an edge of the grid, so its variance is interpolated
linearly between the edge's two nodes. A node's variance is
``a k(0) - |L^-1 k_x|^2`` with ``k_x`` its covariance with the observed rows (scale
included); when the factor grew by a block since the node was evaluated (the incremental
fit, :mod:`.gpis_incremental`), only the new block of ``L^-1 k_x`` is needed:
``L22^-1 (k_new - L21 L11^-1 k_old)``, ``O(m k)`` per node for ``k`` new rows instead of
``O(m^2)``. Nodes are keyed by their integer position on a lattice of fixed spacing
anchored at the origin, so the grids of successive steps share them; the cache keeps the
nodes of the last call only.

Accuracy: the variance along a cell edge is replaced by its chord. Near contacts it curves
within a cell (docs/gpis.md gives the measured error); the target choice, an argmax over
vertices, is unaffected where variance is large.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

from .gpis import value_rows
from .gpis_incremental import corrections, observed_rows

_SNAP = 1e-4  # lattice coordinates this close to an integer are on the node


@dataclass(frozen=True, eq=False)
class NodeVariance:
    """Reductions ``|L^-1 k_x|^2`` at lattice nodes for one factor (immutable).

    Attributes
    ----------
    spacing : float
    kernel : ThinPlateKernel or WendlandKernel
    rows : (p, 4) float
        The factor's observed rows (position, component).
    diagonal : (p,) float
        The factor's diagonal (a changed scale or jitter changes it).
    keys : (N,) int64, sorted
        The nodes' lattice positions, packed.
    reduction : (N,) float
    """

    spacing: float
    kernel: object
    rows: np.ndarray
    diagonal: np.ndarray
    keys: np.ndarray
    reduction: np.ndarray


def _pack(index):
    """(N, 3) int lattice positions -> (N,) int64 keys (each within +-2^20)."""
    shifted = index.astype(np.int64) + (1 << 20)
    return (shifted[:, 0] << 42) | (shifted[:, 1] << 21) | shifted[:, 2]


def _unpack(keys):
    return np.column_stack([(keys >> 42) - (1 << 20), ((keys >> 21) & ((1 << 21) - 1))
                            - (1 << 20), (keys & ((1 << 21) - 1)) - (1 << 20)])


def lattice_low(low, spacing):
    """The lattice node at or below ``low`` (3,) on each axis: (3,) float."""
    return np.floor(np.asarray(low, dtype=float) / spacing) * spacing


def vertex_corners(vertices, low, spacing):
    """The lattice nodes around each vertex and their trilinear weights.

    Parameters
    ----------
    vertices : (v, 3) float, world frame
    low : (3,) float
        A lattice node (``spacing`` times integers).
    spacing : float

    Returns
    -------
    keys : (v, 8) int64
        Packed lattice positions of the 8 corners of the vertex's cell.
    weights : (v, 8) float
        Trilinear weights (0 at the corners a vertex on an edge or node does not use).
    """
    local = (np.asarray(vertices, dtype=float) - low) / spacing
    nearest = np.round(local)
    local = np.where(np.abs(local - nearest) < _SNAP, nearest, local)
    base = np.floor(local)
    frac = local - base
    base = base.astype(np.int64) + np.round(np.asarray(low) / spacing).astype(np.int64)
    offsets = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    weights = np.prod(np.where(offsets[None], frac[:, None], 1 - frac[:, None]), axis=2)
    keys = _pack((base[:, None, :] + offsets[None]).reshape(-1, 3)).reshape(-1, 8)
    return keys, weights


def _reusable(cache, fit, rows, spacing):
    """How many leading factor rows the cache's reductions are for (0: none usable)."""
    if cache is None or cache.spacing != spacing or cache.kernel != fit.kernel:
        return 0
    p = len(cache.rows)
    if p == 0 or p > len(rows) or np.any(cache.rows != rows[:p]):
        return 0
    return p if np.array_equal(cache.diagonal, np.diag(fit.factor)[:p]) else 0


def _full_reduction(fit, nodes):
    """``|L^-1 k_x|^2`` at nodes (N, 3) against the whole factor."""
    cross = fit.scale * value_rows(nodes, fit.points, fit.kernel)[:, fit.kept]
    reduced = solve_triangular(fit.factor, cross.T, lower=True, check_finite=False)
    return np.sum(reduced**2, axis=0)


def _added_reduction(fit, nodes, start):
    """The part of ``|L^-1 k_x|^2`` from factor rows ``start:`` (N,)."""
    factor = fit.factor
    # Y = [-L21 L11^-1, I]: the new block of L^-1 k_x is L22^-1 Y k_x.
    bridge = solve_triangular(factor[:start, :start], factor[start:, :start].T, lower=True,
                              trans="T", check_finite=False)
    combination = np.hstack([-bridge.T, np.eye(len(factor) - start)])
    weights = np.zeros((4 * len(fit.points), len(combination)))
    weights[fit.kept] = combination.T
    mixed = fit.scale * corrections(nodes, fit.points, weights, fit.kernel)
    block = solve_triangular(factor[start:, start:], mixed.T, lower=True, check_finite=False)
    return np.sum(block**2, axis=0)


def node_variance(fit, keys, spacing, cache=None):
    """Posterior variance at lattice nodes, reusing ``cache``'s reductions.

    Parameters
    ----------
    fit : GPISFit
    keys : (N,) int64, unique and sorted
        Packed lattice positions (:func:`vertex_corners`).
    spacing : float
    cache : NodeVariance or None

    Returns
    -------
    variance : (N,) float
        Never negative.
    cache : NodeVariance
        For these nodes and ``fit``'s factor.
    """
    rows = observed_rows(fit.points, fit.kept)
    reduction = np.empty(len(keys))
    start = _reusable(cache, fit, rows, spacing)
    known = np.zeros(len(keys), dtype=bool)
    if start:
        where = np.clip(np.searchsorted(cache.keys, keys), 0, len(cache.keys) - 1)
        known = cache.keys[where] == keys
        reduction[known] = cache.reduction[where[known]]
        if start < len(rows) and known.any():
            reduction[known] += _added_reduction(fit, spacing * _unpack(keys[known]), start)
    if (~known).any():
        reduction[~known] = _full_reduction(fit, spacing * _unpack(keys[~known]))
    variance = np.maximum(fit.prior_variance - reduction, 0.0)
    return variance, NodeVariance(spacing, fit.kernel, rows, np.diag(fit.factor).copy(), keys,
                                  reduction)


def lattice_variance(fit, vertices, low, spacing, cache=None):
    """Posterior variance at surface vertices interpolated from lattice nodes.

    Parameters
    ----------
    fit : GPISFit
    vertices : (v, 3) float, world frame
        On the edges of the grid ``low + spacing * index``.
    low : (3,) float
        A lattice node: ``spacing`` times integers.
    spacing : float
    cache : NodeVariance or None

    Returns
    -------
    variance : (v,) float
    cache : NodeVariance or None
    """
    if len(vertices) == 0 or len(fit.points) == 0:
        return np.full(len(vertices), fit.prior_variance), cache
    corners, weights = vertex_corners(vertices, low, spacing)
    used = weights > 0
    keys, inverse = np.unique(corners[used], return_inverse=True)
    values, cache = node_variance(fit, keys, spacing, cache)
    spread = np.zeros(corners.shape)
    spread[used] = values[inverse.ravel()]
    return np.sum(weights * spread, axis=1), cache
