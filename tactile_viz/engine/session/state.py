"""The state of a session, in explicit objects: :class:`ExplorationState`, everything a
step changes besides the filter, the random generators and the snapshots (adding a field
needs no other edit), and :class:`Checkpoint`, everything a step changes. A checkpoint is
what a failed step gives back, what the engine process sends back after a run and, with
the session's constructor inputs and its filter, what a pickled session holds."""

import copy
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from ..belief.incremental import NOTHING


class Aim(NamedTuple):
    """The target a step reaches for: ``position`` and outward ``normal`` (world frame) and
    the ``estimate`` (``(k, 3) -> (k,)``, negative inside) whose inside the probe depth and
    the approach are taken from."""

    position: np.ndarray
    normal: np.ndarray
    estimate: Any


class Check(NamedTuple):
    """A planned check of a novel estimate: the ``estimate``'s vertices it checks, the
    point ``through`` and ``direction`` it was planned from, and the ``path`` to sweep."""

    estimate: np.ndarray
    through: np.ndarray
    direction: np.ndarray
    path: np.ndarray


def _points():
    return np.zeros((0, 3))


@dataclass(frozen=True)
class GpisState:
    """What the next GPIS fit goes on from: the estimator
    (:class:`~.estimate.Estimator`) takes one and returns the next, never changes one.

    Attributes
    ----------
    scale : float
        The GPIS kernel scale ``a`` of the last fit (its Newton update starts there).
    radius : float or None
        The thin-plate ``R`` kept from fit to fit (``gpis_box_tolerance``).
    spacing : float or None
        The surface grid's cell kept from step to step (``gpis_box_tolerance``).
    fits : int
        Fits since the scale's last Newton step (``gpis_refit_every``).
    shape : Superquadric or None
        The object-agnostic prior mean the last fit started from (``gpis_agnostic``;
        None: the MAP shape's).
    pose : tuple or None
        ``(class name, rotation, translation)`` of the MAP shape the last fit started
        from (None: a superquadric's); ``gpis_prior_hold`` weighs it against the next MAP.
    cache : GramCache or None
        The last fit's Gram matrix and factor (:mod:`~tactile_viz.engine.shape.gpis_incremental`;
        immutable, keyed by content: a fit extends it only where the content agrees).
    variance : NodeVariance or None
        The last surface's lattice-node variances (:mod:`~tactile_viz.engine.shape.gpis_variance`).
    recon : Reconstruction or None
        The last fit's whole surface (before a snapshot's reported parts), which a check
        that touched the object beside it may plan on again (with ``check_refit_every`` over
        1; else None).
    held : int
        Steps since ``recon`` was fitted.
    free : tuple of int
        The non-contacts and free-space points there were at that fit (what carves it).
    """

    scale: float = 1.0
    radius: Any = None
    spacing: Any = None
    fits: int = 0
    shape: Any = None
    pose: Any = None
    cache: Any = None
    variance: Any = None
    recon: Any = None
    held: int = 0
    free: tuple = (0, 0)


@dataclass
class ExplorationState:
    """What exploration remembers from step to step.

    Attributes
    ----------
    gpis : GpisState
        What the next GPIS fit goes on from (the estimator's, replaced by each step).
    target : Aim or None
        Where the next step reaches (None: terminated, a check, or the first touch).
    given_up : list of (3,) float
        Targets the sensor could not reach (exploration leaves the surface near them out).
    free_space : (k, 3) float
        Samples of the paths missed probes passed through.
    swept : (k, 3) float
        Samples of the approach paths up to their first touch.
    missed : (k, 2, 3) float
        Start and end of each probe toward a target that touched nothing (the decision
        weighs the whole path: a probe's end can lie beyond a thin part it passed through).
    frontier : list of (position, normal)
        Targets beside contacts on parts nothing predicted, still to visit.
    frontier_target : bool
        Whether ``target`` came from the frontier.
    followed : list of int
        Contacts an estimate left unheld whose places joined the frontier
        (``follow_unheld``).
    estimate_vertices : (k, 3) float or None
        The whole surface the last step planned on (a snapshot reports only its parts some
        contact supports): the frontier asks whether it predicted a touch.
    telling_apart : bool
        Whether ``target`` is where rival hypotheses disagree (beyond the paper).
    check : Check or None
        The check the next step sweeps.
    check_directions : list of (3,) float
        The directions of the checks so far.
    check_throughs : list of (3,) float
        The points they were planned through (one a check, as ``check_directions``).
    checks_passed : int
        Checks in a row that touched nothing unpredicted.
    hypotheses : tuple of Hypothesis
        The plausible hypotheses of the last decision, weighed again at the next
        (:func:`~tactile_viz.engine.belief.decision.decide`).
    decided : bool
        Whether the last decision was decided (its MAP, ``hypotheses[0]``, is then only
        refitted while it holds: :func:`~tactile_viz.engine.belief.held.held_decision`).
    decision_refined : Refined
        What the last decision refined (``Decision.refined``): the next starts from it
        (:mod:`~tactile_viz.engine.belief.incremental`).
    decision_checks : int
        Checks in a row around a MAP ready to be decided that touched nothing it does not
        predict.
    confirming : bool
        Whether ``check`` is such a check.
    telling_steps : int
        Steps whose target was where rival hypotheses disagree.
    told : list of (3,) float
        Those targets (the next keep away from them: a touch that lands beyond one, on a
        part the rival does not have, leaves it as far from every contact as before).
    moves_rng : dict or None
        The session rng's state when the step in progress began (None between steps).
    results : list of Contact or NonContact
        The results of the step's guarded moves so far.
    held : tuple or None
        ``(observations, free space)`` given before the first contact ever, kept for its step.
    misfit_steps : int
        Steps in a row whose known MAP misfitted (``misfit_novelty``).
    replayed : int
        Recorded steps given to a :class:`~.recorded.RecordedSession` (misses before the
        first contact are held, so it can run ahead of the snapshots).
    """

    gpis: GpisState = field(default_factory=GpisState)
    target: Any = None
    given_up: list = field(default_factory=list)
    free_space: np.ndarray = field(default_factory=_points)
    swept: np.ndarray = field(default_factory=_points)
    missed: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    frontier: list = field(default_factory=list)
    frontier_target: bool = False
    followed: list = field(default_factory=list)
    estimate_vertices: Any = None
    telling_apart: bool = False
    check: Any = None
    check_directions: list = field(default_factory=list)
    check_throughs: list = field(default_factory=list)
    checks_passed: int = 0
    hypotheses: tuple = ()
    decided: bool = False
    decision_refined: Any = NOTHING
    decision_checks: int = 0
    confirming: bool = False
    telling_steps: int = 0
    told: list = field(default_factory=list)
    moves_rng: Any = None
    results: list = field(default_factory=list)
    held: Any = None
    misfit_steps: int = 0
    replayed: int = 0

    @property
    def refuted(self):
        """The given-up targets and the missed probes' free-space samples, ``(k, 3)``
        float, world frame: where probes looked for the object and did not find it."""
        return np.vstack([np.reshape(self.given_up, (-1, 3)),
                          np.reshape(self.free_space, (-1, 3))]).astype(float)

    def adopt(self, plan):
        """Take a step's plan (:class:`~.planner.Plan`): the one place the target, the
        check and their flags enter the state; a frontier target leaves the queue, a
        check's direction and point join ``check_directions`` and ``check_throughs``, a
        telling target ``told``."""
        self.target, self.check, self.frontier_target = plan.target, plan.check, plan.frontier
        self.telling_apart, self.confirming = plan.telling_apart, plan.confirming
        self.decision_checks = plan.decision_checks
        if plan.telling_apart:
            self.telling_steps += 1
            self.told.append(plan.target.position)
        if plan.frontier:
            self.frontier.pop(0)
        if plan.check is not None:
            self.check_directions.append(plan.check.direction)
            self.check_throughs.append(plan.check.through)

    def copy(self):
        """A deep copy: changing any list, dict or array of the copy leaves this state as
        it is. The estimates (callables of points, such as ``target.estimate``) are shared:
        they hold priors and GPIS fits, and a step replaces them, never changes them. So is
        ``gpis`` (frozen, its caches tens of MB: a step replaces it too)."""
        memo = {id(self.gpis): self.gpis}
        _shared_callables([getattr(self, item.name) for item in fields(self)], memo)
        return copy.deepcopy(self, memo)


def _shared_callables(value, memo):
    """Enter in ``memo`` (a deepcopy memo) every callable within ``value``, through
    tuples, lists and dicts, as its own copy."""
    if callable(value):
        memo[id(value)] = value
    elif isinstance(value, (tuple, list)):
        for item in value:
            _shared_callables(item, memo)
    elif isinstance(value, dict):
        for item in value.values():
            _shared_callables(item, memo)


@dataclass
class Checkpoint:
    """Everything a step of a session changes.

    Attributes
    ----------
    filter : object
        :meth:`~tactile_viz.engine.belief.particle_filter.ParticleFilter.checkpoint` (its arrays
        are replaced by an update, never changed, so references suffice).
    generators : tuple of dict
        The bit-generator states of the session's generators (the session's, then the
        simulator's when it has one).
    exploration : ExplorationState
        A copy (:meth:`ExplorationState.copy`).
    steps : int
        The number of snapshots.
    """

    filter: Any
    generators: tuple
    exploration: ExplorationState
    steps: int
