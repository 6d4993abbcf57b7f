"""What a step's observations leave in the exploration state besides the belief: the
swept space, the check's count, the given-up target, the frontier, the free space and the
missed probe. One path, :meth:`Bookkeeper.keep_observations`, for a step taken move by
move (:meth:`Bookkeeper.after_moves`) and one given whole (:meth:`~.loop.Session.observe`).

A part of the step (:class:`~.context.Part`), built from its inputs without a session.
"""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..explore.exploration import path_until
from ..explore.observations import Contact
from ..shape.sdf import normalise_rows
from .context import Part
from .fields import free_approach, free_space_points, thin_points
from .planner import beyond_noise, check_kind

# Lengths in size units (a sixth of the object's longest side; see ..params):
SWEPT_SPACING = 0.25  # samples of the paths the sensor swept, for the gaps of check lines
CONTACT_PRECISION = 0.01  # a sensor without a tolerance: contacts closer than this are one touch
# A contact is followed once this many contacts came after it and the estimate still leaves
# it: early on the fit has not caught up with the newest contacts yet.
UNHELD_AFTER = 10


class Bookkeeper(Part):
    """The exploration state's record of observations (see the module).

    Reads its context, the filter and the snapshots; writes ``state``.
    """

    def after_moves(self, kind, done):
        """The paths and observations of a finished procedure, kept
        (:meth:`keep_observations`) with the free space of a missed target probe or check
        and the approach's start."""
        paths, observations = done[:2]  # a target's procedure adds its own "reached"
        missed, spacing = not isinstance(observations[0], Contact), self.p.contact_spacing
        free, start = np.zeros((0, 3)), None
        if kind == "target":
            start = paths[0][0]
            if missed:
                free = free_space_points(free, paths[0], spacing)
            elif self.novel_on_table():
                # The way to the touch is free too (a guarded move on a table goes past
                # a reconstruction's phantom part): its end a radius and a spacing short.
                free = path_until(paths[0], observations[0].position, spacing,
                                  self.scene.tip_radius + spacing)
        elif kind == "check" and missed:
            free = path_until(paths[0], paths[0][-1], spacing, 0.05 * self.unit)
        self.keep_observations(observations, free, start, aimed=kind == "target")

    def novel_on_table(self):
        """Whether the object stands on a table and the last step judged it novel: its
        guarded moves then go on to the table, and their way to a touch is free space."""
        return self.scene.has_table and bool(self.snapshots) and self.snapshots[-1].novel

    def keep_observations(self, observations, free_space, start, aimed):
        """What a step's observations leave besides the belief, the same for a step taken
        move by move and one given whole: the swept space, the check's count, the given-up
        target, the frontier, the free space and the missed probe.

        Parameters
        ----------
        observations : list of Contact or NonContact
            The step's, in time order (at least one).
        free_space : (k, 3) float
            Points the sensor moved through without touching (world frame).
        start : (3,) float or None
            Where the approach to the target began: the way to its first touch is swept
            (None: nothing to keep; after a check its path is).
        aimed : bool
            Whether the step reached for ``state.target`` (not after a check). Move by
            move only a target's procedure does; a step given whole reached for any
            target there is (with RRT, too).
        """
        state, first = self.state, observations[0]
        self._record_sweep(first, start)
        if state.check is not None:
            self.count_check(first)
        elif aimed:
            # A touch beside an earlier one still tells rivals apart (the noise averages).
            if not self._reached(observations):
                state.given_up.append(state.target.position)
            self._follow_frontier(observations[-1])
        before = len(state.free_space)
        if len(free_space):
            state.free_space = thin_points(np.vstack([state.free_space, free_space]),
                                           self.p.contact_spacing)
        if aimed and state.check is None and not isinstance(first, Contact):
            self._record_miss(before)

    def _record_miss(self, before):
        """Keep a missed target probe's path for the decision: from the first to the last
        free-space point the step added (what a recording holds, so a replay keeps the
        same)."""
        added = self.state.free_space[before:]
        if len(added) >= 2:
            self.state.missed = np.vstack([self.state.missed, added[[0, -1]][None]])

    def count_check(self, touched):
        """Count the check as passed unless it touched the object farther than
        ``contact_spacing`` from the estimate and from every contact (a part nothing
        predicted: the count restarts and the frontier grows from the touch)."""
        known = [points for points in (self.state.check.estimate, self.filter.contact_positions)
                 if len(points)]
        surprise = isinstance(touched, Contact) and min(
            cKDTree(points).query(touched.position)[0]
            for points in known) > self.new_ground()
        if self.state.confirming:  # a check of a decision: a surprise starts it again
            self.state.decision_checks = 0 if surprise else self.state.decision_checks + 1
            return
        if surprise:
            self.state.checks_passed = 0
            self.grow_frontier(touched)
        elif check_kind(self.p, len(self.state.check_directions) - 1) != "weakest":
            # A sweep about the weakest support adds to the gap checks, never replaces one.
            self.state.checks_passed += 1

    def approach_start(self):
        """Where the approach to the current target starts (None without a target, and
        with RRT)."""
        if self.state.target is None or self.context.strategy == "rrt":
            return None
        position, normal, estimate = self.state.target
        return position + free_approach(estimate, position, normal,
                                        self.p.approach_clearance, self.unit) * normal

    def _record_sweep(self, touched, start=None):
        """Keep samples of the path the sensor swept up to its first touch: the planned
        check's path, else the straight approach from ``start`` (None: nothing to keep).
        Checks need not visit that space again."""
        if self.state.check is not None:
            spacing = SWEPT_SPACING * self.unit
            samples = path_until(self.state.check.path, touched.position, spacing,
                                 0.05 * self.unit)
            self.state.swept = thin_points(np.vstack([self.state.swept, samples]), spacing)
        elif start is not None:
            self.state.swept = free_space_points(self.state.swept,
                                                 np.stack([start, touched.position]),
                                                 SWEPT_SPACING * self.unit)

    def _follow_frontier(self, touched):
        """After a frontier target: a contact on new ground grows the frontier from it,
        ground neither a contact nor the estimate the target was planned on predicted.
        Where the estimate has come to hold the part the frontier followed, the checks
        test it: grown from every contact beyond the spacing, the frontier tiled the
        whole surface again at half ``eps`` (a 35 cm sofa to the step cap)."""
        contacts = self.filter.contact_positions
        if not (self.state.frontier_target and isinstance(touched, Contact)
                and len(contacts)):
            return
        estimate = self.state.estimate_vertices
        known = [points for points in (contacts, estimate)
                 if points is not None and len(points)]
        if min(cKDTree(points).query(touched.position)[0]
               for points in known) > self.new_ground():
            self.grow_frontier(touched)

    def new_ground(self):
        """How far from the estimate and every contact a touch is on ground nothing
        predicted: ``contact_spacing``, at least ``eps / 2`` (equal at the paper's values;
        with a larger eps the estimate may lie farther off, and a frontier grown eps at a
        time in four directions would tile the surface ever finer) and at least what the
        sensor's noise explains (:func:`~.planner.beyond_noise`: at 2 mm a tenth
        of the touches land 5 mm off, and 48 checks in a row never passed)."""
        return max(self.p.contact_spacing, self.p.eps / 2, beyond_noise(self.p, self.sensor_noise))

    def grow_frontier(self, contact):
        """Queue targets ``eps`` from a contact on a part that nothing predicted, along
        four tangent directions: following them maps the part out, as a hand runs along a
        rail it bumped into (beyond the paper). Places within :meth:`new_ground` of a
        contact, a given-up target or a queued target are skipped."""
        normal = normalise_rows(np.asarray(contact.normal, float)[None])[0]
        for point in tangent_points(contact.position, normal, self.p.eps):
            taken = np.vstack([self.filter.contact_positions, contact.position[None],
                               self._aimed()])
            if cKDTree(taken).query(point)[0] > self.new_ground():
                self.state.frontier.append((point, normal))

    def follow_unheld(self, recon):
        """Queue frontier targets ``contact_spacing`` about each contact that the novel
        estimate ``recon`` (a :class:`~.snapshot.Reconstruction`) still leaves unheld
        :data:`UNHELD_AFTER` contacts after it (:func:`unheld_contacts` within
        :meth:`new_ground`), once a contact (``follow_unheld``, beyond the paper); places
        within half the spacing of another contact, a given-up or a queued target are
        skipped. Under noise a thin part touched once is a lone contact the fit smooths
        away: a 15 cm elephant's trunk, touched 1.4 mm from the truth, lay 8 mm off its
        estimate for the last 220 of 346 touches, and nothing aimed near it."""
        contacts = self.filter.contact_positions
        if not self.p.follow_unheld or len(contacts) == 0 or len(recon.faces) == 0:
            return
        fresh = np.setdiff1d(np.arange(len(contacts) - UNHELD_AFTER), self.state.followed)
        spacing = self.p.contact_spacing
        for index in fresh[unheld_contacts(contacts[fresh], recon.vertices, recon.faces,
                                           self.new_ground(), recon.fit.mean_value)]:
            self.state.followed.append(int(index))
            normal = normalise_rows(self.filter.contact_normals[index][None])[0]
            # The four places lie at least 1.4 spacings apart: none can skip another.
            places = tangent_points(contacts[index], normal, spacing)
            taken = cKDTree(np.vstack([np.delete(contacts, index, axis=0), self._aimed()]))
            for point in places[taken.query(places)[0] > spacing / 2]:
                self.state.frontier.append((point, normal))

    def _aimed(self):
        """The given-up and queued frontier targets, ``(k, 3)``."""
        return np.vstack([np.reshape(self.state.given_up, (-1, 3)),
                          np.reshape([p for p, _ in self.state.frontier], (-1, 3))])

    def _reached(self, observations):
        """Whether the touches of a step that reached for the target reached it: the
        ``reached`` of :func:`~..exploration.enforce_contact_moves`, and the last contact
        does not repeat an earlier one (:meth:`repeats_contact`) unless it tells rivals
        apart."""
        contacts = [o for o in observations if isinstance(o, Contact)]
        if not contacts or (self.repeats_contact(contacts[-1]) and not self.state.telling_apart):
            return False
        if isinstance(observations[0], Contact) or len(self.filter.contact_positions) == 0:
            return True
        distance = cKDTree(self.filter.contact_positions).query(contacts[-1].position)[0]
        return bool(distance >= self.p.contact_spacing)

    def repeats_contact(self, observation):
        """Whether a contact lands where an earlier one did (within the sensor noise, and at
        least the sensor's contact precision, its ``tolerance``).

        Such a touch taught nothing: something in front of the target (or a crevice the
        probe cannot enter) took it, and aiming at the same target again would repeat it.
        A noiseless sensor does not repeat a touch bit for bit (the approach moves with the
        estimate), so without the precision floor a blocked target was aimed at until the
        step cap (the learned home chair, seed 1005: 110 touches of one spot).
        """
        contacts = self.filter.contact_positions
        if not isinstance(observation, Contact) or len(contacts) == 0:
            return False
        precision = (self.context.tolerance if self.context.tolerance is not None
                     else CONTACT_PRECISION * self.context.filter_unit)
        tolerance = max(4.0 * self.sensor_noise[0], precision)
        return bool(cKDTree(contacts).query(observation.position)[0] <= tolerance)


def tangent_points(position, normal, distance):
    """The four points ``distance`` from ``position`` along two perpendicular tangents of
    the unit ``normal`` (both ways), ``(4, 3)``."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = normalise_rows(np.cross(normal, helper)[None])[0]
    second = np.cross(normal, first)
    return position + distance * np.array([first, -first, second, -second])


def unheld_contacts(contacts, vertices, faces, reach, value=None):
    """Mask of the ``contacts`` ((n, 3)) farther than ``reach`` from the triangle surface
    ``(vertices, faces)`` (one frame; all of them without a surface) and, given the
    surface's implicit function ``value`` (points to (k,) values), where it keeps its
    sign within ``reach`` of the contact (:func:`sign_kept`): a thin part between a
    coarse grid's samples has no triangles, yet the fit's zero level passes by its
    contacts (a 20 cm fork's tines at 32 cells: followed, its frontier grew to the step
    cap)."""
    contacts = np.reshape(contacts, (-1, 3))
    if len(faces) == 0:
        return np.ones(len(contacts), bool)
    far = cKDTree(vertices).query(contacts)[0] > reach  # a vertex is at least as far
    if far.any() and value is not None:  # the cheaper test first: it holds a fork's tines
        far[far] = sign_kept(value, contacts[far], reach)
    if far.any():
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        far[far] = trimesh.proximity.closest_point(mesh, contacts[far])[1] > reach
    return far


def sign_kept(value, points, reach, samples=8):
    """Whether the implicit function ``value`` keeps the sign it has at each of ``points``
    ((n, 3)) out to ``reach`` along the 26 directions of a cube's faces, edges and
    corners, ``samples`` places a direction: no zero level within reach (to a
    ``reach / samples`` step across)."""
    steps = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], float) - 1.0
    steps *= (reach / samples) / np.linalg.norm(steps, axis=1, keepdims=True)
    offsets = (np.arange(1, samples + 1)[:, None, None] * steps[None]).reshape(-1, 3)
    around = value((points[:, None, :] + offsets[None]).reshape(-1, 3))
    here = np.sign(value(points))
    return (np.sign(around).reshape(len(points), -1) == here[:, None]).all(axis=1)
