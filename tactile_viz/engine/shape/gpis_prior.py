"""The GPIS prior mean beyond the MAP shape itself: the shape carved where probes found free
space, the solid behind the contacts added, and the value observations of non-contacts
(beyond the paper); the observations of a fit less the prior mean."""

import numpy as np
from scipy.spatial import cKDTree

SHRINK_STEPS = 32  # shrinking-ball iterations (each a look-up of every ball still shrinking)
# The cut's values within this share of its largest radius tie: there the gradient is the
# prior's if it ties, else the mean of the tied balls'. A contact lies on the rim of
# every ball it bounds, where a rounding error gave it one ball's gradient, another's or
# the prior's: two touches of one spot (a noiseless probe's lie microns apart) disagreed
# by up to 90 degrees, which a fit with little noise explains only by huge weights (a
# 10 cm ball's ellipsoid prior lost its evidence by 80,000 nats).
CUT_TIE = 1e-3


def noncontact_observations(prior, noncontacts, value):
    """The non-contacts that contradict the prior (prior value below ``value``).

    Returns
    -------
    (k, 3) float
        Their positions; each becomes a pseudo-observation ``f = value``.
    """
    noncontacts = np.asarray(noncontacts, dtype=float).reshape(-1, 3)
    if len(noncontacts) == 0:
        return noncontacts
    return noncontacts[np.asarray(prior(noncontacts)[0]) < value]


def row_noise(components, noise_variance, gradient_noise_variance=None):
    """The noise variance of observed rows by their ``components`` ((m,) int: 0 a value,
    1-3 a gradient's): ``noise_variance`` on values, ``gradient_noise_variance`` (None:
    the same) on gradients. A value is a length and a gradient a unit normal's tilt, so
    a sensor's position and normal noise belong to different rows."""
    components = np.asarray(components)
    gradient = noise_variance if gradient_noise_variance is None else gradient_noise_variance
    return np.where(components == 0, float(noise_variance), float(gradient))


def edge_tilt(position_noise, size, gain=1.0):
    """The tilt (rad, a standard deviation) of a contact's normal at its noisy position: a
    contact the position noise ``s`` moves across an edge or a thin wall carries the
    normal of its other side, and the share of such contacts on an object of longest side
    ``size`` grows as ``s / size``; ``gain * sqrt(s / size)``, 0 without noise.

    Parameters
    ----------
    position_noise : float
        The sensor's position noise (a standard deviation, scene units).
    size : float
        The object's longest side (scene units).
    gain : float
        1: a tilt of about 0.3 rad (18 degrees) at a noise of a tenth of the size.
    """
    if not (position_noise > 0 and gain > 0 and size > 0):
        return 0.0
    return float(gain) * float(np.sqrt(position_noise / size))


def observations(points, normals, prior, noncontacts=None, noncontact_value=0.1,
                 noise_variance=1e-4, refuting=None, gradient_noise_variance=None):
    """The GPIS's observations: contacts (value 0, gradient the normal), then non-contacts
    that contradict the prior and the ``refuting`` (q, 3) points, whatever the prior there
    (value ``noncontact_value``), less the prior mean.

    Returns
    -------
    everything : (n, 3) float, world frame
        Contacts, then the non-contacts kept.
    kept : (m,) int
        Observed rows of the ``4 n`` [value, gradient] components.
    residual : (m,) float
        Observation less prior mean on the kept rows.
    noise : (m,) float
        ``noise_variance`` on the value rows, ``gradient_noise_variance`` (None: the
        same) on the contacts' gradient rows.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    outside = (np.zeros((0, 3)) if noncontacts is None
               else noncontact_observations(prior, noncontacts, noncontact_value))
    if refuting is not None:
        outside = np.vstack([outside, np.asarray(refuting, dtype=float).reshape(-1, 3)])
    everything = np.vstack([points, outside])
    if len(everything) == 0:
        return everything, np.zeros(0, dtype=int), np.zeros(0), np.zeros(0)
    prior_values, prior_gradients = prior(everything)
    observed = np.hstack([np.zeros((len(everything), 1)),
                          np.vstack([normals, np.zeros((len(outside), 3))])])
    observed[len(points):, 0] = noncontact_value
    residual = (observed - np.column_stack([prior_values, prior_gradients])).ravel()
    kept = np.concatenate([np.arange(4 * len(points)),
                           4 * (len(points) + np.arange(len(outside)))])
    return (everything, kept, residual[kept],
            row_noise(kept % 4, noise_variance, gradient_noise_variance))


REFUTE_MOST = 64
"""Free points a round of :func:`refuted_fit` adds at most, the deepest inside first: a
box prior's phantom held hundreds, and three rounds of them took 8-30 s a touch."""


def refuted_fit(fit, free, value, rounds, refit, contacts=None, keep_within=0.0):
    """``fit`` fitted again while it puts points known to be outside inside (beyond the
    paper): each round adds the ``free`` points whose posterior mean is below ``value`` to
    those observing ``f = value``, at most ``rounds`` times, the :data:`REFUTE_MOST` deepest
    a round; only points farther than ``keep_within`` from every contact refute.

    The carve (:func:`carved_prior`) removes a prior's phantom part where a probe passed
    through it; a bulge of the fit itself, where the prior is outside, it cannot: a
    thin-plate fit of an 8 cm cup touched on both sides of its 2 mm walls grew one 3-6 cm
    beyond every contact, the targets aimed at it and every probe missed it.

    Parameters
    ----------
    fit : GPISFit
    free : (q, 3) float, world frame
        Points outside the object: non-contacts and points along missed probes.
    value : float, scene units
        ``gpis_noncontact_value``.
    rounds : int
    refit : callable
        ``refit(refuting (k, 3)) -> GPISFit``: the same fit with those points observed.
    contacts : (n, 3) float, world frame, optional
    keep_within : float, scene units
        A probe that passed beside a thin part within this of a contact refutes nothing:
        observed there, it pushed a 20 cm fork's 2 mm tines away (60-104% of its size
        off), as the carve's balls spare the same places (:func:`free_space_cut`).

    Returns
    -------
    GPISFit
        ``fit`` itself when it puts none of ``free`` inside.
    """
    free = np.asarray(free, dtype=float).reshape(-1, 3)
    contacts = np.asarray(() if contacts is None else contacts, dtype=float).reshape(-1, 3)
    if keep_within > 0 and len(free) and len(contacts):
        free = free[cKDTree(contacts).query(free)[0] > keep_within]
    chosen = np.zeros(len(free), dtype=bool)
    for _ in range(rounds if len(free) else 0):
        values = np.asarray(fit.mean_value(free))
        new = np.flatnonzero((values < value) & ~chosen)
        if not len(new):
            break
        chosen[new[np.argsort(values[new], kind="stable")[:REFUTE_MOST]]] = True
        fit = refit(free[chosen])
    return fit


def carved_prior(prior, free_points, contacts, radius, neighbours=8, inside_only=False,
                 normals=None, disk=0.0):
    """The prior mean with the space known to be empty cut out of its shape.

    A ball around each free-space point (where a probe passed without touching) is removed
    from the prior's solid, a CSG difference on signed distances:
    ``m'(x) = max(m(x), r_i - |x - f_i|)``. A ball never reaches a contact:
    ``r_i = min(radius, distance from f_i to the nearest contact)``; where values tie (a
    contact on the rims of the balls it bounds) the gradient is the prior's if it ties,
    else the tied balls' mean. Unlike a value
    observation, which moves the field within a kernel's reach of the point only as far as
    the other data allow, the cut removes a phantom part of a wrong-class prior wherever a
    probe refuted it. With ``inside_only`` only the free points inside the prior's solid
    cut: a probe that passed beside a part of the prior, not through it, refutes nothing
    of it (a ball about it would cut a real sofa foot the probe passed 0.2 from).

    Parameters
    ----------
    prior : callable
        ``prior(points) -> (values (k,), gradients (k, 3))``.
    free_points : (q, 3) float
        Points outside the object.
    contacts : (n, 3) float
    radius : float
        Largest ball radius; 0 returns ``prior`` itself.
    neighbours : int
        Balls considered per query point (the nearest centres).
    inside_only : bool
        Cut only about the free points where ``prior`` is negative.

    Returns
    -------
    callable
        The carved prior, same signature as ``prior``.
    """
    if inside_only and len(free_points):
        free_points = np.asarray(free_points, dtype=float).reshape(-1, 3)
        free_points = free_points[np.asarray(prior(free_points)[0]) < 0]
    cut = free_space_cut(free_points, contacts, radius, neighbours, normals=normals, disk=disk)
    return prior if cut is None else CarvedPrior(prior, cut)


def free_space_cut(free_points, contacts, radius, neighbours=8, keep_within=0.0,
                   normals=None, disk=0.0):
    """The balls :func:`carved_prior` cuts, as a :class:`FreeSpaceCut` (None: no ball);
    points within ``keep_within`` of a contact are never cut. With ``normals`` and a
    ``disk`` radius, a ball reaches no contact's disc either (:func:`disk_distances`,
    each disc at most :func:`disk_radii`)."""
    free_points = np.asarray(free_points, dtype=float).reshape(-1, 3)
    if radius <= 0 or len(free_points) == 0:
        return None
    radii = np.full(len(free_points), float(radius))
    contacts = np.asarray(contacts, dtype=float).reshape(-1, 3)
    tree = cKDTree(contacts) if len(contacts) else None
    if tree is not None:
        if normals is not None and disk > 0:
            normals = np.asarray(normals, dtype=float).reshape(-1, 3)
            discs = disk_radii(contacts, normals, free_points, disk)
            radii = np.minimum(radii, disk_distances(free_points, contacts, normals, discs,
                                                     tree, radius))
        else:
            radii = np.minimum(radii, tree.query(free_points)[0])
    keep = radii > 0
    if not keep.any():
        return None
    kept = (tree, float(keep_within)) if keep_within > 0 and tree is not None else None
    return FreeSpaceCut(free_points[keep], radii[keep], min(neighbours, int(keep.sum())), kept)


DISK_NEIGHBOURS = 16


def disk_distances(points, contacts, normals, disk, tree=None, reach=np.inf):
    """The distance from each of ``points`` (k, 3) to the nearest of the discs of radius
    ``disk`` about ``contacts`` (n, 3) in their tangent planes (unit ``normals``): where
    the surface lies at least, between contacts on a thin wall as much as at them. Only the
    ``DISK_NEIGHBOURS`` nearest contacts within ``reach + disk`` are asked (a disc farther
    lies farther than ``reach``); ``inf`` where none is. Returns (k,) float."""
    tree = cKDTree(contacts) if tree is None else tree
    k = min(DISK_NEIGHBOURS, len(contacts))
    distance, index = tree.query(points, k=k, distance_upper_bound=reach + np.max(disk))
    distance, index = distance.reshape(len(points), k), index.reshape(len(points), k)
    found = index < len(contacts)
    index = np.where(found, index, 0)
    offset = points[:, None, :] - contacts[index]
    along = np.einsum("kjd,kjd->kj", offset, normals[index])
    across = np.sqrt(np.maximum(distance**2 - along**2, 0.0))
    disk = np.broadcast_to(np.asarray(disk, dtype=float), (len(contacts),))
    to_disk = np.hypot(along, np.maximum(across - disk[index], 0.0))
    return np.where(found, to_disk, np.inf).min(axis=1)


def disk_radii(contacts, normals, free_points, disk):
    """Each contact's disc radius, (n,): ``disk``, or less where a free point lies nearer
    across the contact's tangent plane than along its normal (the surface ends there:
    a probe passed between a fork's tines, beyond a wall's rim)."""
    radii = np.full(len(contacts), float(disk))
    if len(free_points) == 0 or disk <= 0:
        return radii
    k = min(DISK_NEIGHBOURS, len(free_points))
    distance, index = cKDTree(free_points).query(contacts, k=k, distance_upper_bound=disk)
    distance, index = distance.reshape(len(contacts), k), index.reshape(len(contacts), k)
    found = index < len(free_points)
    offset = free_points[np.where(found, index, 0)] - contacts[:, None, :]
    along = np.abs(np.einsum("njd,nd->nj", offset, normals))
    across = np.sqrt(np.maximum(np.where(found, distance, 0.0) ** 2 - along**2, 0.0))
    beside = found & (along < across)
    return np.minimum(radii, np.where(beside, across, np.inf).min(axis=1))


class BothCuts:
    """Two cuts of a field's solid applied in turn, as one (a fit's ``cut``): the field
    is the largest of its own and both cuts' balls."""

    def __init__(self, first, second):
        self.first, self.second = first, second

    def __call__(self, points, values, gradients=None):
        self.first(points, values, gradients)
        return self.second(points, values, gradients)


def joined_cut(first, second):
    """``first`` and ``second`` (cuts, or None) as one cut (None: neither)."""
    if first is None or second is None:
        return second if first is None else first
    return BothCuts(first, second)


class CarvedPrior:
    """``prior`` with a :class:`FreeSpaceCut` applied (see :func:`carved_prior`); a
    callable with the prior's signature that pickles."""

    def __init__(self, prior, cut):
        self.prior, self.cut = prior, cut

    def __call__(self, points):
        points = np.atleast_2d(points)
        values, gradients = self.prior(points)
        return self.cut(points, np.array(values, dtype=float),
                        np.array(gradients, dtype=float))


class FreeSpaceCut:
    """Balls of ``radii`` about ``free_points`` removed from a field's solid:
    ``f'(x) = max(f(x), r_i - |x - f_i|)`` over the ``neighbours`` nearest centres, except
    within ``kept = (contacts' tree, distance)`` of a contact (None: everywhere); where
    values tie within ``CUT_TIE`` of the largest radius (a contact lies on the rims of
    the balls it bounds) the gradient is the field's if it ties, else the tied balls'
    normalised mean."""

    def __init__(self, free_points, radii, neighbours, kept=None):
        self.free_points, self.radii = free_points, radii
        self.neighbours = int(neighbours)
        self.tree = cKDTree(free_points)
        self.kept = kept

    def __call__(self, points, values, gradients=None):
        """The cut ``values`` (k,) and, when given, ``gradients`` (k, 3) at ``points``
        (k, 3); the arrays are changed in place and returned."""
        candidates = np.flatnonzero(values < self.radii.max())  # a cut never exceeds its radius
        if self.kept is not None and len(candidates):
            tree, within = self.kept
            near = tree.query(points[candidates], distance_upper_bound=within)[0] <= within
            candidates = candidates[~near]
        if len(candidates) == 0:
            return values, gradients
        distance, index = self._nearest(points[candidates], values[candidates])
        balls = np.append(self.radii, 0.0)[index] - distance  # -inf where none is near
        best = np.argmax(balls, axis=1)
        rows = np.arange(len(candidates))
        cut, centre = balls[rows, best], self.free_points[np.minimum(index[rows, best],
                                                                   len(self.free_points) - 1)]
        before = values[candidates]
        own = None if gradients is None else gradients[candidates]
        wins = cut > before
        changed = candidates[wins]
        values[changed] = cut[wins]
        if gradients is not None:
            offset = points[changed] - centre[wins]
            length = np.linalg.norm(offset, axis=1, keepdims=True)
            gradients[changed] = -offset / np.maximum(length, 1e-12)
            self._tied(points[candidates], balls, cut, index, before, own, gradients,
                       candidates)
        return values, gradients

    def _tied(self, points, balls, cut, index, values, own, gradients, rows):
        """Where the field (``values``, ``own`` gradients at ``points``) or balls
        (``balls``, ``index``: their values and centres there; ``cut`` the largest) tie
        within ``CUT_TIE`` of the largest radius, ``gradients[rows]`` become the field's,
        else the normalised mean of the tied balls'."""
        top = np.maximum(cut, values)
        tolerance = CUT_TIE * self.radii.max()
        tied = balls >= (top - tolerance)[:, None]
        field = values >= top - tolerance
        many = tied.sum(axis=1) + field > 1
        if not many.any():
            return
        centres = self.free_points[np.minimum(index[many], len(self.free_points) - 1)]
        away = centres - points[many][:, None]
        units = away / np.maximum(np.linalg.norm(away, axis=2, keepdims=True), 1e-12)
        total = np.einsum("kn,knd->kd", tied[many].astype(float), units)
        mean = total / np.maximum(np.linalg.norm(total, axis=1, keepdims=True), 1e-12)
        gradients[rows[many]] = np.where(field[many][:, None], own[many], mean)

    def _nearest(self, points, values):
        """Distances and indices (k, neighbours) of the nearest ball centres that could cut
        at ``points`` of prior ``values``; ``inf`` and the index ``len(free_points)`` for
        the rest. A centre farther than ``radius - value`` cannot cut, so the search
        stops there (in a few steps of bound)."""
        reach = self.radii.max() - values
        distance = np.full((len(points), self.neighbours), np.inf)
        index = np.full((len(points), self.neighbours), len(self.free_points))
        bounds = self.radii.max() * np.array([1.0, 2.0, 4.0, 8.0, np.inf])
        step = np.searchsorted(bounds, reach)  # the first bound at or beyond the reach
        for level, bound in enumerate(bounds):
            chosen = step == level
            if chosen.any():
                found = self.tree.query(points[chosen], k=self.neighbours,
                                        distance_upper_bound=bound)
                distance[chosen] = found[0].reshape(chosen.sum(), -1)
                index[chosen] = found[1].reshape(chosen.sum(), -1)
        return distance, index


def contact_balls(contacts, normals, free_points, radius, tolerance=0.0):
    """The solid balls behind the contacts (:class:`ContactFill`; None: no ball).

    Each contact ``c`` with outward normal ``n`` gets the largest ball up to ``radius`` that
    touches ``c' = c - tolerance n`` from inside (centre ``c' - r n``) and holds no other
    contact and no free-space point: the shrinking ball of medial-axis estimation (Ma,
    Bae and Kim 2012). While the point nearest its centre lies inside, the ball shrinks to
    the one through that point ``p``, of radius ``|p - c'|^2 / (2 (c' - p) . n)``. The
    ``tolerance`` (the position noise) keeps a neighbour a little behind the tangent plane
    from shrinking it.

    Parameters
    ----------
    contacts, normals : (n, 3) float, world frame
        Contact positions and outward unit normals.
    free_points : (q, 3) float
        Points outside the object (non-contacts, missed probes' paths).
    radius : float or (n,) float, scene units
        The largest ball (one for all or one a contact); 0 gives no ball.
    tolerance : float, scene units

    Returns
    -------
    ContactFill or None
    """
    contacts = np.asarray(contacts, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    radii = np.broadcast_to(np.asarray(radius, dtype=float), (len(contacts),)).copy()
    if len(contacts) == 0 or not (radii > 0).any():
        return None
    others = np.vstack([contacts, np.asarray(free_points, dtype=float).reshape(-1, 3)])
    tree = cKDTree(others)
    touching = contacts - tolerance * normals
    active = np.arange(len(contacts))
    for _ in range(SHRINK_STEPS):
        distance, index = tree.query(touching[active] - radii[active, None] * normals[active])
        inside = distance < radii[active] * (1 - 1e-9)
        active = active[inside]
        if len(active) == 0:
            break
        offset = touching[active] - others[index[inside]]
        depth = np.einsum("ij,ij->i", offset, normals[active])
        radii[active] = np.einsum("ij,ij->i", offset, offset) / (2 * np.maximum(depth, 1e-300))
    keep = radii > tolerance
    if not keep.any():
        return None
    return ContactFill(touching[keep] - radii[keep, None] * normals[keep], radii[keep])


class ContactFill:
    """Solid balls of ``radii`` about ``centres`` added to a field's solid:
    ``f'(x) = min(f(x), |x - b_i| - r_i)`` over the ``neighbours`` nearest centres."""

    def __init__(self, centres, radii, neighbours=8):
        self.centres, self.radii = centres, radii
        self.neighbours = int(min(neighbours, len(centres)))
        self.tree = cKDTree(centres)

    def __call__(self, points, values, gradients=None):
        """The filled ``values`` (k,) and, when given, ``gradients`` (k, 3) at ``points``
        (k, 3); the arrays are changed in place and returned."""
        candidates = np.flatnonzero(values > -self.radii.max())  # a ball is at least -r
        if len(candidates) == 0:
            return values, gradients
        distance, index = self.tree.query(points[candidates], k=self.neighbours)
        distance, index = distance.reshape(len(candidates), -1), index.reshape(len(candidates), -1)
        filled = distance - self.radii[index]
        best = np.argmin(filled, axis=1)
        rows = np.arange(len(candidates))
        filled, centre = filled[rows, best], self.centres[index[rows, best]]
        wins = filled < values[candidates]
        changed = candidates[wins]
        values[changed] = filled[wins]
        if gradients is not None:
            offset = points[changed] - centre[wins]
            length = np.linalg.norm(offset, axis=1, keepdims=True)
            gradients[changed] = offset / np.maximum(length, 1e-12)
        return values, gradients


def filled_prior(prior, fill):
    """``prior`` with the :class:`ContactFill` ``fill`` added to its solid (``prior`` itself
    when ``fill`` is None)."""
    return prior if fill is None else CarvedPrior(prior, fill)
