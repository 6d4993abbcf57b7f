"""Every prior of a library in shared arrays: what the particle filter reads.

The filter's cost and memory grew with the number of priors because each prior was a
separate object with float64 grids and its own point-pair table, visited in a Python loop.
A :class:`PriorBank` holds all of them together: the SDF grids' codes (16-bit values, 8-bit
gradients) one after another, interpolated for any mix of priors in one call; the feature
points stacked; and one point-pair table over all priors. It is built once from the models' disk
cache, so a library of a thousand priors loads in seconds and holds some 0.8 MB a prior.
Priors the cache lacks are built first, in child processes (one a core) when there are
several (:mod:`~tactile_viz.engine.belief.prior_build`): a library built from meshes ends as
small as one read from the cache.
"""

from __future__ import annotations

import ctypes
from functools import cached_property

import numpy as np

from ..shape.sdf import SDFGrid, interpolate
from ..shape.sdf_build import grid_layout
from .kernels import pairs_below
from .ppf import PairTable, rotation_to_x


class PriorBank:
    """The priors' SDF grids, feature points and point pairs, indexed by class.

    Parameters
    ----------
    models : sequence of ObjectModel
        All with the same ``n_features``.
    distance_step : float
        Point-pair distance key step, scene units.
    angle_step_deg : float
    progress : callable, optional
        Wraps the iteration over the models, or over the priors child processes build
        when the disk cache lacks several (for example ``tqdm``).

    Attributes
    ----------
    codes : (total,) int16
        Every grid's node value codes, one after another.
    gradient_codes : (total, 3) int8
    offsets : (C,) int64
        Where class ``c``'s grid starts in ``codes``.
    shapes : (C, 3) int64
    origins : (C, 3) float
        Object frame, scene units.
    spacings, value_steps : (C,) float
    points, normals : (C, F, 3) float
        Feature points and their unit normals, object frame.
    frames : (C, F, 3, 3) float
        The rotation turning each feature normal onto +x (its point-pair frame).
    pairs : PairTable
        Over every class.
    learned : (C,) bool
    """

    def __init__(self, models, distance_step, angle_step_deg, progress=None):
        from .prior_build import build_in_child

        models = list(models)
        if build_in_child(models, distance_step, angle_step_deg, progress):
            progress = None  # the children's build was the long part
        self._index = {id(model): c for c, model in enumerate(models)}
        self._models = models  # keeps the ids above theirs
        self.names = [model.name for model in models]
        self.learned = np.array([model.learned for model in models], dtype=bool)
        layouts = [grid_layout(model.mesh.bounds, _resolution(model),
                               model.params.sdf_padding * model.size_unit) for model in models]
        self.shapes = np.array([counts for _, _, counts in layouts], dtype=np.int64)
        sizes = self.shapes.prod(axis=1)
        self.offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self.codes = np.empty(int(sizes.sum()), np.int16)
        self.gradient_codes = np.empty((int(sizes.sum()), 3), np.int8)
        self.origins = np.empty((len(models), 3))
        self.spacings = np.empty(len(models))
        self.value_steps = np.empty(len(models))
        features, tables = [], []
        for c, model in enumerate(progress(models) if progress else models):
            with model.transient_exact():
                grid = model.load_sdf()
                features.append(model.features)
                tables.append(model.pair_table(distance_step, angle_step_deg, keep=False))
                model.inertia  # noqa: B018 (cached: the decisions' turns read it)
            if grid.shape != tuple(self.shapes[c]):
                raise RuntimeError(f"prior {model.name!r}: cached grid {grid.shape} is not "
                                   f"the expected {tuple(self.shapes[c])}")
            nodes = slice(self.offsets[c], self.offsets[c] + sizes[c])
            self.codes[nodes] = grid.codes.reshape(-1)
            self.gradient_codes[nodes] = grid.gradient_codes.reshape(-1, 3)
            self.origins[c], self.spacings[c], self.value_steps[c] = (
                grid.origin, grid.spacing, grid.value_step)
        self.points = np.stack([points for points, _ in features])
        self.normals = np.stack([normals for _, normals in features])
        classes, count = self.normals.shape[:2]
        self.frames = rotation_to_x(self.normals.reshape(-1, 3)).reshape(classes, count, 3, 3)
        self.pairs = PairTable.combine(tables)
        del tables, features
        release_freed_memory()

    def __len__(self):
        return len(self.names)

    @property
    def large(self) -> bool:
        """Whether the bank is large enough that a filter trims the heap after each update."""
        return self.nbytes > LARGE

    @property
    def grids(self):
        """The grid arrays in the order :mod:`~tactile_viz.engine.belief.kernels` takes them."""
        return (self.codes, self.gradient_codes, self.offsets, self.shapes, self.origins,
                self.spacings, self.value_steps)

    @cached_property
    def nbytes(self) -> int:
        """Bytes of the bank's arrays (fixed once built)."""
        arrays = (self.codes, self.gradient_codes, self.offsets, self.shapes, self.origins,
                  self.spacings, self.value_steps, self.points, self.normals, self.frames)
        return int(sum(a.nbytes for a in arrays) + self.pairs.nbytes)

    @cached_property
    def boxes(self):
        """Each class's grid box, object frame: ``low (c, 3)``, ``high (c, 3)``, its first
        and last nodes (outside it a class's value is positive and grows by at least the
        distance to it: :func:`~tactile_viz.engine.shape.sdf.interpolate`)."""
        low = np.asarray(self.origins, float)
        return low, low + (np.asarray(self.shapes) - 1) * np.asarray(self.spacings, float)[:, None]

    def near_boxes(self, level=0.0):
        """Each class's box about the nodes whose value is at most ``level`` (scene units),
        object frame, outside which its value exceeds ``level``: ``low (c, 3)``,
        ``high (c, 3)``.

        Inside the grid a point's value is a convex combination of its cell's eight nodes,
        so a point one spacing beyond every such node lies above ``level`` (the nodes are
        taken one value code above it, against rounding); outside it, the value at the
        nearest grid point plus the distance to it. Cached by ``level``.
        """
        cache = self.__dict__.setdefault("_near_boxes", {})
        if level not in cache:
            low, high = np.array(self.boxes[0]), np.array(self.boxes[1])
            for c in range(len(self)):
                grid = self.grid(c)
                below = grid.codes <= level / grid.value_step + 1
                spans = [np.flatnonzero(below.any(axis=tuple({0, 1, 2} - {axis})))
                         for axis in range(3)]
                if not len(spans[0]):
                    continue
                first, last = np.array([[s[0], s[-1]] for s in spans]).T
                if first.min() > 0 and (last < np.array(below.shape) - 1).all():
                    low[c] = grid.origin + (first - 1) * grid.spacing
                    high[c] = grid.origin + (last + 1) * grid.spacing
                else:  # a node on the grid's face: as far out as the least value allows
                    reach = level - grid.codes.min() * grid.value_step
                    low[c], high[c] = low[c] - reach, high[c] + reach
            cache[level] = low, high
        return cache[level]

    def below(self, classes, rotations, translations, points, level=0.0):
        """Each ``(hypothesis, point)`` pair whose signed distance is below ``level``.

        Parameters
        ----------
        classes : (k,) int
        rotations : (k, 3, 3) float
            Object-to-world rotations.
        translations : (k, 3) float, world frame
        points : (q, 3) float, world frame
        level : float, scene units

        Returns
        -------
        pose, point : (n,) int
            The pairs, in order of hypothesis then point.
        values : (n,) float
        gradients : (n, 3) float
            Unit outward gradients, object frame.
        """
        classes = np.ascontiguousarray(classes, dtype=np.int64)
        rotations = np.ascontiguousarray(rotations, float)
        translations = np.ascontiguousarray(translations, float)
        points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
        low, high = self.near_boxes(float(level))
        # Room for every pair of a chunk of hypotheses: a bounded buffer at any count.
        step = max(1, BELOW_PAIRS // max(len(points), 1))
        pose, point = np.empty(step * len(points), np.int64), np.empty(step * len(points),
                                                                        np.int64)
        values, gradients = np.empty(len(pose)), np.empty((len(pose), 3))
        parts = []
        for start in range(0, len(classes), step):
            chunk = slice(start, start + step)
            found = pairs_below(*self.grids, classes[chunk], rotations[chunk],
                                translations[chunk], points, low, high, float(level), pose,
                                point, values, gradients)
            parts.append((pose[:found] + start, point[:found].copy(), values[:found].copy(),
                          gradients[:found].copy()))
        if not parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3))
        return tuple(np.concatenate(arrays) for arrays in zip(*parts))

    def grid(self, c):
        """Class ``c``'s :class:`~tactile_viz.engine.shape.sdf.SDFGrid` as views into the bank's
        arrays (no copy)."""
        nodes = slice(self.offsets[c], self.offsets[c] + self.shapes[c].prod())
        shape = tuple(int(n) for n in self.shapes[c])
        return SDFGrid(self.origins[c], float(self.spacings[c]),
                       self.codes[nodes].reshape(shape), float(self.value_steps[c]),
                       self.gradient_codes[nodes].reshape(shape + (3,)))

    def evaluate(self, classes, points):
        """Signed distance and outward unit gradient of each class's grid.

        Parameters
        ----------
        classes : (k,) int
        points : (k, m, 3) float
            Points in the object frame of their row's class.

        Returns
        -------
        values : (k, m) float
        gradients : (k, m, 3) float
        """
        c = np.asarray(classes)[:, None]
        return interpolate(self.codes, self.gradient_codes, self.offsets[c], self.shapes[c],
                           self.origins[c], self.spacings[c], self.value_steps[c], points)

    def lookup(self, features, neighbours=0):
        """Point pairs of every class that match observed features (see
        :meth:`~tactile_viz.engine.belief.ppf.PairTable.lookup`): query, classes, first, second."""
        return self.pairs.lookup(features, neighbours)


BELOW_PAIRS = 1 << 21  # (hypothesis, point) pairs :meth:`PriorBank.below` looks at a call
LARGE = 200e6  # bytes of a bank beyond which a filter trims the heap after each update


def kept_recent(cache, key, build, keep):
    """``cache[key]``, made by ``build()`` when absent; only the ``keep`` most recently
    asked for stay (what a bank keeps per class: a thousand priors' would not fit)."""
    value = cache.pop(key, None)
    if value is None:
        value = build()
    cache[key] = value  # most recently used last
    while len(cache) > keep:
        cache.pop(next(iter(cache)))
    return value


def release_freed_memory():
    """Hand freed buffers back to the system. glibc keeps them for reuse, and a large
    library's transient arrays fragment its heap: with 1,000 priors the process held 370 MB
    more than its live data after building the bank, and grew 10-15 MB a trial after that.
    About a millisecond when there is little to return."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to do
        pass


_RECENT = {}  # the last bank built: sessions over one library share it


def grid_of(model):
    """``model``'s SDF grid: a view into the current bank if it holds the model, else the
    model's own (built or read from the disk cache once). A long session meets many MAP
    classes; this way their grids are not copied out of the bank one by one."""
    for bank in _RECENT.values():
        c = bank._index.get(id(model))
        if c is not None:
            return bank.grid(c)
    return model.sdf


def bank_for(models, distance_step, angle_step_deg, progress=None) -> PriorBank:
    """The :class:`PriorBank` of ``models``, shared with the last filter over the same
    priors (same names, meshes, learned flags and model parameters) and key steps."""
    key = (tuple((m.name, m.content_hash, m.learned, m.params) for m in models),
           float(distance_step), float(angle_step_deg))
    if key not in _RECENT:
        _RECENT.clear()  # before building: two banks of a large library need not coexist
        _RECENT[key] = PriorBank(models, distance_step, angle_step_deg, progress)
    return _RECENT[key]


def _resolution(model):
    """The model's grid resolution, without keeping the exact distance a fit may need."""
    with model.transient_exact():
        return model.grid_resolution
