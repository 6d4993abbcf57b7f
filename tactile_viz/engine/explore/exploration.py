"""Active data acquisition: target selection and contact enforcement (paper, III-F).

The sensor contract is a *guarded move*: the sensor moves along a polyline (world frame,
scene units) and stops at the first contact; it answers with the :class:`Contact` (position,
outward normal) or with a :class:`NonContact` at the end of the path. The simulator's
``probe(path)`` is one implementation, a robot's another.

Each procedure is written twice over one body: ``*_moves`` is a generator that yields the
paths of its guarded moves and is sent each move's result (so a session can hand the moves
to a robot one at a time, :meth:`Session.propose` / :meth:`Session.observe`), and the plain
function drives it with a sensor (:func:`drive`). A procedure returns the paths it ran and
the observations they gave: usually one contact, sometimes a non-contact before it.
Lengths are in scene units; the fixed ones inside a function are multiples of ``unit``, the
scene units of a size unit (a sixth of the object's longest side: 1 for the paper's
objects).
"""

import numpy as np
from scipy.spatial import Delaunay, QhullError, cKDTree
from scipy.stats import spearmanr

from ..errors import TactileVizError
from ..shape.sdf import normalise_rows
from .observations import Contact
from .simulator import sample_path

STRATEGIES = ("gpis-dhd", "rrt")
# The first lines' second round is offset up to this many units from the centre: a trial
# places its object up to a size unit off it, and a thin one is missed by lines through
# the middle (a 20 cm fork, 2 of 8 trials of one seed).
WIDE_OFFSET = 1.5
RASTER_HALF = 0.55  # of a lattice's radius: the half-size of the cube it sweeps


def farthest_vertex(vertices, contacts):
    """Index of the vertex farthest from every contact (the DHD target): int."""
    distance = cKDTree(contacts).query(vertices)[0]
    return int(np.argmax(distance))


def weakest_support(vertices, contacts, tried=(), least=0.0, largest=np.inf):
    """The vertex farthest from every contact, and that distance (at least ``least``):
    where an estimate rests on the fewest touches.

    A vertex that a sweep about an earlier one (``tried``) was planned to cover is left
    out: within ``RASTER_HALF`` of that one's distance to the contacts (as they stand now,
    between ``least`` and ``largest``), the half-size of the cube :func:`raster_path`
    sweeps about it. Swept about again, it is reached by the same way in and meets what
    it met before (an elephant's hind leg, on the way to its belly, at 17 of its 71
    checks).

    Parameters
    ----------
    vertices : (v, 3) float
        The estimate's vertices that exploration may still visit.
    contacts : (n, 3) float
    tried : (k, 3) float
        Earlier weakest supports that a sweep was planned about.
    least, largest : float
        The bounds of the distance (scene units): a sweep's lattice radius.

    Returns
    -------
    vertex : (3,) float or None
        None without vertices, contacts, or any left.
    distance : float
    """
    vertices, tried = np.reshape(vertices, (-1, 3)), np.reshape(tried, (-1, 3))
    if len(vertices) == 0 or len(contacts) == 0:
        return None, 0.0
    tree = cKDTree(contacts)
    distance = tree.query(vertices)[0]
    if len(tried):
        radii = RASTER_HALF * np.clip(tree.query(tried)[0], least, largest)
        left_out = cKDTree(vertices).query_ball_point(tried, radii)
        distance[np.concatenate([np.asarray(i, dtype=int) for i in left_out])] = -np.inf
    best = int(np.argmax(distance))
    if not np.isfinite(distance[best]):
        return None, 0.0
    return vertices[best], max(float(distance[best]), least)


def variance_target(vertices, subset, variance, reachable, contacts, uncovered_beyond=None,
                    farthest_when_flat=False):
    """Index of the GPIS-DHD target of a novel object: the surface vertex of largest
    posterior variance (paper III-F).

    Parameters
    ----------
    vertices : (v, 3) float
    subset : (k,) int
        The vertices whose variance was evaluated (the candidates).
    variance : (k,) float
        The posterior variance at ``vertices[subset]``.
    reachable : (v,) bool
        Vertices away from given-up targets and missed probes (others only if none is).
    contacts : (n, 3) float
    uncovered_beyond : float, optional
        Beyond the paper: prefer vertices farther than this from every contact.
    farthest_when_flat : bool
        Beyond the paper: where the variance does not grow away from the contacts
        (:func:`grows_away`), the candidate farthest from every contact.

    Returns
    -------
    int
    """
    score = np.asarray(variance, dtype=float)
    distance = cKDTree(contacts).query(vertices[subset])[0]
    if farthest_when_flat and not grows_away(score, distance):
        score = np.zeros(len(score))  # every candidate ties: the farthest is taken
    uncovered = distance > (-1.0 if uncovered_beyond is None else uncovered_beyond)
    for usable in (reachable[subset] & uncovered, reachable[subset]):
        if usable.any():
            score = np.where(usable, score, -np.inf)
            break
    # Beyond a compact kernel's support the variance is the prior's everywhere: the tie goes
    # to the vertex farthest from the contacts.
    best = score >= score.max() - 1e-9 * abs(score.max())
    return int(subset[int(np.argmax(np.where(best, distance, -np.inf)))])


def grows_away(variance, distance):
    """Whether the variance at the candidates grows with their distance to the contacts
    (a positive rank correlation).

    It does while the GPIS's fitted scale dominates its observation noise. Once the data
    agree with the prior so well that the scale falls to the noise's order (a 10 cm ball
    against a superquadric prior, after about 40 touches), the largest variance lies
    beside the contacts (rank correlation -0.7 at 100 touches) and the paper's target
    lands 0.3-2.4 mm from one: 200 touches left that ball 18 mm off its nearest contact.
    """
    variance, distance = np.asarray(variance, float), np.asarray(distance, float)
    if len(variance) < 3 or np.ptp(variance) == 0 or np.ptp(distance) == 0:
        return len(variance) < 3
    return bool(spearmanr(variance, distance)[0] > 0)


def drive(moves, sensor):
    """Run a procedure of guarded moves (a ``*_moves`` generator) with ``sensor``, whose
    ``probe(path)`` carries out one move; returns the procedure's result."""
    try:
        path = next(moves)
        while True:
            path = moves.send(sensor.probe(path))
    except StopIteration as done:
        return done.value


def first_contact_moves(centre, rng, radius=10.0, attempts=50, unit=1.0):
    """The random first touch: straight lines through the workspace from random directions
    (``radius`` on either side of ``centre``, offset up to ``unit / 2``), then, if
    ``attempts`` of them touch nothing, as many offset up to ``WIDE_OFFSET`` units: a thin
    object (a fork's 2 mm tines and handle) a size unit off the centre can slip between
    50 lines through the middle.

    Yields the lines; returns ``(paths, observations)``: non-contacts for lines that
    missed, then the contact.
    """
    paths, observations = [], []
    for reach in (0.5, WIDE_OFFSET):
        for _ in range(attempts):
            direction = normalise_rows(rng.normal(size=(1, 3)))[0]
            offset = rng.uniform(-reach, reach, size=3) * unit
            path = np.stack([centre + offset + radius * direction,
                             centre + offset - radius * direction])
            observation = yield path
            paths.append(path)
            observations.append(observation)
            if isinstance(observation, Contact):
                return paths, observations
    where = "the origin" if float(np.linalg.norm(centre)) == 0 else "the workspace's centre"
    raise TactileVizError(
        f"no contact after {2 * attempts} random lines through the workspace, the first "
        f"{attempts} passing within {0.5 * np.sqrt(3) * unit:.3g} of {where} and the rest "
        f"within {WIDE_OFFSET * np.sqrt(3) * unit:.3g}, as the priors' size sets it: is "
        "the object there, and of about the priors' size?")


def lines_until_contact(line, attempts, what):
    """Yield ``line()`` paths until one touches (at most ``attempts``); returns
    ``(paths, observations)``: the misses, then the contact. ``what`` ends the error's
    sentence when none touches."""
    paths, observations = [], []
    for _ in range(attempts):
        path = line()
        observation = yield path
        paths.append(path)
        observations.append(observation)
        if isinstance(observation, Contact):
            return paths, observations
    raise TactileVizError(f"no contact after {attempts} {what}")


def first_contact(simulator, centre, rng, radius=10.0, attempts=50, unit=1.0):
    """:func:`first_contact_moves` carried out by ``simulator``."""
    return drive(first_contact_moves(centre, rng, radius, attempts, unit), simulator)


def sweep_directions(count):
    """``count`` nearly evenly spread unit vectors (a Fibonacci sphere): (count, 3) float."""
    index = np.arange(count) + 0.5
    height = 1.0 - 2.0 * index / count
    angle = np.pi * (1.0 + np.sqrt(5.0)) * index
    ring = np.sqrt(1.0 - height**2)
    return np.column_stack([ring * np.cos(angle), ring * np.sin(angle), height])


def next_sweep_direction(used, rng, count=64):
    """The direction of the next check line: the one of ``count`` spread directions farthest
    in angle from every direction in ``used`` ((k, 3); a random one when k = 0)."""
    candidates = sweep_directions(count)
    used = np.reshape(used, (-1, 3))
    if len(used) == 0:
        return candidates[rng.integers(count)]
    return candidates[int(np.argmin((candidates @ used.T).max(axis=1)))]


def widest_gap(contacts, explored, surface, outside, margin=None, shell=0.6, max_points=8000,
               unit=1.0, observed_only=False):
    """The point inside the contacts' convex hull or in a shell just outside the estimated
    surface that lies farthest from everything observed and (but for a shell point with
    ``observed_only``) from the estimated surface: where a part that nothing predicted
    could still hide (between touched parts, or beyond the end of a part that the
    estimate closes off).

    Parameters
    ----------
    contacts : (n, 3) float
    explored : (m, 3) float
        Points known to be free or touched (contacts, non-contacts, swept paths).
    surface : (v, 3) float
        Vertices of the estimated surface.
    outside : callable
        ``(k, 3) -> (k,)`` positive outside the estimate (its signed distance or GPIS mean).
    margin : float, optional
        Points nearer than this to the estimated surface are not candidates (default
        ``0.3 unit``).
    shell : float
        Points up to this far from the estimated surface are candidates outside the hull
        (0: the hull alone).
    max_points : int
        Grid points over the bounding box at most.
    observed_only : bool
        A shell point's width is its distance to ``explored`` alone: the estimated surface
        is no observation, and a part just beside it (a mug's handle 25 mm off the
        estimate of its body) was never wider than the shell's far rim.

    Returns
    -------
    point : (3,) float or None
        None when no grid point is a candidate.
    gap : float
        Its distance to the nearest observed point or surface vertex (0 without one).
    """
    margin = 0.3 * unit if margin is None else margin
    everything = np.vstack([contacts, surface]) if shell > 0 else contacts
    low, high = everything.min(axis=0) - shell, everything.max(axis=0) + shell
    spacing = max(float(np.prod(high - low) / max_points) ** (1 / 3), 0.05 * unit)
    axes = [np.arange(a, b + spacing / 2, spacing) for a, b in zip(low, high)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    try:
        in_hull = Delaunay(contacts).find_simplex(grid) >= 0
    except (QhullError, ValueError):  # fewer than 4 contacts, or all in a plane
        in_hull = np.zeros(len(grid), bool)
    distance = np.full(len(grid), np.inf)
    hull = in_hull.copy()
    tree = cKDTree(surface) if len(surface) else None
    if tree is not None:
        # Deep inside a closed surface a nearest vertex is slow to find, and such a node
        # is no gap: distances beyond the shell and the margin are found for the nodes
        # left outside the estimate alone.
        distance = tree.query(grid, distance_upper_bound=1.01 * max(shell, margin))[0]
        if shell > 0:
            in_hull |= distance <= shell
    keep = in_hull & (distance > margin)
    grid, distance, hull = grid[keep], distance[keep], hull[keep]
    if len(grid):
        free = outside(grid) > 0
        grid, distance, hull = grid[free], distance[free], hull[free]
    if len(grid) == 0:
        return None, 0.0
    if tree is not None:
        far = ~np.isfinite(distance)
        distance[far] = tree.query(grid[far])[0]
        if observed_only:
            distance = np.where(hull, distance, np.inf)
    if len(explored):
        distance = np.minimum(distance, cKDTree(explored).query(grid)[0])
    best = int(np.argmax(distance))
    return grid[best], float(distance[best]) if np.isfinite(distance[best]) else 0.0


def clearest_direction(through, surface, used=(), count=64, reach=10.0, wanted=0.5, unit=1.0):
    """Of ``count`` spread directions, one along which a line comes in to ``through``
    from ``reach`` away without passing within ``wanted unit`` of the estimated surface
    (the least used of those, else the clearest): a line that can reach the point.

    Returns
    -------
    (3,) float
    """
    candidates = sweep_directions(count)
    distances = np.linspace(0.3 * unit, reach, 40)
    wanted = wanted * unit
    samples = through + distances[None, :, None] * candidates[:, None, :]
    clearance = np.full(count, np.inf)
    if len(surface):
        clearance = cKDTree(surface).query(samples.reshape(-1, 3))[0].reshape(count, -1).min(1)
    used = np.reshape(used, (-1, 3))
    novelty = -(candidates @ used.T).max(axis=1) if len(used) else np.zeros(count)
    return candidates[int(np.argmax(np.minimum(clearance, wanted) + 1e-3 * novelty))]


def inward(point, surface, radius, margin=0.3, unit=1.0):
    """``point`` moved toward its nearest vertex of the estimated ``surface`` until the
    cube a :func:`raster_path` of ``radius`` sweeps about it reaches in to ``margin unit``
    of the surface (unmoved when it already does): a gap on a shell's far rim is swept
    together with the band beside the estimate, which any part the estimate misses
    crosses (an ear's tip 1.4 eps beyond it, never reaching the rim).

    Parameters
    ----------
    point : (3,) float
        A gap in the shell outside the estimate (:func:`widest_gap`).
    surface : (v, 3) float
        Vertices of the estimated surface.
    radius : float
        The lattice's ball (its cube's half-size is :data:`RASTER_HALF` of it).

    Returns
    -------
    (3,) float
    """
    point = np.asarray(point, dtype=float)
    if len(surface) == 0:
        return point
    distance, index = cKDTree(surface).query(point)
    wanted = margin * unit + RASTER_HALF * radius
    if distance <= wanted:
        return point
    return surface[index] + (point - surface[index]) * (wanted / distance)


def raster_path(centre, radius, direction, spacing=0.2, reach=10.0):
    """A sweep of the free space around a gap: in along ``-direction`` from ``reach``
    away, then along rows ``spacing`` apart in each of three perpendicular directions
    through the cube of half-size ``RASTER_HALF radius`` about ``centre`` (inside the ball of
    ``radius``): a lattice that any bar crossing the cube meets if it is thicker than
    ``spacing``, whatever its direction.

    Returns
    -------
    (k, 3) float
        The waypoints, the first ``reach`` outside ``centre``.
    """
    direction = normalise_rows(np.asarray(direction, float)[None])[0]
    helper = np.eye(3)[int(np.argmin(np.abs(direction)))]
    across = normalise_rows(np.cross(direction, helper)[None])[0]
    up = np.cross(direction, across)
    half = max(RASTER_HALF * radius, spacing / 2)
    offsets = np.linspace(-half, half, max(2, int(np.ceil(2 * half / spacing)) + 1))
    waypoints = [centre + reach * direction]
    row = 0
    for along, first, second in ((across, direction, up), (up, direction, across),
                                 (direction, across, up)):
        for a in offsets[::-1]:
            for b in offsets:
                ends = (-half, half) if row % 2 == 0 else (half, -half)
                base = centre + a * first + b * second
                waypoints += [base + ends[0] * along, base + ends[1] * along]
                row += 1
    return np.array(waypoints)


def path_until(path, point, spacing, tolerance=0.05):
    """Samples ``spacing`` apart of the polyline ``path`` up to its first pass within
    ``tolerance`` of ``point`` (where the sensor touched), all of it if it never does.

    Returns
    -------
    (k, 3) float
    """
    fine = sample_path(path, tolerance / 2)  # tolerance: scene units
    near = np.flatnonzero(np.linalg.norm(fine - point, axis=1) <= tolerance)
    if len(near):
        fine = fine[:max(near[0], 1)]
    keep = np.unique(np.floor(np.cumsum(np.r_[0.0, np.linalg.norm(np.diff(fine, axis=0),
                                                                  axis=1)]) / spacing),
                     return_index=True)[1]
    return fine[keep]


def sweep_line(simulator, through, direction, radius=10.0):
    """A straight line along ``direction`` through the point ``through``, from ``radius``
    outside it: the first thing it touches is recorded.

    It checks an estimate that looks covered: a contact far from the estimate and from
    every earlier contact means part of the object was never predicted.

    Returns
    -------
    paths : [(2, 3) float]
    observations : [Contact or NonContact]
    """
    path = np.stack([through + radius * direction, through - radius * direction])
    return [path], [simulator.probe(path)]


def free_approach(estimate, target, normal, longest, unit=1.0, samples=32):
    """How far outside ``target`` to start the approach along ``normal``: ``longest``, or
    less where the estimate predicts the object on the way (the approach then starts a
    sample short of it), but at least ``shortest = 0.5 unit``.

    A long approach meets parts of the object that the estimate does not predict; the
    ones it predicts are not passed through.
    """
    shortest = 0.5 * unit
    if longest <= shortest:
        return float(longest)
    distances = np.linspace(shortest, longest, samples)
    inside = np.flatnonzero(estimate(target + distances[:, None] * normal) < 0)
    if len(inside) == 0:
        return float(longest)
    return float(max(shortest, distances[max(inside[0] - 1, 0)]))


def enforce_contact(simulator, target, normal, contacts, contact_normals, depth=1.0,
                    clearance=0.5, follow_step=0.1, spacing=0.3, max_follow=3.0, anchors=1):
    """:func:`enforce_contact_moves` carried out by ``simulator`` (the way back ends two of
    its steps inside the anchor)."""
    return drive(enforce_contact_moves(target, normal, contacts, contact_normals, depth,
                                       clearance, follow_step, spacing, max_follow,
                                       2 * simulator.step, anchors), simulator)


def enforce_contact_moves(target, normal, contacts, contact_normals, depth=1.0,
                          clearance=0.5, follow_step=0.1, spacing=0.3, max_follow=3.0,
                          back_depth=0.04, anchors=1):
    """Reach for a target as in the paper's figure; yields the guarded moves, returns what
    was touched.

    The sensor moves from just outside ``target`` inward along ``-normal`` up to ``depth``.
    A miss is recorded as a non-contact; the sensor then moves from the probe's end toward
    the nearest contact (a contact on the way counts; touching nothing, toward the next
    nearest, up to ``anchors`` contacts) and from wherever it touched follows
    the surface in small in-contact steps toward the target, until it stands at least
    ``spacing`` from every earlier contact. That contact is recorded. When the way back
    touches nothing, only the miss is recorded (the target counts as not reached).

    Parameters
    ----------
    target, normal : (3,) float, world frame
        The target and the estimated outward normal there.
    contacts, contact_normals : (n, 3) float
        Earlier contacts (n >= 1).
    depth, clearance : float
        How far inside and outside the target the first probe runs.
    follow_step : float
        Length of one surface-following step.
    spacing : float
        A contact this far from every earlier one is new; following stops there.
    max_follow : float
        Longest surface path before giving up.
    back_depth : float
        How far inside the nearest contact the way back to it ends.
    anchors : int
        Contacts the way back tries in turn (the paper: the nearest only).

    Returns
    -------
    paths : list of (k, 3) arrays
    observations : list of Contact / NonContact
        ``[contact]`` on a hit, else ``[non-contact, contact]`` (``[non-contact]`` when the
        way back found no contact).
    reached : bool
        False when the procedure ended within ``spacing`` of an earlier contact: the target
        is out of the sensor's reach from here.
    """
    path = np.stack([target + clearance * normal, target - depth * normal])
    observation = yield path
    if isinstance(observation, Contact):
        return [path], [observation], True
    tree = cKDTree(contacts)
    paths, touched = [path], None
    for nearest in np.atleast_1d(tree.query(path[-1], k=min(anchors, len(contacts)))[1]):
        anchor, anchor_normal = contacts[nearest], contact_normals[nearest]
        back = np.stack([paths[-1][-1], anchor, anchor - back_depth * anchor_normal])
        touched = yield back
        paths.append(back)
        if isinstance(touched, Contact):
            break
    if not isinstance(touched, Contact):
        # No anchor is there again: wrong readings, or ones that noise put farther off
        # than the way back reaches. Anchoring on one would record it again.
        return paths, [observation], False
    follow_paths, touched = yield from follow_toward_moves(touched, target, tree, follow_step,
                                                           spacing, max_follow)
    reached = bool(tree.query(touched.position)[0] >= spacing)
    return paths + follow_paths, [observation, touched], reached


def follow_toward(simulator, contact, target, tree, step=0.1, spacing=0.3, max_follow=3.0):
    """:func:`follow_toward_moves` carried out by ``simulator``."""
    return drive(follow_toward_moves(contact, target, tree, step, spacing, max_follow),
                 simulator)


def follow_toward_moves(contact, target, tree, step=0.1, spacing=0.3, max_follow=3.0,
                        path_at=None):
    """Slide along the surface from ``contact`` toward ``target`` in in-contact steps.

    Each step moves ``step`` along the tangent plane toward the target and probes across
    the surface there; off an edge the probe swings back under the last contact, which
    wraps it around the edge. Stops at ``spacing`` from every contact in ``tree``, at the
    target, after ``max_follow`` of path, or when the surface stops leading on.
    ``path_at(moved, normal, position, step)`` gives each step's path instead (a robot's
    scene comes down onto ``moved`` within its cone).

    Returns
    -------
    paths : list of (k, 3) arrays
    contact : Contact
        Where the sensor stopped.
    """
    paths, travelled = [], 0.0
    while travelled < max_follow and tree.query(contact.position)[0] < spacing:
        position, normal = contact.position, normalise_rows(contact.normal[None])[0]
        tangent = target - position
        tangent -= (tangent @ normal) * normal
        length = float(np.linalg.norm(tangent))
        if length < step / 2:
            break
        moved = position + min(step, length) * tangent / length
        path = (swing_path if path_at is None else path_at)(moved, normal, position, step)
        following = yield path
        paths.append(path)
        if not isinstance(following, Contact):
            break
        advance = float(np.linalg.norm(following.position - position))
        if advance < step / 10:
            break
        travelled += advance
        contact = following
    return paths, contact


def swing_path(moved, normal, position, step):
    """A following step's path: across the surface at ``moved``, then back under the last
    contact ``position`` (which wraps it around an edge)."""
    reach = 2 * step
    return np.stack([moved + reach * normal, moved - reach * normal, position - reach * normal])


def follow_surface(simulator, toward, contacts, contact_normals, step=0.3, depth=1.0,
                   clearance=0.5, unit=1.0):
    """:func:`follow_surface_moves` carried out by ``simulator``."""
    return drive(follow_surface_moves(toward, contacts, contact_normals, step, depth,
                                      clearance, unit), simulator)


def follow_surface_moves(toward, contacts, contact_normals, step=0.3, depth=1.0,
                         clearance=0.5, unit=1.0):
    """One surface-following step from the contact nearest ``toward``, along its tangent."""
    nearest = int(cKDTree(contacts).query(toward)[1])
    start, normal = contacts[nearest], contact_normals[nearest]
    tangent = toward - start
    tangent -= (tangent @ normal) * normal
    length = np.linalg.norm(tangent)
    if length < 1e-9:
        tangent = np.cross(normal, [1.0, 0.0, 0.0])
        if np.linalg.norm(tangent) < 1e-6:
            tangent = np.cross(normal, [0.0, 1.0, 0.0])
        length = np.linalg.norm(tangent)
    moved = start + min(step, max(length, 1e-3 * unit)) * tangent / length
    path = np.stack([moved + clearance * normal, moved - depth * normal])
    observation = yield path
    if isinstance(observation, Contact):
        return [path], [observation]
    # Off an edge: come back toward the known contact, which must cross the surface.
    back = np.stack([moved + clearance * normal, start - 0.2 * unit * normal])
    return [path, back], [(yield back)]


def rrt_step(simulator, contacts, contact_normals, workspace, rng, step=0.3, depth=1.0,
             clearance=0.5, unit=1.0):
    """:func:`rrt_moves` carried out by ``simulator``."""
    return drive(rrt_moves(contacts, contact_normals, workspace, rng, step, depth, clearance,
                           unit), simulator)


def rrt_moves(contacts, contact_normals, workspace, rng, step=0.3, depth=1.0, clearance=0.5,
              unit=1.0):
    """RRT-style exploration: a random workspace sample, projected on the tangent plane at
    its nearest contact, and a small surface-constrained step toward it."""
    low, high = workspace
    sample = rng.uniform(low, high)
    return (yield from follow_surface_moves(sample, contacts, contact_normals, step, depth,
                                            clearance, unit))
