"""Where a session touches next and when it stops.

The paper's rules (Algorithm 2; lines and equations as tagged in :mod:`.loop`): the DHD of
the estimate (l.8, eq. 35, :meth:`Planner.coverage`), the stop ``d_H <= eps`` (l.1,
:mod:`.stop`, gathered by :meth:`Planner.stop_test`) and the next target
(:meth:`Planner.choose_target`): the GPIS vertex of largest variance while novel (l.4,
eq. 32), the MAP surface's vertex farthest from the contacts while known (l.6, eq. 36).
Each returns what it decides; the step assigns the
:class:`Plan` into the exploration state (:meth:`~.state.ExplorationState.adopt`).

The extensions beyond the paper sit behind the same three calls; :data:`EXTENSIONS` lists
them with the parameter that switches each off (all are off in the ``paper`` preset):

=================  ===============================================  ==========================
extension          what it does                                     off with
=================  ===============================================  ==========================
given-up targets   targets out of reach, and the free space of      (always on; without a
                   missed probes, leave the DHD and the targets     miss it changes nothing)
missed parts       so do unsupported detached parts missed often    ``missed_parts=0``
box caps           where a GPIS estimate closes at its box beyond   ``gpis_carve_radius=0``
                   eps of every contact, a miss refutes it as far
                   as the carve reaches
prior cover        a novel object's MAP prior must be covered too   ``cover_prior=False``
uncovered target   the variance target among uncovered vertices     ``target_uncovered=False``
noisy target       under noise, the variance target and a check's   ``target_noise_stds=0``
                   surprise beyond the noise of every contact
flat variance      where the variance does not grow away from the   ``target_farthest=False``
                   contacts, the candidate farthest from them
noisy cover        under noise, a known object is covered within    ``cover_noise_stds=0``
                   its noise as well as eps
own size           a novel object much smaller or larger than its   ``own_size_share=0``
                   MAP prior is explored at its own size
check lines        sweeps through unobserved gaps before stopping   ``check_lines=0``
frontier           targets along parts nothing predicted            ``check_lines=0`` (grown
                                                                    by checks' surprises)
unheld contacts    frontier targets about a contact the estimate    ``follow_unheld=False``
                   leaves beyond a surprise's distance
decision           whether a known object is decided; its checks    ``stop_at_decision=False``
                   can stop the session                             (reported always)
telling apart      targets where rival hypotheses disagree          ``decision_targets=False``
confirm checks     sweeps just outside a decided MAP                ``decision_targets=False``
=================  ===============================================  ==========================

A part of the step (:class:`~.context.Part`), built from its inputs without a session.
"""

import functools
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from ..belief.decision import UNDECIDED, Decision, decide
from ..belief.held import held_decision
from ..belief.telling import disagreement_target
from ..explore.exploration import (
    clearest_direction,
    farthest_vertex,
    inward,
    next_sweep_direction,
    raster_path,
    variance_target,
    weakest_support,
    widest_gap,
)
from ..explore.scene_moves import check_line
from ..explore.simulator import segment_points
from ..shape.meshes import bare_mesh
from ..shape.metrics import directed_hausdorff, oriented_samples
from ..shape.sdf import normalise_rows
from .context import Part
from .fields import BelowTangentPlane, MixedSDF, PosedSDF, ValueOf, prior_poses
from .lengths import own_unit
from .refuted import open_estimate, open_parts, open_vertices
from .state import Aim, Check
from .stop import FLICKER_STEPS, Progress, stop_rule

# Lengths in size units (a sixth of the object's longest side; see ..params):
SWEEP_RADIUS = 10.0  # a check line runs this far on either side of its point
MAX_RASTER_RADIUS = 1.0  # a check sweeps at most the cube inside this ball about its gap
SCENE_MARGIN = 0.02  # a scene's tip centre is not asked to come this close to the table
FIRST_CONTACTS = 3  # on a table, known targets stay near the contacts until this many
FIRST_SEARCH = 0.5  # size units: how near
MISSED_SPACING = 0.1  # missed probes' paths sampled this far apart for the decision
TELL_SPACING = 0.5  # of contact_spacing: telling touches kept this far from contacts
MISFIT_STEPS = 5  # steps in a row a known MAP must misfit before the object is novel
MISFIT_HOLD = 10  # after this many steps in a row of misfit, it is assessed only
MISFIT_EVERY = 8  # every this many steps (while the MAP class stays)
ROUND_SHARE = 0.5  # or contacts spanning under this share of its size, settled, misfit

# (extension, the parameter and value that switch it off; None: always on)
EXTENSIONS = (("given-up targets", None), ("missed parts", ("missed_parts", 0)),
              ("box caps", ("gpis_carve_radius", 0.0)),
              ("prior cover", ("cover_prior", False)),
              ("uncovered target", ("target_uncovered", False)),
              ("noisy target", ("target_noise_stds", 0.0)),
              ("flat variance", ("target_farthest", False)),
              ("noisy cover", ("cover_noise_stds", 0.0)),
              ("own size", ("own_size_share", 0.0)),
              ("check lines", ("check_lines", 0)), ("frontier", ("check_lines", 0)),
              ("unheld contacts", ("follow_unheld", False)),
              ("misfit holds the stop", ("misfit_novelty", 0.0)),
              ("decision stop", ("stop_at_decision", False)),
              ("telling apart", ("decision_targets", False)),
              ("confirm checks", ("decision_targets", False)))


class Coverage(NamedTuple):
    """How well the contacts cover the estimate (l.8).

    Attributes
    ----------
    surface : (n, 3) float
        The estimate S*: the GPIS zero level set, else the MAP surface (world frame).
    reachable : (n,) bool
        Its vertices exploration may still visit (:meth:`Planner._reachable`).
    dhd : float
        ``d_H(S*, X_c)`` over those vertices (eq. 35).
    prior_open : (m,) bool or None
        With ``cover_prior`` and a reconstruction: the MAP vertices still to visit.
    prior_dhd : float
        Their DHD (0 without).
    """

    surface: np.ndarray
    reachable: np.ndarray
    dhd: float
    prior_open: Any
    prior_dhd: float

    @property
    def value(self):
        """The DHD a snapshot reports and the stop compares with ``eps``."""
        return max(self.dhd, self.prior_dhd)


@dataclass(frozen=True)
class Plan:
    """What a step decided: the next target or check and the stop.

    Attributes
    ----------
    target : Aim or None
        Where the next step reaches (None: stopped, or a check).
    check : Check or None
        The check the next step sweeps.
    frontier : bool
        ``target`` is the head of the frontier queue (taken off it).
    telling_apart, confirming : bool
        ``target`` tells rival hypotheses apart; ``check`` confirms a decision.
    dhd : float
        ``Coverage.value``.
    terminated, decided : bool
    decision_checks : int
        The confirm checks passed so far (restarted when the MAP no longer qualifies).
    """

    target: Any
    check: Any
    dhd: float
    terminated: bool
    decided: bool
    decision_checks: int
    frontier: bool = False
    telling_apart: bool = False
    confirming: bool = False


class Planner(Part):
    """Targets, checks, frontier and the stop rule of a session (see the module).

    Built from a :class:`~.context.StepContext`, the filter, the exploration state, the
    session's generator and its snapshots (:class:`~.context.Part`). It writes nothing:
    the step adopts the :class:`~..belief.decision.Decision`, the misfit count and the
    :class:`Plan` into the exploration state.
    """

    def decide(self, belief):
        """The step's :class:`~..decision.Decision` (beyond the paper; not assessed while
        the object is judged novel); while the MAP keeps misfitting (the misfit count runs)
        searched first on a spread of the contacts (``decision_contacts``), and once it
        has misfitted long, held between assessments (:meth:`_misfit_held`)."""
        if belief.novel:
            return UNDECIDED
        if self._misfit_held(belief):
            # What the last decision weighed goes on to the next; fit_p 0: still a misfit.
            return Decision(False, 0.0, tuple(self.state.hypotheses), fit_p=0.0,
                            refined=self.state.decision_refined)
        p, noise = self.p, self.sensor_noise[0]
        floor = float(np.hypot(p.decision_floor, noise))
        free_space = segment_points(self.state.missed, MISSED_SPACING * self.unit)
        localisation = p.decision_floor if p.misfit_novelty > 0 else None
        if p.decision_hold and self.state.decided and self.state.hypotheses:
            held = held_decision(self.filter, belief, self.state.hypotheses[0],
                                 p.decision_confidence, floor, free_space,
                                 self.sensor_noise[1], p.decision_normals, localisation,
                                 p.decision_normals_p)
            if held is not None:
                return held
        return decide(self.filter, belief, p.decision_confidence, floor=floor,
                      same_mode=max(p.decision_same_mode, 2 * noise),
                      carried=self.state.hypotheses, free_space=free_space,
                      pose_tolerance=p.decision_pose_error,
                      normal_noise_deg=self.sensor_noise[1],
                      refined=self.state.decision_refined, refresh=p.decision_refresh,
                      budget=p.decision_budget, normals=p.decision_normals,
                      any_class=p.decision_any_class,
                      spread=p.decision_contacts if self.state.misfit_steps else 0,
                      localisation=localisation, least_turn_p=p.decision_normals_p)

    def _misfit_held(self, belief):
        """Whether the step holds the misfit it would assess: the MAP class of the last
        step has misfitted for :data:`MISFIT_HOLD` steps in a row or more, what the last
        decision weighed is carried (with nothing carried the step is assessed), and the
        step is not one of every :data:`MISFIT_EVERY`. A misfitting
        look-alike's decision searches every step's poses afresh: an 8 cm cup judged novel
        against a 10 cm mug at 2 mm noise spent 60 s of its 106 s deciding, 0.45 s each
        fourth touch."""
        steps, last = self.state.misfit_steps, self.snapshots[-1] if self.snapshots else None
        return (steps >= MISFIT_HOLD and steps % MISFIT_EVERY != 0 and last is not None
                and last.map_class == belief.map_class and bool(self.state.hypotheses))

    def misfits(self, belief, decision):
        """Whether an object the filter judges known is novel after all (beyond the paper):
        its MAP's refined residuals fail the chi-squared test (``decision.fit_p`` below
        ``misfit_novelty``), or of their means by place or their stretch
        (``decision.group_p``, :mod:`~..belief.grouped`), for ``MISFIT_STEPS`` steps in a
        row with contacts all around it (the last DHD within ``decision_cover``) and the
        same MAP class, and stay novel until the fit passes at ``decision_confidence``.
        The paper's test passes a look-alike of equal size that misfits by a few percent
        of the size everywhere (its ``sigma_d`` is 8% of the size); the decision's test
        asks for the sensor's noise. A step the paper's test judges novel keeps the count
        and what the last decision weighed (nothing is assessed there): a misfitting
        look-alike whose paper test flips now and then stays novel instead of counting
        its five steps afresh.

        Returns
        -------
        novel : bool
        steps : int
            The steps in a row that misfit, this one included (the next
            ``state.misfit_steps``).
        """
        p, before = self.p, self.state.misfit_steps
        if p.misfit_novelty <= 0:
            return False, 0
        if belief.novel:
            return False, before
        if not decision.hypotheses:
            return False, 0
        last = self.snapshots[-1] if self.snapshots else None
        around = (last is not None and last.map_class == belief.map_class
                  and (last.dhd <= p.decision_cover or self._touched_round(belief)))
        # Judged novel, it stays so until the fit passes at the decision's confidence: a
        # look-alike's p-value hovers about misfit_novelty (a mug against its copy 4%
        # larger, by place, between 2e-7 and 2e-6 from touch 190 at 2 mm).
        level = p.misfit_novelty if before < MISFIT_STEPS else max(
            p.misfit_novelty, 1 - p.decision_confidence)
        misfit = min(decision.fit_p, decision.group_p) < level
        steps = before + 1 if misfit and (around or before >= MISFIT_STEPS) else 0
        return steps >= MISFIT_STEPS, steps

    def _touched_round(self, belief):
        """Whether the contacts' span settled under :data:`ROUND_SHARE` of the MAP class's
        size (:func:`~.lengths.own_unit`): an object much smaller than its MAP is touched
        all round while the MAP's surface is never covered (a 2 cm die beside a 20 cm mug,
        its MAP 19 cm from its contacts, p-values under 1e-200, known to the cap)."""
        f = self.filter
        model = f.models[f.class_names.index(belief.map_class)]
        return own_unit(f.contact_positions, model.size_unit, ROUND_SHARE) is not None

    def coverage(self, recon, map_vertices, contacts, model=None, pose=None):
        """The :class:`Coverage` of the estimate S* (the GPIS surface, else the MAP
        surface) by the contacts: l.8, eq. 35, over the vertices still to visit; with
        ``cover_prior`` a novel object's MAP prior counts too, unless the GPIS started from
        an object-agnostic prior or the object is explored at its own size (beyond the
        paper). In a robot's scene only what its probe can reach counts (:meth:`_in_scene`).
        """
        reconstructed = recon is not None and not recon.empty
        surface = recon.vertices if reconstructed else map_vertices
        reachable = (open_estimate(surface, recon.closure, self.state, self.p, contacts)
                     if reconstructed else self._reachable(surface))
        if reconstructed:
            reachable = open_parts(reachable, surface, recon.faces, contacts, self.state, self.p)
        in_scene = not self.scene.is_free and model is not None
        map_reach = None  # the MAP's reachable vertices, only where they are asked for
        if in_scene and (not reconstructed or self.p.cover_prior):
            map_reach = self._in_scene(map_vertices, vertex_normals(model) @ pose[0].T,
                                       ValueOf(PosedSDF(model, *pose)), contacts)
        if in_scene:
            reachable = _both(reachable, map_reach if not reconstructed else self._in_scene(
                surface, mesh_vertex_normals(recon.vertices, recon.faces),
                recon.fit.mean_value, contacts))
        dhd = directed_hausdorff(surface[reachable], contacts)
        prior_open, prior_dhd = None, 0.0
        if self._covers_prior(recon):
            # The prior is cut out around missed probes as far as the carve reaches; a
            # prior refuted everywhere has nothing left to cover (a 2 mm fork's held
            # screwdriver, every vertex within 20 mm of a given-up target, held its stop
            # 28 mm off for 80 touches to the cap).
            prior_open = open_vertices(map_vertices, self.state,
                                       max(self.p.contact_spacing, self.p.gpis_carve_radius),
                                       all_refuted=False)
            if map_reach is not None and prior_open.any():
                prior_open = _both(prior_open, map_reach)
            if prior_open.any() and model is not None:
                prior_open = prior_open.copy()
                prior_open[prior_open] = self._agreed(map_vertices[prior_open], model, pose)
            if prior_open.any():
                prior_dhd = directed_hausdorff(map_vertices[prior_open], contacts)
        return Coverage(surface, reachable, dhd, prior_open, prior_dhd)

    def _agreed(self, vertices, model, pose):
        """Which MAP ``vertices`` (world frame) lie within ``eps / 2`` of the class's surface
        averaged over its heaviest poses (``cover_prior_poses``, :class:`MixedSDF`): a part
        no touch pinned, which they place apart, is no prediction (a mug prior's handle
        turning about a cup's free axis held the cup's stop)."""
        f = self.filter
        poses = prior_poses(f.particles, f.class_names.index(model.name), *pose,
                            self.p.cover_prior_poses)
        if len(poses[0]) == 1:
            return np.ones(len(vertices), bool)
        return np.abs(MixedSDF(model, *poses)(vertices)[0]) <= self.p.eps / 2

    def _covers_prior(self, recon):
        """Whether the MAP prior counts in the coverage (``cover_prior``): not while a
        superquadric is the GPIS prior, nor while the object is explored at its own size.
        A prior many times the object's size is not its shape at any pose: a 2 cm block's
        25 cm knife prior held the stop 15-23 cm off the block for 400 touches, its pose
        wandering as the block's touches left it free."""
        return (recon is not None and self.p.cover_prior and self.state.gpis.shape is None
                and not self.context.own_size)

    def _in_scene(self, vertices, normals, outside, contacts):
        """Mask of the estimate's vertices the scene's probe can reach
        (:meth:`~..scene.Scene.reachable`): above the table, facing the reach cone,
        where the tip fits and the way in along the cone is free of the estimate for
        ``approach_clearance``. The estimate (``outside``) is evaluated only at vertices
        farther than ``eps / 2`` from every contact: nearer ones neither hold the stop
        nor become targets."""
        p = self.p
        keep = self.scene.reachable(vertices, normals, margin=SCENE_MARGIN * self.unit)
        far = keep.copy()
        if len(contacts):
            far[keep] = cKDTree(contacts).query(vertices[keep])[0] > p.eps / 2
        if far.any():
            keep[far] = self.scene.reachable(vertices[far], normals[far], outside,
                                             margin=SCENE_MARGIN * self.unit,
                                             clear=p.approach_clearance)
        return keep

    def stop_test(self, coverage, belief, decision=UNDECIDED):
        """The :class:`~.stop.Stop` of the step: :func:`~.stop.stop_rule` on its
        coverage, belief and decision and the exploration state's progress."""
        state = self.state
        progress = Progress(len(self.snapshots), bool(state.frontier), state.checks_passed,
                            state.decision_checks, state.telling_steps, state.misfit_steps,
                            any(s.novel for s in self.snapshots[-FLICKER_STEPS:]))
        return stop_rule(self.p, coverage.value, coverage.dhd, belief.novel,
                         belief.novel and self.context.strategy != "rrt", decision, progress,
                         self.sensor_noise[0])

    def choose_target(self, stop, coverage, model, rotation, translation, map_vertices,
                       recon, contacts, decision=UNDECIDED):
        """The step's :class:`Plan`: the next target (l.4, eq. 32 while novel; l.6, eq. 36
        while known) or, beyond the paper, the frontier's next target, a check line, a
        confirm check, a telling-apart target or the uncovered prior's farthest vertex."""
        keep = dict(dhd=coverage.value, terminated=stop.terminated, decided=stop.decided,
                    decision_checks=stop.decision_checks)
        if recon is not None and not recon.empty:
            outside = recon.fit.mean_value
        else:
            outside = ValueOf(PosedSDF(model, rotation, translation))
        if stop.terminated:
            return Plan(None, None, **keep)
        if stop.frontier:
            position, normal = self.state.frontier[0]
            # Probe the full depth across the tangent plane (the estimate has no surface
            # here), but approach short of what the estimate does predict.
            aim = Aim(position, normal, BelowTangentPlane(position, normal, outside))
            return Plan(aim, None, frontier=True, **keep)
        if stop.checking:
            return Plan(None, self.plan_check_line(coverage.surface, contacts, outside), **keep)
        if stop.confirm:
            return Plan(None, self.plan_check_line(map_vertices, contacts, outside),
                        confirming=True, **keep)
        if stop.rivals and (aim := self.telling_apart(decision, contacts)) is not None:
            return Plan(aim, None, telling_apart=True, **keep)
        if stop.posing and decision.loosest is None:
            # The filter's posterior settles with touches anywhere: the paper's target.
            return Plan(self._next_target(coverage.surface, coverage.reachable, recon, model,
                                          rotation, translation, contacts), None,
                        telling_apart=True, **keep)
        if stop.posing:
            # Where the pose is least certain (the fit's covariance), on the MAP surface.
            position, normal = decision.loosest
            aim = Aim(position, normalise_rows(normal[None])[0],
                      ValueOf(PosedSDF(model, rotation, translation)))
            return Plan(aim, None, telling_apart=True, **keep)
        if coverage.dhd <= self.p.eps < coverage.prior_dhd:
            # The reconstruction is covered, but part of the prior it came from is neither
            # touched nor refuted: the object may extend there.
            return Plan(self._next_target(map_vertices, coverage.prior_open, None, model,
                                          rotation, translation, contacts), None, **keep)
        return Plan(self._next_target(coverage.surface, coverage.reachable, recon, model,
                                      rotation, translation, contacts), None, **keep)

    def telling_apart(self, decision, contacts):
        """The :class:`Aim` where the plausible hypotheses disagree most (None: nowhere)."""
        hypotheses = (decision.hypotheses[0],) + decision.rivals
        # Touches are spread over the parts that differ (each earlier one within half the
        # contact spacing halves a place's worth), but may come back to the one part that
        # tells the hypotheses apart while noise leaves them plausible.
        refuted = self.state.refuted
        spread = max(2 * self.sensor_noise[0], self.p.decision_floor,
                     TELL_SPACING * self.p.contact_spacing)
        told = np.reshape(self.state.told, (-1, 3))
        if len(told) and len(contacts):  # a touch that landed counts once, as its contact
            told = told[cKDTree(contacts).query(told)[0] > spread]
        found = disagreement_target(
            self.filter.bank, hypotheses, decision.scale,
            avoid=((refuted, self.p.contact_spacing),),
            crowd=((contacts, spread), (told, spread)), candidates=self._telling_candidates)
        if found is None:
            return None
        position, normal, owner = found
        hypothesis = hypotheses[owner]
        prior = self.filter.models[hypothesis.class_index]
        estimate = ValueOf(PosedSDF(prior, hypothesis.rotation, hypothesis.translation))
        return Aim(position, normalise_rows(normal[None])[0], estimate)

    def _telling_candidates(self, class_index):
        """The surface points a class offers as telling targets (``decision_candidates``;
        0: its feature points), object frame."""
        count = self.p.decision_candidates
        if count == 0:
            return self.filter.bank.points[class_index], self.filter.bank.normals[class_index]
        return oriented_samples(self.filter.models[class_index], count)

    def _next_target(self, surface, reachable, recon, model, rotation, translation, contacts):
        """The :class:`Aim` of the next step: the novel or the known rule of
        :mod:`.exploration`, with the estimate whose inside the probe depth is taken from."""
        if recon is not None and not recon.empty:
            index = variance_target(recon.vertices, recon.subset, recon.candidate_variance,
                                    reachable, contacts, self._uncovered_beyond(),
                                    self.p.target_farthest)
            target = recon.vertices[index]
            _, gradient = recon.fit.mean(target[None])
            return Aim(target, normalise_rows(gradient)[0], recon.fit.mean_value)
        if self.scene.has_table and 0 < len(contacts) < FIRST_CONTACTS:
            # A probe aimed far from the few touches lands on the table beside an object
            # lying flat (a fork: 300 misses after one touch): search around them first.
            near = cKDTree(contacts).query(surface)[0] <= FIRST_SEARCH * self.unit
            if (near & reachable).any():
                reachable = near & reachable
        index = np.flatnonzero(reachable)[farthest_vertex(surface[reachable], contacts)]
        normal = vertex_normals(model)[index] @ rotation.T
        estimate = ValueOf(PosedSDF(model, rotation, translation))
        return Aim(surface[index], normalise_rows(normal[None])[0], estimate)

    def _uncovered_beyond(self):
        """How far from every contact the novel target is looked for first (None: the
        paper's, anywhere): ``eps`` with ``target_uncovered``, and at least the sensor's
        noise times ``target_noise_stds`` (:func:`beyond_noise`)."""
        beyond = max(self.p.eps if self.p.target_uncovered else 0.0, self._beyond_noise())
        return beyond or None

    def _beyond_noise(self):
        return beyond_noise(self.p, self.sensor_noise)

    def _reachable(self, vertices, radius=None):
        """Mask of the vertices that exploration may still have to visit: away from every
        target the sensor failed to reach and from the free space that missed probes
        passed through (within ``radius``, default ``contact_spacing``).

        The DHD and the next target leave the others out (all vertices count if none is
        left): probing there again cannot change the estimate, so the trial would only run
        to its step cap.
        """
        return open_vertices(vertices, self.state,
                             self.p.contact_spacing if radius is None else radius)

    def plan_check_line(self, estimate, contacts, outside=None):
        """The next :class:`Check`: the estimate's vertices, its point, its direction and the
        path to sweep (its direction joins ``check_directions`` when the step adopts it).

        ``check_line_aim = "gap"`` (with ``outside``, positive outside the estimate): a
        lattice through the widest unobserved gap, alternately inside the contacts' hull
        and in a shell of ``2 eps`` around the estimate (with ``check_shell_inward`` the
        lattice moved in to reach the band beside the estimate, :func:`~.exploration.inward`;
        a robot's scene sweeps one line through the gap itself),
        in from a direction with a clear way (:func:`~.exploration.widest_gap`,
        :func:`~.exploration.raster_path`);
        ``"gap-weakest"``: every third check sweeps the same lattice about the estimate's
        vertex farthest from every contact (:meth:`_weakest_support`), in addition to the
        ``check_lines`` gap checks;
        otherwise, or without a gap, a straight line through a random contact moved by
        about ``eps``, from the least used of the spread directions.
        """
        through = None
        kind = check_kind(self.p, len(self.state.check_directions))
        if kind == "weakest" and outside is not None:
            through, gap = self._weakest_support(estimate, contacts)
        elif kind in ("hull", "shell") and outside is not None:
            # A place a check was planned about counts as observed: swept about again, a
            # gap under an elephant was reached by the same way in, touched at its edge.
            explored = np.vstack([contacts, self.filter.noncontact_positions,
                                  self.state.free_space, self.state.swept,
                                  np.reshape(self.state.check_throughs, (-1, 3))])
            # Checks alternate between gaps inside the contacts' hull and the shell just
            # outside the estimate (beyond the ends of parts it closes off).
            shell = 2 * self.p.eps if kind == "shell" else 0.0
            through, gap = widest_gap(contacts, explored, estimate, outside, shell=shell,
                                      unit=self.unit, observed_only=self.p.check_shell_observed)
        if not self.scene.is_free:  # one line, no lattice: the gap itself
            return self._scene_check(estimate, contacts, through)
        if kind == "shell" and through is not None and self.p.check_shell_inward:
            through = inward(through, estimate, min(gap, MAX_RASTER_RADIUS * self.unit),
                             unit=self.unit)
        if through is None:
            direction = next_sweep_direction(self.state.check_directions, self.rng)
            through = contacts[self.rng.integers(len(contacts))] + self.rng.normal(
                0.0, self.p.eps, size=3)
            path = np.stack([through + SWEEP_RADIUS * self.unit * direction,
                             through - SWEEP_RADIUS * self.unit * direction])
        else:
            unit = self.unit
            direction = clearest_direction(through, estimate, self.state.check_directions,
                                           reach=SWEEP_RADIUS * unit, unit=unit)
            path = raster_path(through, min(gap, MAX_RASTER_RADIUS * unit), direction,
                               spacing=0.2 * unit, reach=SWEEP_RADIUS * unit)
        return Check(estimate, through, direction, path)

    def _scene_check(self, estimate, contacts, through):
        """A check of a robot's scene: one straight line through the gap (else a contact
        moved by about ``eps``) from the clearest direction of the cone, to the table."""
        scene, unit = self.scene, self.unit
        if through is None:
            through = contacts[self.rng.integers(len(contacts))] + self.rng.normal(
                0.0, self.p.eps, size=3)
        if scene.has_table:  # a gap below the tip's reach is looked for just above it
            low = scene.tip_radius + SCENE_MARGIN * unit - scene.height(through[None])[0]
            through = through + max(0.0, low) * scene.up
        path, direction = check_line(scene, through, estimate, self.state.check_directions,
                                     reach=SWEEP_RADIUS * unit, unit=unit)
        return Check(estimate, through, direction, path)

    def _weakest_support(self, estimate, contacts):
        """The estimate's vertex farthest from every contact (among those exploration may
        still visit, away from earlier weakest supports: :func:`weakest_support`) and that
        distance: where the estimate rests on the fewest touches, so the object may lie up
        to ``eps`` off it unseen (a leg's middle between touched ends)."""
        tried = [through for index, through in enumerate(self.state.check_throughs)
                 if check_kind(self.p, index) == "weakest"]
        return weakest_support(estimate[self._reachable(estimate)], contacts, tried,
                               self.p.contact_spacing, MAX_RASTER_RADIUS * self.unit)


def check_kind(p, index):
    """What check number ``index`` (0 first) of a session with parameters ``p`` aims at:
    ``"hull"`` and ``"shell"`` gaps in turn, with ``"gap-weakest"`` a ``"weakest"`` support
    after each pair; ``"contact"`` with ``check_line_aim = "contact"``."""
    aim = p.check_line_aim
    if aim == "contact":
        return "contact"
    kinds = ("hull", "shell", "weakest") if aim == "gap-weakest" else ("hull", "shell")
    return kinds[index % len(kinds)]


def beyond_noise(p, sensor_noise):
    """``target_noise_stds`` position-noise standard deviations (scene units): nearer a
    contact a touch only repeats it within the noise."""
    return p.target_noise_stds * sensor_noise[0]



@functools.lru_cache(maxsize=8)
def vertex_normals(model):
    """A prior's vertex normals, (n, 3), object frame, from a bare copy of its mesh (see
    :func:`~tactile_viz.engine.shape.meshes.bare_mesh`): a long run meets many MAP classes."""
    return bare_mesh(model.mesh).vertex_normals


def _both(mask, other):
    """``mask & other``, or ``other`` alone when nothing is left of both (``mask`` when
    nothing is left of ``other``)."""
    both = mask & other
    return both if both.any() else (other if other.any() else mask)


def mesh_vertex_normals(vertices, faces):
    """Area-weighted vertex normals of a triangle mesh, (v, 3), unit (zero-area: +z)."""
    vertices, faces = np.asarray(vertices, float), np.asarray(faces)
    face_normals = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]],
                            vertices[faces[:, 2]] - vertices[faces[:, 0]])
    normals = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals)
    return normalise_rows(normals, fallback=np.array([0.0, 0.0, 1.0]))
