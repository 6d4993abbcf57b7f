"""The inference session: Algorithm 2 of the paper, one step at a time.

A :class:`Session` couples a prior library, the particle filter, the GPIS and an
exploration strategy with a sensor. A step asks the sensor for guarded moves until its
procedure is done (the first touch, contact enforcement toward the target, a check, an RRT
step), keeps what they found (:mod:`.bookkeeping`), then runs the rest of the algorithm's
loop (:meth:`Session._iteration`) and returns an immutable :class:`Snapshot`. The planner,
the bookkeeping and the estimate (GPIS) are parts built from explicit inputs
(:meth:`Session.parts`, :mod:`.context`), each in its own module; everything a step
changes besides the filter and the generators is one :class:`~.state.ExplorationState`.

Algorithm 2's lines are tagged ``l.N``, counting its statements after the initialisation,
end lines left out: l.1 while ``d_H(S*, X_c) > eps``; l.2 update the belief (PF), MAP
particle ``z*``; l.3 if its evidence is below the threshold; l.4 update the GPIS, target
from its zero level set; l.5 else; l.6 target from the MAP surface; l.7 establish contact
(the guarded moves); l.8 update ``d_H``. Equations are numbered in the order of the
paper's LaTeX source: 14 MAP particle, 19-20 weights, 24 novelty threshold, 32 GPIS
target, 35 DHD, 36 MAP-surface target.
"""

from __future__ import annotations

import inspect
import os
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from ..belief.decision import UNDECIDED
from ..belief.particle_filter import ParticleFilter
from ..errors import SessionError
from ..explore.exploration import STRATEGIES
from ..explore.observations import Contact, NonContact
from ..explore.simulator import ContactSimulator, GroundTruth
from ..io.observation_file import RecordedStep
from ..io.persistence import load_session, save_session
from ..params import PAPER_SIZE, SessionParams, scaled_lengths
from ..presets import noise_matched
from ..scene import FREE, Scene
from ..shape.library import PriorLibrary
from .bookkeeping import Bookkeeper
from .context import Observation, Parts, Sensor, StepContext  # noqa: F401 (Sensor: public)
from .estimate import Estimator, decided_class, map_shape
from .learning import learned_model
from .legacy import legacy_arguments
from .lengths import OWN_STEPS, novel_for_long, own_unit, session_lengths
from .planner import Planner
from .procedures import step_procedure
from .snapshot import Move, Snapshot, frozen, step_snapshot
from .state import Checkpoint, ExplorationState, GpisState
from .truth import TruthEvaluator, make_truth  # noqa: F401 (make_truth: public here too)


@contextmanager
def _timed(timings, name):
    clock = time.perf_counter()
    yield
    timings[name] = timings.get(name, 0.0) + time.perf_counter() - clock


class Session:
    """Active exploration of one object with one prior library: Algorithm 2, step by step.

    The sensor contract is a guarded move (:class:`Move`): move along a path and stop at the
    first contact, answering with the :class:`Contact` or a :class:`NonContact` at the path's
    end. The session, not the sensor, carries out contact enforcement and surface
    following by asking for such moves. Two ways to drive it, one code path:

    - callback: a ``sensor`` with ``probe(path) -> Contact | NonContact`` (a robot, or the
      simulator of :meth:`simulated`); :meth:`step` runs a whole step;
    - ask/tell: ``move = session.propose()``, the robot carries it out,
      ``session.observe(result)``; ``observe`` returns the step's :class:`Snapshot` when the
      step is complete, else None (more moves are needed).

    :meth:`observe` also takes a whole step's observations (a list), as a recording gives
    them. Misses before the first contact are kept until it comes. The session knows no
    ground truth: a simulated trial is :meth:`simulated`, whose sensor is the simulator and
    whose ``evaluator`` fills the snapshots' error fields (None otherwise).

    Parameters
    ----------
    library : PriorLibrary
    strategy : {"gpis-dhd", "rrt"}
    params : SessionParams, optional
    seed : int
        Seeds the filter and the exploration (and the simulator's noise, :meth:`simulated`).
    sensor_noise : tuple of float
        The sensor model: ``(position std in scene units, normal std in degrees)`` the
        model assumes (the likelihood's widths grow with it,
        :func:`~..presets.noise_matched`, and so does the GPIS's observation noise). The
        chance of a wrong contact the model assumes is ``params.filter.outlier_probability``.
    sensor : Sensor, optional
        ``sensor.probe(path)`` carries out one guarded move (needed by :meth:`step`).
    scene : Scene, optional
        The robot's world: a table, the reach cone, the tip's radius (:mod:`..scene`);
        default the paper's free space. Paths are then the tip's centre's, straight and
        within the cone; table contacts are misses of the object; the DHD stop and the
        decision's coverage count only the part of the estimate a probe can reach.

    The signature before 2026-12, the ground truth first, still works (:mod:`.legacy`).
    """

    def __init__(self, *args, **kwargs) -> None:
        truth, outliers, args, kwargs = legacy_arguments(args, kwargs)
        self._build(*args, **kwargs)
        if truth is not None:
            self._simulate(truth, outliers)

    def _build(self, library: PriorLibrary, strategy: str = "gpis-dhd",
               params: SessionParams | None = None, seed: int = 0,
               sensor_noise: tuple[float, float] = (0.0, 0.0), sensor: Sensor | None = None,
               scene: Scene | None = None) -> None:
        if not isinstance(library, PriorLibrary):
            raise SessionError(f"a session needs a PriorLibrary, got {type(library).__name__}")
        if strategy not in STRATEGIES:
            raise SessionError(f"unknown strategy {strategy!r}; "
                               f"choose from {', '.join(STRATEGIES)}")
        if len(library) == 0:
            raise SessionError("the prior library is empty")
        self.library = library
        self.strategy = strategy
        self.params = params or SessionParams()
        self.seed = int(seed)
        self.sensor_noise = tuple(float(v) for v in sensor_noise)
        self.scene = FREE if scene is None else scene
        self.rng = np.random.default_rng([self.seed, 1])
        self.sensor = sensor
        self.evaluator = None  # errors against a truth, outside the timed step
        # The filter's lengths scale with the library, which all classes share.
        self._filter_unit = self.params.length_unit or library.reference_size / PAPER_SIZE
        filter_params = scaled_lengths(self.params.filter, self._filter_unit)
        if any(self.sensor_noise):
            filter_params = noise_matched(filter_params, *self.sensor_noise)
        self.filter = ParticleFilter(library, filter_params,
                                     rng=np.random.default_rng([self.seed, 3]),
                                     scene=self.scene)
        self.snapshots = []
        self._p, self._unit = self._scene_lengths(self._filter_unit), self._filter_unit
        self._lengths = self._filter_unit, None  # (size unit, own size unit): _use_lengths
        self._live = None  # (kind, procedure, rng, path): transient, rebuilt by replay
        self.state = ExplorationState(gpis=GpisState(scale=self._p.gpis_scale))

    __init__.__signature__ = inspect.signature(_build)

    @classmethod
    def simulated(cls, truth: GroundTruth, library: PriorLibrary, strategy: str = "gpis-dhd",
                  params: SessionParams | None = None, seed: int = 0,
                  sensor_noise: tuple[float, float] = (0.0, 0.0), sensor_outliers: float = 0.0,
                  scene: Scene | None = None) -> Session:
        """A simulated trial: the sensor is a :class:`~..explore.simulator.ContactSimulator`
        of ``truth`` that adds ``sensor_noise`` (the noise the model assumes too) and makes
        a wrong contact with chance ``sensor_outliers``; a
        :class:`~.truth.TruthEvaluator` fills the snapshots' error fields, untimed.

        Parameters
        ----------
        truth : GroundTruth
            The simulated object, placed in the world.
        library, strategy, params, seed, sensor_noise, scene
            As for :class:`Session`.
        sensor_outliers : float
            The simulated sensor's chance of a wrong contact, in [0, 1).

        Returns
        -------
        Session
        """
        session = cls(library, strategy, params, seed, sensor_noise, scene=scene)
        session._simulate(truth, sensor_outliers)
        return session

    def _simulate(self, truth, outliers):
        """Make the simulator of ``truth`` the sensor and attach its evaluator."""
        if not isinstance(truth, GroundTruth):
            raise SessionError(f"the truth must be a GroundTruth, got {type(truth).__name__}")
        self.sensor = ContactSimulator(truth, position_noise=self.sensor_noise[0],
                                       normal_noise_deg=self.sensor_noise[1],
                                       rng=np.random.default_rng([self.seed, 2]),
                                       outlier_fraction=outliers, scene=self.scene)
        self.evaluator = TruthEvaluator(truth, self.params.metric_samples)

    @property
    def simulator(self) -> ContactSimulator | None:
        """The sensor when it is the simulator (:meth:`simulated`), else None."""
        return self.sensor if isinstance(self.sensor, ContactSimulator) else None

    @property
    def truth(self) -> GroundTruth | None:
        """The simulated object (:meth:`simulated`), else None."""
        return None if self.simulator is None else self.simulator.truth

    @property
    def sensor_outliers(self) -> float:
        """The simulated sensor's chance of a wrong contact (0 without a simulator)."""
        return 0.0 if self.simulator is None else self.simulator.outlier_fraction

    def setup(self) -> dict:
        """The arguments that made this session (by keyword; with ``truth`` and
        ``sensor_outliers`` those of :meth:`simulated`): what a pickle, the engine process
        and a saved file rebuild it from (:meth:`from_setup`)."""
        setup = {"library": self.library, "strategy": self.strategy, "params": self.params,
                 "seed": self.seed, "sensor_noise": self.sensor_noise, "scene": self.scene}
        if self.simulator is not None:
            return {**setup, "truth": self.truth, "sensor_outliers": self.sensor_outliers}
        return {**setup, "sensor": self.sensor}

    @classmethod
    def from_setup(cls, **setup) -> Session:
        """The session :meth:`setup` describes, with no steps: :meth:`simulated` when it
        holds a ``truth`` (None: not simulated)."""
        truth = setup.pop("truth", None)
        outliers = setup.pop("sensor_outliers", 0.0)
        if truth is None:
            return cls(**setup)
        return cls.simulated(truth, **setup, sensor_outliers=outliers)

    def __getstate__(self):
        # The filter goes whole: its models then travel as references in the engine
        # process (ParticleFilter pickles without its bank). A running procedure of
        # guarded moves does not pickle; it is replayed from the checkpoint.
        return {"setup": self.setup(), "filter": self.filter,
                "snapshots": list(self.snapshots), "checkpoint": self.checkpoint()}

    def __setstate__(self, state):
        self.__dict__.update(type(self).from_setup(**state["setup"]).__dict__)
        self.filter, self.snapshots = state["filter"], list(state["snapshots"])
        self.restore(state["checkpoint"])

    @property
    def step_count(self):
        return len(self.snapshots)

    @property
    def terminated(self):
        return bool(self.snapshots) and self.snapshots[-1].terminated

    @property
    def latest(self):
        return self.snapshots[-1] if self.snapshots else None

    def run(self, max_steps: int | None = None,
            callback: Callable[[Snapshot], object] | None = None) -> Snapshot | None:
        """Step until termination (or ``max_steps`` more steps); returns the last snapshot."""
        while not self.terminated and (max_steps is None or max_steps > 0):
            snapshot = self.step()
            if callback is not None:
                callback(snapshot)
            if max_steps is not None:
                max_steps -= 1
        return self.latest

    def step(self) -> Snapshot:
        """One time step of Algorithm 2 with the sensor (the simulator or a robot given as
        ``sensor``): the guarded moves of the step, then the update; returns its
        :class:`Snapshot`.

        The same path as :meth:`propose` and :meth:`observe`. A step that fails leaves the
        session exactly as it was before it.
        """
        if self.sensor is None:
            raise SessionError("this session has no sensor: give it what the sensor found "
                               "with observe(), or a sensor with probe(path)")
        if self.terminated:
            raise SessionError("the session has terminated; start a new one")
        saved = self.checkpoint()
        try:
            sensing, snapshot = 0.0, None
            while snapshot is None:
                move = self.propose()
                clock = time.perf_counter()
                result = self.sensor.probe(move.path)
                sensing += time.perf_counter() - clock
                snapshot = self._observe_move(result, {"sensor": sensing})
            return snapshot
        except BaseException:
            self.restore(saved)
            raise

    def propose(self) -> Move | None:
        """The next guarded move of the step in progress, or None after termination.

        Asking again before :meth:`observe` gives the same move.

        Returns
        -------
        Move or None
        """
        if self.terminated:
            return None
        self._use_lengths()
        kind, _, _, path = self._live_procedure()
        target = (self.state.target.position if kind == "target" else None)
        return Move(frozen(path), kind, len(self.state.results),
                    None if target is None else frozen(target))

    def _live_procedure(self):
        """The step's procedure of guarded moves, advanced to the next move: built from the
        state at the step's start and replayed with the results so far when it is not
        running (after a pickle, a copy or a rollback)."""
        if self._live is not None:
            return self._live
        if self.state.moves_rng is None:
            self.state.moves_rng = self.rng.bit_generator.state
        rng = np.random.Generator(type(self.rng.bit_generator)())
        rng.bit_generator.state = self.state.moves_rng
        kind, procedure = step_procedure(self.parts().bookkeeper, rng,
                                         getattr(self.sensor, "step", None))
        path = next(procedure)
        for result in self.state.results:
            path = procedure.send(result)
        self._live = (kind, procedure, rng, path)
        return self._live

    def _seen(self, observation):
        """A result as the object's belief takes it: a contact with the scene's table is
        a miss of the object where the tip stopped."""
        if (isinstance(observation, Contact) and self.scene.has_table
                and self.scene.is_table_contact(observation.position, observation.normal,
                                                self._table_tolerance())):
            return NonContact(self.scene.centre_of(observation.position, self.scene.up))
        return observation

    def _table_tolerance(self):
        """How far off the plane a reported contact may be and still be the table: the
        sensor's tolerance (1/600 of the library's size) and half a position-noise std.
        A robot places a table contact by its own kinematics, without the object's
        contact noise; a wider band would take the floor of a cup with a 2 mm base for
        the table under 2 mm noise, and lose what tells the cup upright from upside
        down."""
        return (getattr(self.sensor, "tolerance", self._filter_unit * PAPER_SIZE / 600)
                + 0.5 * self.sensor_noise[0] + 1e-9)

    def _observe_move(self, result, timings):
        """Take the result of the current guarded move; the step's snapshot when its
        procedure is done, else None."""
        self._use_lengths()
        kind, procedure, rng, _ = self._live_procedure()
        result = self._seen(result)
        self.state.results.append(result)
        try:
            path = procedure.send(result)
        except StopIteration as done:
            self.rng.bit_generator.state = rng.bit_generator.state
            self.state.moves_rng, self.state.results, self._live = None, [], None
            self.parts().bookkeeper.after_moves(kind, done.value)
            paths, observations = done.value[:2]  # a target's adds its own "reached"
            finish = getattr(self.sensor, "finish_step", None)
            if finish is not None:  # the simulated sensor's wrong readings, if any
                observations = finish(observations)
            return self._iteration(paths, observations, timings)
        self._live = (kind, procedure, rng, path)
        return None

    def observe(self, observations: Observation | Sequence[Observation],
                free_space: np.ndarray | None = None) -> Snapshot | None:
        """What the sensor found: the result of the proposed guarded move, or a whole step.

        Parameters
        ----------
        observations : Contact, NonContact or sequence of them
            One observation: the result of the move :meth:`propose` gave (ask/tell); the
            step's :class:`Snapshot` is returned when its procedure is done, else None.
            A sequence: what the sensor found in one whole step, in time order (at least
            one), as a recording gives it; misses before the first contact ever are held
            (None is returned) and join the step of that contact.
        free_space : (k, 3) float, optional
            Points the sensor moved through without touching; they cut the prior of the
            reconstruction (``gpis_carve_radius``) and are not observations of the filter.

        Notes
        -----
        The proposed target is given up by the rule of a step taken move by move
        (:meth:`~.bookkeeping.Bookkeeper._reached`). After a proposed check the first
        observation is where its sweep first touched. The session keeps accepting
        observations after it would have stopped (``terminated``).
        A step that fails leaves the session exactly as it was before it.
        """
        if isinstance(observations, (Contact, NonContact)):
            if free_space is not None:
                raise SessionError("free_space goes with a whole step's observations")
            saved = self.checkpoint()
            try:
                return self._observe_move(observations, {})
            except BaseException:
                self.restore(saved)
                raise
        if self.state.results:
            raise SessionError("a guarded move is pending: observe its result (one Contact "
                               "or NonContact) before a whole step")
        observations = list(observations)
        if not observations:
            raise SessionError("a step needs at least one observation")
        for observation in observations:
            if not isinstance(observation, (Contact, NonContact)):
                raise SessionError(f"not an observation: {observation!r} (use Contact or "
                                   "NonContact)")
        observations = [self._seen(observation) for observation in observations]
        points = np.asarray(np.zeros((0, 3)) if free_space is None else free_space, float)
        if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
            raise SessionError("free_space must be a finite (k, 3) array of points")
        self._use_lengths()
        saved = self.checkpoint()
        try:
            contacts = [o for o in observations if isinstance(o, Contact)]
            if self.state.held is not None:
                observations = self.state.held[0] + observations
                points = np.vstack([self.state.held[1], points])
                self.state.held = None
            if not contacts and len(self.filter.contact_positions) == 0:
                self.state.held = (observations, points)  # no estimate before a contact
                return None
            bookkeeper = self.parts().bookkeeper
            bookkeeper.keep_observations(observations, points, bookkeeper.approach_start(),
                                         aimed=self.state.target is not None)
            return self._iteration([], observations, {})
        except BaseException:
            self.restore(saved)
            raise

    def recorded_steps(self) -> list[RecordedStep]:
        """What was observed in each step so far: replaying them through :meth:`observe` of
        a session with the same library, parameters and seed gives the same estimates.

        Returns
        -------
        list of RecordedStep
        """
        steps, before = [], 0
        for snapshot in self.snapshots:
            free = snapshot.free_space
            steps.append(RecordedStep(list(snapshot.new_observations), np.array(free[before:])))
            before = len(free)
        return steps

    def checkpoint(self) -> Checkpoint:
        """Everything a step changes (what a failed step gives back): the filter's state,
        the random generators', a copy of the exploration state and the number of
        snapshots."""
        return Checkpoint(self.filter.checkpoint(),
                          tuple(g.bit_generator.state for g in self._generators()),
                          self.state.copy(), len(self.snapshots))

    def restore(self, saved: Checkpoint) -> None:
        """Return to ``saved`` (:meth:`checkpoint`); snapshots made since are dropped."""
        self.filter.restore(saved.filter)
        for generator, generator_state in zip(self._generators(), saved.generators):
            generator.bit_generator.state = generator_state
        self.state, self._live = saved.exploration.copy(), None
        del self.snapshots[saved.steps:]
        self._use_lengths()

    def _use_lengths(self, model=None, novel=None):
        """Set ``self._p``, the parameters with their lengths in scene units, and
        ``self._unit``, the scene units of a size unit (:meth:`_lengths_of`). Derived from
        the snapshots and the filter's contacts, so rollbacks and copies of a session need
        not keep it."""
        self._p, self._unit, self._lengths = self._lengths_of(model, novel)
        return self._p

    def _lengths_of(self, model=None, novel=None):
        """``(parameters in scene units, size unit, (unit, own unit))`` for ``model``: a
        sixth of its longest side, default the latest MAP object (the library's reference
        size before the first step), or ``params.length_unit``; an object judged novel
        at this step (``novel``; default: the latest step's judgement) and the steps
        before (:func:`~.lengths.novel_for_long`), much smaller or larger than ``model``,
        is explored at its own size (:func:`~.lengths.own_unit`). Changes nothing."""
        if model is None and self.snapshots:
            model = self.filter.models[self.filter.class_names.index(self.latest.map_class)]
        judged = [s.novel for s in self.snapshots[-OWN_STEPS:]]
        if novel is not None:  # this step's judgement, not yet a snapshot
            judged.append(novel)
        unit = self.params.length_unit or (model.size_unit if model is not None
                                           else self._filter_unit)
        own = None
        if novel_for_long(judged) and not self.params.length_unit:
            own = own_unit(self.filter.contact_positions, unit, self.params.own_size_share,
                           None if model is None else model.diameter)
        if (unit, own) == self._lengths:
            return self._p, self._unit, self._lengths
        return self._scene_lengths(unit, own), unit, (unit, own)

    def parts(self, model=None, novel=None) -> Parts:
        """The parts of a step (estimator, planner, bookkeeper) built from the session's
        current lengths, or from those of ``model`` (:meth:`_lengths_of`) without
        changing the session's; they share its filter, exploration state, generator and
        snapshots.

        Returns
        -------
        Parts
        """
        p, unit, lengths = ((self._p, self._unit, self._lengths) if model is None
                            else self._lengths_of(model, novel))
        context = StepContext(p, unit, self._filter_unit, self.sensor_noise, self.scene,
                              self.strategy, getattr(self.sensor, "tolerance", None),
                              own_size=lengths[1] is not None)
        inputs = (context, self.filter, self.state, self.rng, self.snapshots)
        return Parts(Estimator(*inputs), Planner(*inputs), Bookkeeper(*inputs))

    def learned_model(self, name: str, snapshot: Snapshot | None = None,
                      resolution: int | None = None):
        """The reconstructed surface of a novel snapshot (default the latest) as a new
        :class:`~..shape.objects.ObjectModel` (:func:`~.learning.learned_model`), at
        ``resolution`` (default ``params.learned_resolution``). Changes nothing."""
        snapshot = snapshot or self.latest
        model = None if snapshot is None else self.filter.models[
            self.filter.class_names.index(snapshot.map_class)]
        estimator = self.parts(model).estimator
        return learned_model(estimator, snapshot, name,
                             resolution or self.params.learned_resolution, self.library)

    def _scene_lengths(self, unit, own=None):
        """The parameters in scene units (:func:`~.lengths.session_lengths`)."""
        return session_lengths(self.params, unit, own, self.sensor_noise[0], self.scene.tip_radius)

    def _generators(self):
        simulator = self.simulator
        return (self.rng,) if simulator is None else (self.rng, simulator.rng)

    def _iteration(self, paths, observations, timings):
        """One pass of Algorithm 2's loop after the step's guarded moves (l.7, which reach
        for the target the last pass chose): l.2-l.6, l.8 and l.1's test, each a call that
        returns what it decides; the plan enters the exploration state in one place."""
        with _timed(timings, "filter"):
            belief = self.filter.update(observations)             # l.2: PF, eqs. 19-20
        model, pose, map_vertices = map_shape(self.filter, belief)  # l.2: z*, eq. 14
        self._use_lengths(model, belief.novel)                    # lengths in its size
        estimator, planner, _ = self.parts()
        contacts, recon, fitted = self.filter.contact_positions, None, (model, *pose, map_vertices)
        if belief.novel:                                          # l.3: below eq. 24
            recon, self.state.gpis = estimator.estimate(*fitted, timings)  # l.4: GPIS
        with _timed(timings, "decision"):                         # beyond the paper
            decision = planner.decide(belief)
        misfit, self.state.misfit_steps = planner.misfits(belief, decision)
        # What the decision weighed is carried to the next step's, misfit or not (afresh, a
        # misfit's assessment refined three poses in full), and through a step the
        # paper's test judges novel while the misfit count runs.
        if not (belief.novel and self.state.misfit_steps):
            self.state.hypotheses = decision.carried
            self.state.decision_refined = decision.refined
        if misfit:                                                # beyond the paper
            belief, decision = replace(belief, novel=True), UNDECIDED
            self._use_lengths(model, novel=True)
            estimator, planner, _ = self.parts()
            recon, self.state.gpis = estimator.reconstruct(*fitted, timings)
        self.state.decided = decision.decided
        reported = decided_class(self.filter, belief, decision, model, pose, map_vertices)
        if reported[1] is not model:                              # beyond the paper
            belief, model, pose, map_vertices = reported
            self._use_lengths(model, novel=False)                 # lengths in its size
            estimator, planner, _ = self.parts()
        if recon is not None and belief.novel and self.strategy != "rrt":  # beyond the paper
            self.parts().bookkeeper.follow_unheld(recon)
        aimed = estimator.aimed_pose(decision, model, pose, map_vertices)
        while True:
            pose, map_vertices = aimed
            if recon is not None:                                 # beyond the paper
                pose, map_vertices = estimator.prior_pose(model, pose, map_vertices)
            with _timed(timings, "target"):
                coverage = planner.coverage(recon, map_vertices, contacts, model, pose)  # l.8
                stop = planner.stop_test(coverage, belief, decision)        # l.1: d_H <= eps
                plan = planner.choose_target(stop, coverage, model, *pose,  # l.4: eq. 32,
                                             map_vertices, recon, contacts, decision)  # 36
            if not (plan.terminated and recon is not None and self.state.gpis.held):
                break
            # A session stops on a fit of all its contacts, not on one held through checks.
            recon, self.state.gpis = estimator.reconstruct(*fitted, timings)
        self.state.adopt(plan)
        self.state.estimate_vertices = None if recon is None else recon.vertices
        if plan.terminated:
            recon, self.state.gpis = estimator.final_surface(
                recon, map_vertices, contacts, timings, (model.name, *pose))
        else:
            recon = estimator.reported(recon, contacts, timings)
        return self._snapshot(belief, model, pose, map_vertices, recon, plan, paths,
                              observations, timings, decision)

    def _snapshot(self, belief, model, pose, map_vertices, recon, plan, paths,
                  observations, timings, decision):
        """Record the step's :class:`Snapshot`, with the evaluator's errors (untimed)."""
        errors = {} if self.evaluator is None else self.evaluator.errors(
            model, *pose, recon, self.filter.contact_positions, plan.terminated)
        snapshot = step_snapshot(self.step_count + 1, self.filter, self.state, belief,
                                 (model, pose, map_vertices), recon, plan, decision,
                                 (paths, observations, timings), errors)
        self.snapshots.append(snapshot)
        return snapshot

    def save(self, path: str | os.PathLike) -> str | os.PathLike:
        """Save the session (set-up, observations) to an ``.npz`` file: :func:`save_session`."""
        return save_session(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike,
             callback: Callable[[Snapshot], object] | None = None) -> Session:
        """Rebuild a saved session by replaying its steps: :func:`load_session`."""
        return load_session(path, cls.from_setup, callback)
