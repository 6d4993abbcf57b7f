"""Where a session touches next and when it stops: the paper's targets (the GPIS's largest
variance while novel, the MAP surface's farthest point from the contacts while known) and
the DHD stop, with the extensions beyond the paper behind the same entry point
(:meth:`Planner._stop_and_target`): coverage of a novel object's prior, check lines through
the gaps nothing was observed near, a frontier along parts nothing predicted, given-up
targets and repeated touches.

A mixin of :class:`~.loop.Session`: it reads the session's filter, parameters in scene
units (``_p``, ``_unit``) and exploration state (``state``).
"""

import functools

import numpy as np
from scipy.spatial import cKDTree

from ..decision import UNDECIDED, decide, disagreement_target
from ..exploration import (clearest_direction, farthest_vertex, next_sweep_direction,
                           path_until, raster_path, variance_target, widest_gap)
from ..meshes import bare_mesh
from ..metrics import directed_hausdorff
from ..observations import Contact
from ..sdf import normalise_rows
from .fields import BelowTangentPlane, ValueOf, free_approach, free_space_points, thin_points
from .state import Aim, Check

# Lengths in size units (a sixth of the object's longest side; see ..params):
SWEEP_RADIUS = 10.0  # a check line runs this far on either side of its point
SWEPT_SPACING = 0.25  # samples of the paths the sensor swept, for the gaps of check lines
MAX_RASTER_RADIUS = 1.0  # a check sweeps at most the cube inside this ball about its gap
CONTACT_PRECISION = 0.01  # without a simulator: contacts closer than this are one touch
MISSED_SPACING = 0.1  # missed probes' paths sampled this far apart for the decision
TELL_SPACING = 0.5  # of contact_spacing: telling touches kept this far from contacts


class Planner:
    """Targets, checks, frontier and the stop rule of a session (see the module)."""

    def _decide(self, belief):
        """The step's :class:`~..decision.Decision` (beyond the paper; not assessed while
        the object is judged novel)."""
        if belief.novel:
            self.state.hypotheses = ()
            return UNDECIDED
        p, noise = self._p, self.sensor_noise[0]
        decision = decide(self.filter, belief, p.decision_confidence,
                          floor=float(np.hypot(p.decision_floor, noise)),
                          same_mode=max(p.decision_same_mode, 2 * noise),
                          carried=self.state.hypotheses,
                          free_space=segment_points(self.state.missed, MISSED_SPACING * self._unit))
        self.state.hypotheses = decision.hypotheses[:1] + decision.rivals
        return decision

    def _stop_and_target(self, state, model, rotation, translation, map_vertices, recon,
                         contacts, decision=UNDECIDED):
        """The DHD of the estimate, whether to stop, whether the object is decided, and the
        next target (kept in ``self.state.target``); returns ``(dhd, terminated, decided)``.

        A decision also needs contacts all around the MAP surface (its DHD within
        ``decision_cover``) and checks just outside it (:meth:`_decided`): a wrong pose or
        class can fit contacts on one part within the noise (a novel statue's trident
        fitted a knife), and nothing else would refute it."""
        surface = recon.vertices if recon is not None and not recon.empty else map_vertices
        reachable = self._reachable(surface)
        dhd = directed_hausdorff(surface[reachable], contacts)
        prior_open, prior_dhd = None, 0.0
        if recon is not None and self._p.cover_prior:
            # The prior is cut out around missed probes as far as the carve reaches.
            prior_open = self._reachable(map_vertices, max(self._p.contact_spacing,
                                                           self._p.gpis_carve_radius))
            prior_dhd = directed_hausdorff(map_vertices[prior_open], contacts)
        cap = self._p.max_steps_novel if state.novel else self._p.max_steps_known
        covered = max(dhd, prior_dhd) <= self._p.eps
        exploring = state.novel and self.strategy != "rrt"
        frontier = exploring and bool(self.state.frontier)
        checking = (covered and exploring and not frontier
                    and self.state.checks_passed < self._p.check_lines)
        decided, confirm = self._decided(decision, dhd)
        # Rivals are aimed at (and the DHD stop waits) only while the MAP fits within the
        # noise (else the object is none of them) and for decision_patience steps at most.
        rivals = (self._p.decision_targets and not state.novel and not decided
                  and not confirm and decision.fits and len(decision.rivals) > 0
                  and self.state.telling_steps < self._p.decision_patience)
        # The DHD stop waits for the decision's checks too: they are a step or two, and a
        # thin object is covered before they are swept (an 18 cm pencil in 15 touches).
        terminated = bool((covered and not checking and not frontier and not rivals
                           and not confirm)
                          or (self._p.stop_at_decision and decided)
                          or self.step_count + 1 >= cap)
        self.state.check, self.state.frontier_target = None, False
        self.state.telling_apart = self.state.confirming = False
        if recon is not None and not recon.empty:
            outside = recon.fit.mean_value
        else:
            outside = ValueOf(self._prior(model, rotation, translation))
        if terminated:
            self.state.target = None
        elif frontier:
            position, normal = self.state.frontier.pop(0)
            # Probe the full depth across the tangent plane (the estimate has no surface
            # here), but approach short of what the estimate does predict.
            self.state.target = Aim(position, normal, BelowTangentPlane(position, normal, outside))
            self.state.frontier_target = True
        elif checking:
            self.state.target = None
            self.state.check = self._plan_check_line(surface, contacts, outside)
        elif confirm:
            self.state.target = None
            self.state.check = self._plan_check_line(map_vertices, contacts, outside)
            self.state.confirming = True
        elif rivals and (aim := self._telling_apart(decision, contacts)) is not None:
            self.state.target = aim
        elif dhd <= self._p.eps < prior_dhd:
            # The reconstruction is covered, but part of the prior it came from is neither
            # touched nor refuted: the object may extend there.
            self.state.target = self._next_target(map_vertices, prior_open, None, model,
                                                  rotation, translation, contacts)
        else:
            self.state.target = self._next_target(surface, reachable, recon, model,
                                                  rotation, translation, contacts)
        return max(dhd, prior_dhd), terminated, decided

    def _decided(self, decision, dhd):
        """``(decided, confirm)``: the step's decision needs contacts all around the MAP
        (``decision_cover``) and, exploring with ``decision_targets``, ``decision_checks``
        sweeps just outside it that touched nothing it does not predict (``confirm``: plan
        the next); a MAP that no longer qualifies starts the count again."""
        ready = decision.decided and dhd <= self._p.decision_cover
        if not ready:
            self.state.decision_checks = 0
        if not self._p.decision_targets:
            return ready, False
        confirm = ready and self.state.decision_checks < self._p.decision_checks
        return ready and not confirm, confirm

    def _telling_apart(self, decision, contacts):
        """The :class:`Aim` where the plausible hypotheses disagree most (None: nowhere)."""
        hypotheses = (decision.hypotheses[0],) + decision.rivals
        # Touches are spread over the parts that differ (half the contact spacing apart):
        # touched again and again at one spot, a rival shifts a little and absorbs it.
        refuted = np.vstack([np.reshape(self.state.given_up, (-1, 3)), self.state.free_space])
        spread = max(2 * self.sensor_noise[0], self._p.decision_floor,
                     TELL_SPACING * self._p.contact_spacing)
        found = disagreement_target(
            self.filter.bank, hypotheses, self._p.probe_depth,
            avoid=((contacts, spread), (np.reshape(self.state.told, (-1, 3)), spread),
                   (refuted, self._p.contact_spacing)))
        if found is None:
            return None
        position, normal, owner = found
        hypothesis = hypotheses[owner]
        prior = self.filter.models[hypothesis.class_index]
        estimate = ValueOf(self._prior(prior, hypothesis.rotation, hypothesis.translation))
        self.state.telling_apart = True
        self.state.telling_steps += 1
        self.state.told.append(position)
        return Aim(position, normalise_rows(normal[None])[0], estimate)

    def _next_target(self, surface, reachable, recon, model, rotation, translation, contacts):
        """The :class:`Aim` of the next step: the novel or the known rule of
        :mod:`.exploration`, with the estimate whose inside the probe depth is taken from."""
        if recon is not None and not recon.empty:
            index = variance_target(recon.vertices, recon.variance, recon.subset, reachable,
                                    contacts, self._p.eps if self._p.target_uncovered
                                    else None)
            target = recon.vertices[index]
            _, gradient = recon.fit.mean(target[None])
            return Aim(target, normalise_rows(gradient)[0], recon.fit.mean_value)
        index = np.flatnonzero(reachable)[farthest_vertex(surface[reachable], contacts)]
        normal = vertex_normals(model)[index] @ rotation.T
        estimate = ValueOf(self._prior(model, rotation, translation))
        return Aim(surface[index], normalise_rows(normal[None])[0], estimate)

    def _reachable(self, vertices, radius=None):
        """Mask of the vertices that exploration may still have to visit: away from every
        target the sensor failed to reach and from the free space that missed probes
        passed through (within ``radius``, default ``contact_spacing``).

        The DHD and the next target leave the others out (all vertices count if none is
        left): probing there again cannot change the estimate, so the trial would only run
        to its step cap.
        """
        refuted = np.vstack([np.reshape(self.state.given_up, (-1, 3)), self.state.free_space])
        if len(refuted) == 0:
            return np.ones(len(vertices), bool)
        radius = self._p.contact_spacing if radius is None else radius
        far = cKDTree(refuted).query(vertices)[0] >= radius
        return far if far.any() else np.ones(len(vertices), bool)

    def _plan_check_line(self, estimate, contacts, outside=None):
        """The next :class:`Check`: the estimate's vertices, its point, its direction and the
        path to sweep.

        ``check_line_aim = "gap"`` (with ``outside``, positive outside the estimate): a
        lattice through the widest unobserved gap, alternately inside the contacts' hull
        and in a shell of ``2 eps`` around the estimate, in from a direction with a clear
        way (:func:`~.exploration.widest_gap`, :func:`~.exploration.raster_path`);
        ``"gap-weakest"``: every third check sweeps the same lattice about the estimate's
        vertex farthest from every contact (:meth:`_weakest_support`), in addition to the
        ``check_lines`` gap checks;
        otherwise, or without a gap, a straight line through a random contact moved by
        about ``eps``, from the least used of the spread directions.
        """
        through = None
        kind = self._check_kind(len(self.state.check_directions))
        if kind == "weakest" and outside is not None:
            through, gap = self._weakest_support(estimate, contacts)
        elif kind in ("hull", "shell") and outside is not None:
            explored = np.vstack([contacts, self.filter.noncontact_positions,
                                  self.state.free_space, self.state.swept])
            # Checks alternate between gaps inside the contacts' hull and the shell just
            # outside the estimate (beyond the ends of parts it closes off).
            shell = 2 * self._p.eps if kind == "shell" else 0.0
            through, gap = widest_gap(contacts, explored, estimate, outside, shell=shell,
                                      unit=self._unit)
        if through is None:
            direction = next_sweep_direction(self.state.check_directions, self.rng)
            through = contacts[self.rng.integers(len(contacts))] + self.rng.normal(
                0.0, self._p.eps, size=3)
            path = np.stack([through + SWEEP_RADIUS * self._unit * direction,
                             through - SWEEP_RADIUS * self._unit * direction])
        else:
            unit = self._unit
            direction = clearest_direction(through, estimate, self.state.check_directions,
                                           reach=SWEEP_RADIUS * unit, unit=unit)
            path = raster_path(through, min(gap, MAX_RASTER_RADIUS * unit), direction,
                               spacing=0.2 * unit, reach=SWEEP_RADIUS * unit)
        self.state.check_directions.append(direction)
        return Check(estimate, through, direction, path)

    def _weakest_support(self, estimate, contacts):
        """The estimate's vertex farthest from every contact (among those exploration may
        still visit) and that distance: where the estimate rests on the fewest touches, so
        the object may lie up to ``eps`` off it unseen (a leg's middle between touched ends).
        """
        reachable = np.flatnonzero(self._reachable(estimate))
        if len(reachable) == 0 or len(contacts) == 0:
            return None, 0.0
        distance = cKDTree(contacts).query(estimate[reachable])[0]
        best = int(np.argmax(distance))
        return estimate[reachable[best]], max(float(distance[best]), self._p.contact_spacing)

    def _check_kind(self, index):
        """What check number ``index`` (0 first) of the session aims at: ``"hull"`` and
        ``"shell"`` gaps in turn, with ``"gap-weakest"`` a ``"weakest"`` support after each
        pair; ``"contact"`` with ``check_line_aim = "contact"``."""
        aim = self._p.check_line_aim
        if aim == "contact":
            return "contact"
        kinds = ("hull", "shell", "weakest") if aim == "gap-weakest" else ("hull", "shell")
        return kinds[index % len(kinds)]

    def _count_check(self, touched):
        """Count the check as passed unless it touched the object farther than
        ``contact_spacing`` from the estimate and from every contact (a part nothing
        predicted: the count restarts and the frontier grows from the touch)."""
        known = [points for points in (self.state.check.estimate, self.filter.contact_positions)
                 if len(points)]
        surprise = isinstance(touched, Contact) and min(
            cKDTree(points).query(touched.position)[0]
            for points in known) > self._new_ground()
        if self.state.confirming:  # a check of a decision: a surprise starts it again
            self.state.decision_checks = 0 if surprise else self.state.decision_checks + 1
            return
        if surprise:
            self.state.checks_passed = 0
            self._grow_frontier(touched)
        elif self._check_kind(len(self.state.check_directions) - 1) != "weakest":
            # A sweep about the weakest support adds to the gap checks, never replaces one.
            self.state.checks_passed += 1

    def _approach_start(self):
        """Where the approach to the current target starts (None without a target, and
        with RRT)."""
        if self.state.target is None or self.strategy == "rrt":
            return None
        position, normal, estimate = self.state.target
        return position + free_approach(estimate, position, normal,
                                        self._p.approach_clearance, self._unit) * normal

    def _record_sweep(self, touched, start=None):
        """Keep samples of the path the sensor swept up to its first touch: the planned
        check's path, else the straight approach from ``start`` (None: nothing to keep).
        Checks need not visit that space again."""
        if self.state.check is not None:
            spacing = SWEPT_SPACING * self._unit
            samples = path_until(self.state.check.path, touched.position, spacing, 0.05 * self._unit)
            self.state.swept = thin_points(np.vstack([self.state.swept, samples]), spacing)
        elif start is not None:
            self.state.swept = free_space_points(self.state.swept, np.stack([start, touched.position]),
                                            SWEPT_SPACING * self._unit)

    def _follow_frontier(self, touched):
        """After a frontier target: a contact on new ground grows the frontier from it."""
        contacts = self.filter.contact_positions
        if (self.state.frontier_target and isinstance(touched, Contact) and len(contacts)
                and cKDTree(contacts).query(touched.position)[0] > self._new_ground()):
            self._grow_frontier(touched)

    def _new_ground(self):
        """How far from the estimate and every contact a touch is on ground nothing
        predicted: ``contact_spacing``, at least ``eps / 2`` (equal at the paper's values;
        with a larger eps the estimate may lie farther off, and a frontier grown eps at a
        time in four directions would tile the surface ever finer)."""
        return max(self._p.contact_spacing, self._p.eps / 2)

    def _grow_frontier(self, contact):
        """Queue targets ``eps`` from a contact on a part that nothing predicted, along
        four tangent directions: following them maps the part out, as a hand runs along a
        rail it bumped into (beyond the paper). Places within :meth:`_new_ground` of a
        contact, a given-up target or a queued target are skipped."""
        normal = normalise_rows(np.asarray(contact.normal, float)[None])[0]
        helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
        first = normalise_rows(np.cross(normal, helper)[None])[0]
        second = np.cross(normal, first)
        for tangent in (first, -first, second, -second):
            point = contact.position + self._p.eps * tangent
            taken = np.vstack([self.filter.contact_positions, contact.position[None],
                               np.reshape(self.state.given_up, (-1, 3)),
                               np.reshape([p for p, _ in self.state.frontier], (-1, 3))])
            if cKDTree(taken).query(point)[0] > self._new_ground():
                self.state.frontier.append((point, normal))

    def _reached(self, observations, contacts):
        """Whether touches made for the proposed target reached it (the rule of
        :func:`~.exploration.enforce_contact`)."""
        if not contacts or (self._repeats_contact(contacts[-1]) and not self.state.telling_apart):
            return False
        if isinstance(observations[0], Contact) or len(self.filter.contact_positions) == 0:
            return True
        distance = cKDTree(self.filter.contact_positions).query(contacts[-1].position)[0]
        return bool(distance >= self._p.contact_spacing)

    def _repeats_contact(self, observation):
        """Whether a contact lands where an earlier one did (within the sensor noise, and at
        least the simulator's contact precision).

        Such a touch taught nothing: something in front of the target (or a crevice the
        probe cannot enter) took it, and aiming at the same target again would repeat it.
        A noiseless sensor does not repeat a touch bit for bit (the approach moves with the
        estimate), so without the precision floor a blocked target was aimed at until the
        step cap (the learned home chair, seed 1005: 110 touches of one spot).
        """
        contacts = self.filter.contact_positions
        if not isinstance(observation, Contact) or len(contacts) == 0:
            return False
        precision = (self.simulator.tolerance if self.simulator is not None
                     else CONTACT_PRECISION * self._filter_unit)
        tolerance = max(4.0 * self.sensor_noise[0], precision)
        return bool(cKDTree(contacts).query(observation.position)[0] <= tolerance)


@functools.lru_cache(maxsize=8)
def vertex_normals(model):
    """A prior's vertex normals, (n, 3), object frame, from a bare copy of its mesh (see
    :func:`~tactile_viz.engine.meshes.bare_mesh`): a long run meets many MAP classes."""
    return bare_mesh(model.mesh).vertex_normals


def segment_points(segments, spacing):
    """Points along each segment, at most ``spacing`` apart, ends included.

    Parameters
    ----------
    segments : (k, 2, 3) float
    spacing : float, > 0

    Returns
    -------
    (m, 3) float
    """
    if len(segments) == 0:
        return np.zeros((0, 3))
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    counts = np.maximum(np.ceil(lengths / spacing).astype(int), 1) + 1
    fractions = np.concatenate([np.linspace(0.0, 1.0, c) for c in counts])
    starts = np.repeat(segments[:, 0], counts, axis=0)
    ends = np.repeat(segments[:, 1], counts, axis=0)
    return starts + fractions[:, None] * (ends - starts)
