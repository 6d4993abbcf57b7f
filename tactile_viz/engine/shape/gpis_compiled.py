"""The GPIS mean's correction summed by compiled loops (numba), without the ``(p, q)``
temporaries of :func:`~.gpis.value_rows` (:mod:`.gpis_incremental`)."""

import numpy as np
from numba import njit


@njit(cache=True, fastmath=True)
def _profile(x, y, reach, wendland, dx, dy, dz, value, g):
    """Offsets, ``k(r)`` and ``-g(r)`` of one query against every point (in place)."""
    big3 = reach**3
    for j in range(y.shape[1]):
        dx[j], dy[j], dz[j] = x[0] - y[0, j], x[1] - y[1, j], x[2] - y[2, j]
        r = np.sqrt(dx[j] * dx[j] + dy[j] * dy[j] + dz[j] * dz[j])
        if wendland:
            rest = max(1.0 - r / reach, 0.0)
            rest3 = rest * rest * rest
            value[j], g[j] = rest3 * rest * (4.0 / reach * r + 1.0), 20.0 / reach**2 * rest3
        else:
            value[j], g[j] = (2.0 * r - 3.0 * reach) * r * r + big3, 6.0 * (reach - r)


@njit(cache=True, fastmath=True)
def _corrections(x, y, weights, reach, wendland):
    count, columns = y.shape[1], weights.shape[0]
    out = np.empty((len(x), columns))
    dx, dy, dz = np.empty(count), np.empty(count), np.empty(count)
    value, g = np.empty(count), np.empty(count)
    for i in range(len(x)):
        _profile(x[i], y, reach, wendland, dx, dy, dz, value, g)
        for c in range(columns):
            total = 0.0
            for j in range(count):
                total += value[j] * weights[c, 0, j] + g[j] * (
                    dx[j] * weights[c, 1, j] + dy[j] * weights[c, 2, j]
                    + dz[j] * weights[c, 3, j])
            out[i, c] = total
    return out


def compiled_corrections(x, y, weights, reach, wendland):
    """``value_rows(x, y, kernel) @ weights`` by a compiled loop, for several weight
    vectors at once.

    Parameters
    ----------
    x : (p, 3) float
    y : (q, 3) float
    weights : (4 q,) or (4 q, c) float
    reach : float
        The kernel's radius (thin-plate ``R`` or Wendland support ``c``).
    wendland : bool
        The Wendland kernel, else the thin-plate one.

    Returns
    -------
    (p,) or (p, c) float
    """
    weights = np.asarray(weights, dtype=float)
    stacked = np.ascontiguousarray(weights.reshape(len(y), 4, -1).transpose(2, 1, 0))
    out = _corrections(np.ascontiguousarray(x, dtype=float),
                       np.ascontiguousarray(np.asarray(y, dtype=float).T), stacked,
                       float(reach), bool(wendland))
    return out[:, 0] if weights.ndim == 1 else out
