"""The GPIS mean's correction summed by compiled loops (numba), without the ``(p, q)``
temporaries of :func:`~.gpis.value_rows` (:mod:`.gpis_incremental`).

No kernel here uses ``fastmath``: with it, the order in which LLVM summed the correction
depended on whether numba compiled the kernel in this process or loaded it from its disk
cache, and a trial's numbers with them (an 8 cm cup's reconstruction 18.4% of its size in
a fresh checkout, 15.9% once cached). The sum runs in :data:`LANES` fixed partial sums
instead (within about 15% of the old speed), the same however the kernel was compiled.
"""

import numpy as np
from numba import njit

LANES = 16
"""Partial sums of the correction, added in a fixed order at the end."""


@njit(cache=True)
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


@njit(cache=True)
def _corrections(x, y, weights, reach, wendland):
    count, columns = y.shape[1], weights.shape[0]
    out = np.empty((len(x), columns))
    dx, dy, dz = np.empty(count), np.empty(count), np.empty(count)
    value, g = np.empty(count), np.empty(count)
    lanes = np.empty(LANES)
    whole = count - count % LANES
    for i in range(len(x)):
        _profile(x[i], y, reach, wendland, dx, dy, dz, value, g)
        for c in range(columns):
            lanes[:] = 0.0
            for start in range(0, whole, LANES):
                for lane in range(LANES):
                    lanes[lane] += _term(start + lane, c, value, g, dx, dy, dz, weights)
            for j in range(whole, count):
                lanes[j - whole] += _term(j, c, value, g, dx, dy, dz, weights)
            total = 0.0
            for lane in range(LANES):
                total += lanes[lane]
            out[i, c] = total
    return out


@njit(cache=True, inline="always")
def _term(j, c, value, g, dx, dy, dz, weights):
    """Point ``j``'s share of weight column ``c``'s correction."""
    return value[j] * weights[c, 0, j] + g[j] * (
        dx[j] * weights[c, 1, j] + dy[j] * weights[c, 2, j] + dz[j] * weights[c, 3, j])


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


@njit(cache=True)
def _kernel_terms(dx, dy, dz, reach, big3, four_c, g_c, dg_c, wendland):
    """``r``, ``k(r)``, ``g = k'(r) / r`` and ``g'(r)`` of one offset, each rounded as
    the kernels' ``profile`` rounds it (no fastmath: the results are those of numpy)."""
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    if wendland:
        rest = max(1.0 - r / reach, 0.0)
        rest2 = rest * rest
        rest3 = rest2 * rest
        return r, rest3 * rest * (four_c * r + 1), rest3 * g_c, dg_c * rest2
    r2 = r * r
    return r, 2 * r2 * r - 3 * reach * r2 + big3, 6 * (r - reach), 6.0


@njit(cache=True)
def _value_rows(x, y, reach, big3, four_c, g_c, dg_c, wendland, out):
    for i in range(x.shape[0]):
        for j in range(y.shape[0]):
            dx, dy, dz = x[i, 0] - y[j, 0], x[i, 1] - y[j, 1], x[i, 2] - y[j, 2]
            _, value, g, _ = _kernel_terms(dx, dy, dz, reach, big3, four_c, g_c, dg_c,
                                           wendland)
            out[i, 4 * j] = value
            out[i, 4 * j + 1], out[i, 4 * j + 2], out[i, 4 * j + 3] = -g * dx, -g * dy, -g * dz
    return out


@njit(cache=True)
def _kernel_blocks(x, y, reach, big3, four_c, g_c, dg_c, wendland, out):
    d = np.empty(3)
    for i in range(x.shape[0]):
        for j in range(y.shape[0]):
            for a in range(3):
                d[a] = x[i, a] - y[j, a]
            r, value, g, dg = _kernel_terms(d[0], d[1], d[2], reach, big3, four_c, g_c,
                                            dg_c, wendland)
            out[4 * i, 4 * j] = value
            for a in range(3):
                first = g * d[a]
                out[4 * i + 1 + a, 4 * j] = first
                out[4 * i, 4 * j + 1 + a] = -first
                for b in range(3):
                    outer = d[a] * d[b] / r if r > 0 else 0.0
                    out[4 * i + 1 + a, 4 * j + 1 + b] = -(dg * outer
                                                          + (1.0 if a == b else 0.0) * g)
    return out


def _constants(reach, wendland):
    """The kernel's constants, computed in Python as ``profile`` computes them."""
    reach = float(reach)
    return (reach, reach**3, 4 / reach, -20 / reach**2, 60 / reach**3 if wendland else 6.0,
            bool(wendland))


def compiled_value_rows(x, y, reach, wendland):
    """:func:`~.gpis.value_rows` by a compiled loop: the same numbers, without the
    ``(p, q, 3)`` temporaries. ``(p, 4 q)`` float."""
    x, y = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(y, dtype=float)
    return _value_rows(x, y, *_constants(reach, wendland), np.empty((len(x), 4 * len(y))))


def compiled_kernel_blocks(x, y, reach, wendland):
    """:func:`~.gpis.kernel_blocks` by a compiled loop: the same numbers, without the
    ``(p, q, 3, 3)`` temporaries. ``(4 p, 4 q)`` float."""
    x, y = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(y, dtype=float)
    return _kernel_blocks(x, y, *_constants(reach, wendland),
                          np.empty((4 * len(x), 4 * len(y))))
