"""The inference session: Algorithm 2 of the paper, one step at a time.

A :class:`Session` couples a prior library, the particle filter, the GPIS and an
exploration strategy with a source of touches. Each :meth:`Session.step` touches a
simulated object once (after the random first contact: reach for the target chosen last
step, or an RRT step); :meth:`Session.observe` takes the touches of a real sensor or a
recording instead, after :meth:`Session.propose` said where to touch. Either way the step
updates the belief, reconstructs the surface when the object is judged novel, measures
coverage (DHD) and, with a simulated object, the errors against it, picks the next target
and returns an immutable :class:`Snapshot`. Parameters live in :mod:`.params`, saving and
loading in :mod:`.persistence`.
"""

import time
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .errors import TactileVizError
from .exploration import (STRATEGIES, clearest_direction, enforce_contact_moves,
                          farthest_vertex, first_contact_moves, next_sweep_direction,
                          path_until, raster_path, rrt_moves, variance_target, widest_gap)
from .gpis import (ThinPlateKernel, WendlandKernel, carved_prior, fit_gpis,
                   zero_level_surface)
from .metrics import directed_hausdorff, pose_difference, surface_samples, two_way_hausdorff
from .metrics import pose_error as metric_pose_error
from .objects import ObjectModel
from .observation_file import RecordedStep
from .observations import Contact, NonContact
from .params import (PAPER_SIZE, SESSION_PRESETS, SessionParams, noise_matched, scaled_lengths,
                     session_preset)
from .particle_filter import ParticleFilter
from .sdf import normalise_rows
from .simulator import ContactSimulator, GroundTruth
from .transforms import random_pose, transform_points


class SessionError(TactileVizError):
    """A session cannot be run, saved or loaded as asked."""


HYPOTHESES = 4  # poses after the MAP in each snapshot (the viewer's belief ghosts)
# Lengths in size units (a sixth of the object's longest side; see .params):
SWEEP_RADIUS = 10.0  # a check line runs this far on either side of its point
SWEPT_SPACING = 0.25  # samples of the paths the sensor swept, for the gaps of check lines
MAX_RASTER_RADIUS = 1.0  # a check sweeps at most the cube inside this ball about its gap
CONTACT_PRECISION = 0.01  # without a simulator: contacts closer than this are one touch
RRT_MARGIN = 3.0  # the RRT's workspace: the contacts' box grown by this
FIRST_LINE_REACH = 10.0  # the random first lines run this far on either side of the origin


def _frozen(array):
    array = np.array(array)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything a viewer or a benchmark needs after one step (arrays are read-only).

    Frames: everything is in the world frame. ``truth_coverage``, ``pose_error`` and
    ``recon_error`` are None in a session without a simulated object. ``gpis_resolution``
    is the marching-cubes cells of the GPIS surface (``final_resolution`` on the step that
    stops; None without a surface).
    """

    step: int
    new_observations: tuple
    paths: tuple
    contacts: np.ndarray
    normals: np.ndarray
    noncontacts: np.ndarray
    free_space: np.ndarray
    map_class: str
    map_rotation: np.ndarray
    map_translation: np.ndarray
    map_vertices: np.ndarray
    map_faces: np.ndarray
    class_posterior: dict
    n_particles: int
    log_evidence: float
    log_threshold: float
    novel: bool
    gpis_vertices: object
    gpis_faces: object
    gpis_variance: object
    gpis_scale: object
    target: object
    dhd: float
    truth_coverage: object
    pose_error: object
    recon_error: object
    terminated: bool
    timings: dict
    hypotheses: tuple = ()
    gpis_resolution: object = None
    rotation_error_deg: object = None
    translation_error: object = None

    def record(self):
        """The JSON record of this step (the ``trial`` command's contract)."""
        return {"t": self.step, "map_class": self.map_class, "pose_error": self.pose_error,
                "dhd": self.dhd, "truth_coverage": self.truth_coverage, "novel": self.novel,
                "recon_error": self.recon_error,
                "n_particles": self.n_particles, "n_contacts": int(len(self.contacts)),
                "n_noncontacts": int(len(self.noncontacts)),
                "step_seconds": float(sum(self.timings.values())),
                "timings": {k: float(v) for k, v in self.timings.items()},
                "rotation_error_deg": self.rotation_error_deg,
                "translation_error": self.translation_error,
                "gpis_scale": self.gpis_scale,
                "map_rotation": self.map_rotation.tolist(),
                "map_translation": self.map_translation.tolist()}


def _hypotheses(state, count=HYPOTHESES):
    """The ``count`` heaviest distinct poses of the filter after its MAP, as
    ``(class name, rotation, translation, weight)`` (weights of the duplicates summed)."""
    particles = getattr(state, "particles", None)
    if particles is None or len(particles) < 2:
        return ()
    weights = np.exp(particles.log_weights)
    keys = np.column_stack([particles.classes, particles.translations.round(3),
                            particles.rotations.reshape(len(particles), -1).round(3)])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    totals = np.bincount(inverse, weights, minlength=len(first))
    map_group = inverse[np.argmax(particles.log_weights)]  # drawn on its own
    order = [k for k in np.argsort(-totals) if k != map_group][:count]
    return tuple((state.class_names[particles.classes[first[k]]],
                  _frozen(particles.rotations[first[k]]),
                  _frozen(particles.translations[first[k]]), float(totals[k]))
                 for k in order)


class PosedSDF:
    """A model's SDF placed at a pose: ``field(points) -> (values (k,), gradients (k, 3))``
    for (k, 3) world points. Callables of a session are classes, not closures, so that a
    session pickles (the app steps it in another process); this one holds the model, not
    its grid, so that a pickle can name the model instead of copying the grid."""

    def __init__(self, model, rotation, translation):
        self.model, self.rotation, self.translation = model, rotation, translation

    def __call__(self, points):
        values, gradients = self.model.sdf.evaluate(
            (np.atleast_2d(points) - self.translation) @ self.rotation)
        return values, gradients @ self.rotation.T


class ValueOf:
    """The values of a field returning ``(values, gradients)``."""

    def __init__(self, field):
        self.field = field

    def __call__(self, points):
        return self.field(points)[0]


class BelowTangentPlane:
    """``min(signed height above the plane through position, outside(points))``: the full
    depth across the tangent plane, short of what ``outside`` predicts."""

    def __init__(self, position, normal, outside):
        self.position, self.normal, self.outside = position, normal, outside

    def __call__(self, points):
        return np.minimum((points - self.position) @ self.normal, self.outside(points))


@dataclass(frozen=True)
class Reconstruction:
    """The GPIS estimate of a novel object in one step.

    Attributes
    ----------
    vertices : (v, 3) float
        The zero level set of the posterior mean (marching cubes), world frame.
    faces : (f, 3) int
    variance : (v,) float
        Posterior variance at the vertices (evaluated at ``subset``, nearest elsewhere).
    subset : (k,) int or None
        The vertices where the variance was evaluated.
    fit : GPISFit
    resolution : int
        Marching-cubes cells along the box's longest side.
    """

    vertices: np.ndarray
    faces: np.ndarray
    variance: np.ndarray
    subset: object
    fit: object
    resolution: int

    @property
    def empty(self):
        return len(self.vertices) == 0


@dataclass(frozen=True)
class Target:
    """Where the session wants the next touch.

    Attributes
    ----------
    position : (3,) float
        The point to touch, world frame.
    normal : (3,) float
        The estimated outward normal there: approach along ``-normal``.
    depth : float
        How far beyond ``position`` to probe (the estimate's deepest point within the
        probe depth).
    clearance : float
        How far outside ``position`` the approach starts (short of any part the estimate
        predicts on the way).
    path : (k, 3) float or None
        A check (``check_lines``): the polyline to sweep instead of an approach; the first
        touch along it is the step's first observation.
    """

    position: np.ndarray
    normal: np.ndarray
    depth: float
    clearance: float = 0.5
    path: object = None


@dataclass(frozen=True)
class Move:
    """A guarded move the session asks of the sensor: move along ``path`` and stop at the
    first contact.

    Attributes
    ----------
    path : (k, 3) float
        The polyline, world frame, scene units (k >= 2).
    kind : {"first", "target", "check", "rrt"}
        The procedure the move belongs to: random lines until the first contact, contact
        enforcement toward a target (the probe, then after a miss the way back to the
        nearest contact and the in-contact steps along the surface), a check line, an RRT
        step.
    number : int
        The move's place in its step (0 first).
    target : (3,) float or None
        The target the step reaches for (``kind == "target"``).
    """

    path: np.ndarray
    kind: str
    number: int
    target: object = None


def _one_move(path):
    """A procedure of one guarded move: returns ``([path], [result])``."""
    result = yield path
    return [path], [result]


class Session:
    """Active exploration of one object with one prior library: Algorithm 2, step by step.

    The sensor contract is a guarded move (:class:`Move`): move along a path and stop at the
    first contact, answering with the :class:`Contact` or a :class:`NonContact` at the path's
    end. The session, not the sensor, carries out contact enforcement and surface
    following by asking for such moves. Two ways to drive it, one code path:

    - callback: a ``sensor`` with ``probe(path) -> Contact | NonContact`` (the simulator
      when ``truth`` is given, or a robot); :meth:`step` runs a whole step;
    - ask/tell: ``move = session.propose()``, the robot carries it out,
      ``session.observe(result)``; ``observe`` returns the step's :class:`Snapshot` when the
      step is complete, else None (more moves are needed).

    :meth:`observe` also takes a whole step's observations (a list), as a recording gives
    them. Misses before the first contact are kept until it comes. Without a truth the
    error metrics of the snapshots are None.

    Parameters
    ----------
    truth : GroundTruth or None
        The simulated object; None for a session fed by :meth:`observe`.
    library : PriorLibrary
    strategy : {"gpis-dhd", "rrt"}
    params : SessionParams, optional
    seed : int
        Seeds the filter, the exploration and the simulator noise.
    sensor_noise : tuple of float
        ``(position std in scene units, normal std in degrees)`` of the sensor: the
        simulator adds it, and the model assumes it (the likelihood's widths grow with it,
        :func:`~.params.noise_matched`, and so does the GPIS's observation noise).
    sensor_outliers : float
        The simulated sensor's chance of a wrong contact (``ContactSimulator``); the model's
        is ``params.filter.outlier_probability``.
    sensor : object, optional
        A robot: ``sensor.probe(path)`` carries out one guarded move (ignored with a truth,
        whose simulator is the sensor).
    """

    def __init__(self, truth, library, strategy="gpis-dhd", params=None, seed=0,
                 sensor_noise=(0.0, 0.0), sensor=None, sensor_outliers=0.0):
        if strategy not in STRATEGIES:
            raise SessionError(f"unknown strategy {strategy!r}; choose from {', '.join(STRATEGIES)}")
        if len(library) == 0:
            raise SessionError("the prior library is empty")
        self.truth = truth
        self.library = library
        self.strategy = strategy
        self.params = params or SessionParams()
        self.seed = int(seed)
        self.sensor_noise = tuple(float(v) for v in sensor_noise)
        self.rng = np.random.default_rng([self.seed, 1])
        self.simulator = None
        self.sensor = sensor
        self._truth_samples = None
        if truth is not None:
            self.simulator = ContactSimulator(truth, position_noise=self.sensor_noise[0],
                                              normal_noise_deg=self.sensor_noise[1],
                                              rng=np.random.default_rng([self.seed, 2]),
                                              outlier_fraction=sensor_outliers)
            self.sensor = self.simulator
            self._truth_samples = transform_points(
                surface_samples(truth.model, self.params.metric_samples), truth.rotation,
                truth.translation)
        # The filter's lengths scale with the library, which all classes share.
        self._filter_unit = self.params.length_unit or library.reference_size / PAPER_SIZE
        filter_params = scaled_lengths(self.params.filter, self._filter_unit)
        if any(self.sensor_noise):
            filter_params = noise_matched(filter_params, *self.sensor_noise)
        self.filter = ParticleFilter(library, filter_params,
                                     rng=np.random.default_rng([self.seed, 3]))
        self.snapshots = []
        self._p, self._unit = scaled_lengths(self.params, self._filter_unit), self._filter_unit
        self._scale = self._p.gpis_scale
        self._target = None
        self._given_up_targets = []
        self._free_space = np.zeros((0, 3))
        self._swept = np.zeros((0, 3))  # approach paths up to their first touch
        self._frontier = []  # (position, normal) beside contacts on unpredicted parts
        self._frontier_target = False  # whether the current target came from it
        self._check = None  # (estimate's vertices, point, direction, path) while a check is due
        self._check_directions = []
        self._checks_passed = 0
        # The step in progress: the session rng's state when it began, the results of its
        # guarded moves so far, observations held before the first contact.
        self._moves_rng = None
        self._results = []
        self._held = None
        self._live = None  # (kind, procedure, rng, path): transient, rebuilt by replay

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_live"] = None  # a running generator does not pickle; it is replayed
        return state

    @property
    def step_count(self):
        return len(self.snapshots)

    @property
    def terminated(self):
        return bool(self.snapshots) and self.snapshots[-1].terminated

    @property
    def latest(self):
        return self.snapshots[-1] if self.snapshots else None

    def run(self, max_steps=None, callback=None):
        """Step until termination (or ``max_steps`` more steps); returns the last snapshot."""
        while not self.terminated and (max_steps is None or max_steps > 0):
            snapshot = self.step()
            if callback is not None:
                callback(snapshot)
            if max_steps is not None:
                max_steps -= 1
        return self.latest

    def step(self):
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
        saved = self._checkpoint()
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
            self._restore(saved)
            raise

    def propose(self):
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
        target = (self._target[0] if kind == "target" else None)
        return Move(_frozen(path), kind, len(self._results),
                    None if target is None else _frozen(target))

    def _live_procedure(self):
        """The step's procedure of guarded moves, advanced to the next move: built from the
        state at the step's start and replayed with the results so far when it is not
        running (after a pickle, a copy or a rollback)."""
        if self._live is not None:
            return self._live
        if self._moves_rng is None:
            self._moves_rng = self.rng.bit_generator.state
        rng = np.random.Generator(type(self.rng.bit_generator)())
        rng.bit_generator.state = self._moves_rng
        kind, procedure = self._procedure(rng)
        path = next(procedure)
        for result in self._results:
            path = procedure.send(result)
        self._live = (kind, procedure, rng, path)
        return self._live

    def _procedure(self, rng):
        """``(kind, generator of guarded moves)`` for the step: lines 2-4 of Algorithm 2
        (reach for the target chosen last step) or the first touch, a check, an RRT step."""
        contacts, normals = self.filter.contact_positions, self.filter.contact_normals
        p, unit = self._p, self._unit
        if len(contacts) == 0 or (self._target is None and self._check is None
                                  and self.strategy != "rrt"):
            return "first", first_contact_moves(
                np.zeros(3), rng, radius=FIRST_LINE_REACH * self._filter_unit,
                unit=self._filter_unit)
        if self.strategy == "rrt":
            low, high = contacts.min(axis=0) - RRT_MARGIN * unit, contacts.max(axis=0) + RRT_MARGIN * unit
            return "rrt", rrt_moves(contacts, normals, (low, high), rng, p.rrt_step,
                                    p.probe_depth, 0.5 * unit, unit)
        if self._check is not None:
            return "check", _one_move(self._check[3])
        target, normal, estimate = self._target
        depth = deepest_inside(estimate, target, normal, p.probe_depth)
        clearance = free_approach(estimate, target, normal, p.approach_clearance, unit)
        # The way back ends two simulator steps inside the anchor (1/150 of the size).
        back = 2 * getattr(self.sensor, "step", unit * PAPER_SIZE / 300)
        return "target", enforce_contact_moves(
            target, normal, contacts, normals, depth, clearance, p.follow_step,
            p.contact_spacing, p.max_follow, back)

    def _observe_move(self, result, timings):
        """Take the result of the current guarded move; the step's snapshot when its
        procedure is done, else None."""
        self._use_lengths()
        kind, procedure, rng, _ = self._live_procedure()
        self._results.append(result)
        try:
            path = procedure.send(result)
        except StopIteration as done:
            self.rng.bit_generator.state = rng.bit_generator.state
            self._moves_rng, self._results, self._live = None, [], None
            paths, observations = self._after_moves(kind, done.value)
            return self._update(paths, observations, timings)
        self._live = (kind, procedure, rng, path)
        return None

    def _after_moves(self, kind, done):
        """What a finished procedure leaves besides its observations: the swept space, the
        given-up target, the check's count, the frontier, the missed probe's free space."""
        if kind == "check":
            (path,), observations = done
            self._record_sweep(observations[0])
            self._count_check(observations[0])
            if not isinstance(observations[0], Contact):
                spacing = self._p.contact_spacing
                self._free_space = thin_points(np.vstack([self._free_space, path_until(
                    path, path[-1], spacing, 0.05 * self._unit)]), spacing)
            return [path], observations
        if kind != "target":
            return done
        paths, observations, reached = done
        target = self._target[0]
        self._record_sweep(observations[0], paths[0][0])  # the approach's start
        if not reached or self._repeats_contact(observations[-1]):
            self._given_up_targets.append(target)
        self._follow_frontier(observations[-1])
        if not isinstance(observations[0], Contact):
            self._free_space = free_space_points(self._free_space, paths[0],
                                                 self._p.contact_spacing)
        return paths, observations

    def observe(self, observations, free_space=None):
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
        The proposed target is given up as the simulated contact enforcement does: when no
        contact was made, when the first touch missed and the last contact lies within
        ``contact_spacing`` of an earlier one, or when a contact repeats an earlier one.
        After a proposed check the first observation is where its sweep first touched. The session keeps
        accepting observations after it would have stopped (``terminated``).
        A step that fails leaves the session exactly as it was before it.
        """
        if isinstance(observations, (Contact, NonContact)):
            if free_space is not None:
                raise SessionError("free_space goes with a whole step's observations")
            saved = self._checkpoint()
            try:
                return self._observe_move(observations, {})
            except BaseException:
                self._restore(saved)
                raise
        if self._results:
            raise SessionError("a guarded move is pending: observe its result (one Contact "
                               "or NonContact) before a whole step")
        observations = list(observations)
        if not observations:
            raise SessionError("a step needs at least one observation")
        for observation in observations:
            if not isinstance(observation, (Contact, NonContact)):
                raise SessionError(f"not an observation: {observation!r} (use Contact or "
                                   "NonContact)")
        points = np.asarray(np.zeros((0, 3)) if free_space is None else free_space, float)
        if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
            raise SessionError("free_space must be a finite (k, 3) array of points")
        self._use_lengths()
        saved = self._checkpoint()
        try:
            contacts = [o for o in observations if isinstance(o, Contact)]
            if self._held is not None:
                observations = self._held[0] + observations
                points = np.vstack([self._held[1], points])
                self._held = None
            if not contacts and len(self.filter.contact_positions) == 0:
                self._held = (observations, points)  # no estimate before a contact
                return None
            self._record_sweep(observations[0], self._approach_start())
            if self._check is not None:
                self._count_check(observations[0])
            elif self._target is not None:
                if not self._reached(observations, contacts):
                    self._given_up_targets.append(self._target[0])
                self._follow_frontier(observations[-1])
            if len(points):
                self._free_space = thin_points(np.vstack([self._free_space, points]),
                                               self._p.contact_spacing)
            return self._update([], observations, {})
        except BaseException:
            self._restore(saved)
            raise

    def recorded_steps(self):
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

    def _checkpoint(self):
        return (self.filter.checkpoint(),
                [g.bit_generator.state for g in self._generators()],
                (self._scale, self._target, list(self._given_up_targets), self._free_space,
                 self._swept, len(self.snapshots)),
                (self._check, list(self._check_directions), self._checks_passed,
                 list(self._frontier), self._frontier_target),
                (self._moves_rng, list(self._results), self._held))

    def _restore(self, saved):
        (filter_state, generator_states, (scale, target, given_up, free, swept, count), check,
         (self._moves_rng, self._results, self._held)) = saved
        self._live = None
        (self._check, self._check_directions, self._checks_passed, self._frontier,
         self._frontier_target) = check
        self.filter.restore(filter_state)
        for generator, state in zip(self._generators(), generator_states):
            generator.bit_generator.state = state
        self._scale, self._target, self._given_up_targets = scale, target, given_up
        self._free_space, self._swept = free, swept
        del self.snapshots[count:]

    def _use_lengths(self, model=None):
        """Set ``self._p``, the parameters with their lengths in scene units, and
        ``self._unit``, the scene units of a size unit: a sixth of the longest side of
        ``model``, default the latest MAP object (the library's reference size before the
        first step), or ``params.length_unit``. Derived from the snapshots, so rollbacks and
        copies of a session need not keep it."""
        if model is None and self.snapshots:
            model = self.filter.models[self.filter.class_names.index(self.latest.map_class)]
        unit = self.params.length_unit or (model.size_unit if model is not None
                                           else self._filter_unit)
        if unit != self._unit:
            self._p, self._unit = scaled_lengths(self.params, unit), unit
        return self._p

    def _generators(self):
        return (self.rng,) if self.simulator is None else (self.rng, self.simulator.rng)

    def _update(self, paths, observations, timings):
        """Lines 5-15 of Algorithm 2 after the touch: the filter's update, the estimate
        (MAP shape; GPIS when novel), the stop test and the next target."""
        clock = time.perf_counter()
        state = self.filter.update(observations)
        timings["filter"] = time.perf_counter() - clock

        model = self.filter.models[self.filter.class_names.index(state.map_class)]
        self._use_lengths(model)
        rotation, translation = state.map_rotation, state.map_translation
        map_vertices = transform_points(model.mesh.vertices, rotation, translation)
        contacts, normals = self.filter.contact_positions, self.filter.contact_normals
        recon = None
        if state.novel:
            recon = self._reconstruct(model, rotation, translation, map_vertices, timings)
        clock = time.perf_counter()
        dhd, terminated = self._stop_and_target(state, model, rotation, translation,
                                                map_vertices, recon, contacts)
        timings["target"] = time.perf_counter() - clock
        if terminated:
            recon = self._final_surface(recon, map_vertices, contacts, timings)

        clock = time.perf_counter()
        pose_error, recon_error, truth_coverage = self._truth_metrics(
            model, rotation, translation, recon, contacts)
        timings["metrics"] = time.perf_counter() - clock

        snapshot = Snapshot(
            step=self.step_count + 1, new_observations=tuple(observations),
            paths=tuple(_frozen(p) for p in paths), contacts=_frozen(contacts),
            normals=_frozen(normals), noncontacts=_frozen(self.filter.noncontact_positions),
            free_space=_frozen(self._free_space),
            map_class=state.map_class, map_rotation=_frozen(rotation),
            map_translation=_frozen(translation), map_vertices=_frozen(map_vertices),
            map_faces=model.mesh.faces, class_posterior=dict(state.class_posterior),
            n_particles=state.n_particles, log_evidence=float(state.log_evidence),
            log_threshold=float(state.log_threshold), novel=bool(state.novel),
            gpis_vertices=None if recon is None else _frozen(recon.vertices),
            gpis_faces=None if recon is None else _frozen(recon.faces),
            gpis_variance=None if recon is None else _frozen(recon.variance),
            gpis_scale=float(self._scale) if recon is not None else None,
            target=None if self._target is None else _frozen(self._target[0]),
            dhd=float(dhd), truth_coverage=truth_coverage, pose_error=pose_error,
            recon_error=recon_error, terminated=terminated, timings=timings,
            hypotheses=_hypotheses(state),
            gpis_resolution=None if recon is None else recon.resolution,
            **self._pose_difference(model, rotation, translation))
        self.snapshots.append(snapshot)
        return snapshot

    def _stop_and_target(self, state, model, rotation, translation, map_vertices, recon,
                         contacts):
        """The DHD of the estimate, whether to stop, and the next target (kept in
        ``self._target``); returns ``(dhd, terminated)``."""
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
        frontier = exploring and bool(self._frontier)
        checking = (covered and exploring and not frontier
                    and self._checks_passed < self._p.check_lines)
        terminated = bool((covered and not checking and not frontier)
                          or self.step_count + 1 >= cap)
        self._check, self._frontier_target = None, False
        if recon is not None and not recon.empty:
            outside = recon.fit.mean_value
        else:
            outside = ValueOf(self._prior(model, rotation, translation))
        if terminated:
            self._target = None
        elif frontier:
            position, normal = self._frontier.pop(0)
            # Probe the full depth across the tangent plane (the estimate has no surface
            # here), but approach short of what the estimate does predict.
            self._target = (position, normal, BelowTangentPlane(position, normal, outside))
            self._frontier_target = True
        elif checking:
            self._target = None
            self._check = self._plan_check_line(surface, contacts, outside)
        elif dhd <= self._p.eps < prior_dhd:
            # The reconstruction is covered, but part of the prior it came from is neither
            # touched nor refuted: the object may extend there.
            self._target = self._next_target(map_vertices, prior_open, None, model, rotation,
                                             translation, contacts)
        else:
            self._target = self._next_target(surface, reachable, recon, model, rotation,
                                             translation, contacts)
        return max(dhd, prior_dhd), terminated

    def _pose_difference(self, model, rotation, translation):
        """``rotation_error_deg`` and ``translation_error`` of the MAP against the simulated
        object (None without one, or when the MAP is another shape)."""
        if self.truth is None:
            return {}
        angle, distance = pose_difference(model, rotation, translation, self.truth)
        return {"rotation_error_deg": angle, "translation_error": distance}

    def _truth_metrics(self, model, rotation, translation, recon, contacts):
        """Pose error, reconstruction error and truth coverage against the simulated
        object (None without one; the reconstruction error also while known)."""
        if self.truth is None:
            return None, None, None
        pose_error = metric_pose_error(model, rotation, translation, self.truth,
                                       self._p.metric_samples)
        recon_error = None
        if recon is not None and len(recon.faces):
            mesh = trimesh.Trimesh(recon.vertices, recon.faces, process=False)
            samples, _ = trimesh.sample.sample_surface(mesh, self._p.metric_samples, seed=0)
            recon_error = float(two_way_hausdorff(samples, self._truth_samples))
        return (float(pose_error), recon_error,
                directed_hausdorff(self._truth_samples, contacts))

    # ---------------------------------------------------------------- pieces
    def _plan_check_line(self, estimate, contacts, outside=None):
        """The next check: ``(estimate's vertices, its point, its direction, the path to
        sweep)``.

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
        kind = self._check_kind(len(self._check_directions))
        if kind == "weakest" and outside is not None:
            through, gap = self._weakest_support(estimate, contacts)
        elif kind in ("hull", "shell") and outside is not None:
            explored = np.vstack([contacts, self.filter.noncontact_positions,
                                  self._free_space, self._swept])
            # Checks alternate between gaps inside the contacts' hull and the shell just
            # outside the estimate (beyond the ends of parts it closes off).
            shell = 2 * self._p.eps if kind == "shell" else 0.0
            through, gap = widest_gap(contacts, explored, estimate, outside, shell=shell,
                                      unit=self._unit)
        if through is None:
            direction = next_sweep_direction(self._check_directions, self.rng)
            through = contacts[self.rng.integers(len(contacts))] + self.rng.normal(
                0.0, self._p.eps, size=3)
            path = np.stack([through + SWEEP_RADIUS * self._unit * direction,
                             through - SWEEP_RADIUS * self._unit * direction])
        else:
            unit = self._unit
            direction = clearest_direction(through, estimate, self._check_directions,
                                           reach=SWEEP_RADIUS * unit, unit=unit)
            path = raster_path(through, min(gap, MAX_RASTER_RADIUS * unit), direction,
                               spacing=0.2 * unit, reach=SWEEP_RADIUS * unit)
        self._check_directions.append(direction)
        return estimate, through, direction, path

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

    def _approach_start(self):
        """Where the approach to the current target starts (None without a target, and
        with RRT)."""
        if self._target is None or self.strategy == "rrt":
            return None
        position, normal, estimate = self._target
        return position + free_approach(estimate, position, normal,
                                        self._p.approach_clearance, self._unit) * normal

    def _record_sweep(self, touched, start=None):
        """Keep samples of the path the sensor swept up to its first touch: the planned
        check's path, else the straight approach from ``start`` (None: nothing to keep).
        Checks need not visit that space again."""
        if self._check is not None:
            spacing = SWEPT_SPACING * self._unit
            samples = path_until(self._check[3], touched.position, spacing, 0.05 * self._unit)
            self._swept = thin_points(np.vstack([self._swept, samples]), spacing)
        elif start is not None:
            self._swept = free_space_points(self._swept, np.stack([start, touched.position]),
                                            SWEPT_SPACING * self._unit)

    def _count_check(self, touched):
        """Count the check as passed unless it touched the object farther than
        ``contact_spacing`` from the estimate and from every contact (a part nothing
        predicted: the count restarts and the frontier grows from the touch)."""
        known = [points for points in (self._check[0], self.filter.contact_positions)
                 if len(points)]
        surprise = isinstance(touched, Contact) and min(
            cKDTree(points).query(touched.position)[0]
            for points in known) > self._new_ground()
        if surprise:
            self._checks_passed = 0
            self._grow_frontier(touched)
        elif self._check_kind(len(self._check_directions) - 1) != "weakest":
            # A sweep about the weakest support adds to the gap checks, never replaces one.
            self._checks_passed += 1

    def _check_kind(self, index):
        """What check number ``index`` (0 first) of the session aims at: ``"hull"`` and
        ``"shell"`` gaps in turn, with ``"gap-weakest"`` a ``"weakest"`` support after each
        pair; ``"contact"`` with ``check_line_aim = "contact"``."""
        aim = self._p.check_line_aim
        if aim == "contact":
            return "contact"
        kinds = ("hull", "shell", "weakest") if aim == "gap-weakest" else ("hull", "shell")
        return kinds[index % len(kinds)]

    def _follow_frontier(self, touched):
        """After a frontier target: a contact on new ground grows the frontier from it."""
        contacts = self.filter.contact_positions
        if (self._frontier_target and isinstance(touched, Contact) and len(contacts)
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
                               np.reshape(self._given_up_targets, (-1, 3)),
                               np.reshape([p for p, _ in self._frontier], (-1, 3))])
            if cKDTree(taken).query(point)[0] > self._new_ground():
                self._frontier.append((point, normal))

    def _reached(self, observations, contacts):
        """Whether touches made for the proposed target reached it (the rule of
        :func:`~.exploration.enforce_contact`)."""
        if not contacts or self._repeats_contact(contacts[-1]):
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

    def _reachable(self, vertices, radius=None):
        """Mask of the vertices that exploration may still have to visit: away from every
        target the sensor failed to reach and from the free space that missed probes
        passed through (within ``radius``, default ``contact_spacing``).

        The DHD and the next target leave the others out (all vertices count if none is
        left): probing there again cannot change the estimate, so the trial would only run
        to its step cap.
        """
        refuted = np.vstack([np.reshape(self._given_up_targets, (-1, 3)), self._free_space])
        if len(refuted) == 0:
            return np.ones(len(vertices), bool)
        radius = self._p.contact_spacing if radius is None else radius
        far = cKDTree(refuted).query(vertices)[0] >= radius
        return far if far.any() else np.ones(len(vertices), bool)

    def _noncontact_points(self, noncontacts=None, free_space=None):
        """Where the sensor found no object: the non-contacts and the points along missed
        probes, one per quarter of the kernel's reach (what the GPIS's non-contact switch
        constrains)."""
        noncontacts = self.filter.noncontact_positions if noncontacts is None else noncontacts
        free_space = self._free_space if free_space is None else free_space
        reach = self._p.gpis_support if self._p.gpis_kernel == "wendland" else self._unit
        return np.vstack([noncontacts, thin_points(free_space, reach / 4)])

    def _prior(self, model, rotation, translation):
        return PosedSDF(model, rotation, translation)

    def _gpis_prior(self, model, rotation, translation, contacts, noncontacts, free_space):
        """The GPIS prior mean: the MAP shape with the refuted space cut out."""
        return carved_prior(self._prior(model, rotation, translation),
                            np.vstack([noncontacts, free_space]), contacts,
                            self._p.gpis_carve_radius)

    def _gpis_box(self, map_vertices, contacts):
        """The reconstruction box (low, high) and the GPIS kernel."""
        p = self._p
        low = np.minimum(map_vertices.min(axis=0), contacts.min(axis=0)) - p.gpis_margin
        high = np.maximum(map_vertices.max(axis=0), contacts.max(axis=0)) + p.gpis_margin
        if p.gpis_kernel == "wendland":
            return low, high, WendlandKernel(p.gpis_support)
        return low, high, ThinPlateKernel(p.gpis_radius_factor * float(np.linalg.norm(high - low)))

    def _fit(self, kernel, contacts, normals, noncontacts, prior, scale, newton=True):
        p = self._p
        # The sensor's position noise adds to the GPIS's observation noise (variances).
        return fit_gpis(contacts, normals, prior, kernel, scale=scale,
                        noise_variance=p.gpis_noise + self.sensor_noise[0] ** 2, newton=newton,
                        noncontacts=noncontacts if p.gpis_noncontacts else None,
                        noncontact_value=p.gpis_noncontact_value)

    def _reconstruct(self, model, rotation, translation, map_vertices, timings):
        p = self._p
        contacts, normals = self.filter.contact_positions, self.filter.contact_normals
        low, high, kernel = self._gpis_box(map_vertices, contacts)
        clock = time.perf_counter()
        prior = self._gpis_prior(model, rotation, translation, contacts,
                                 self.filter.noncontact_positions, self._free_space)
        fit = self._fit(kernel, contacts, normals, self._noncontact_points(), prior,
                        self._scale)
        self._scale = fit.scale
        timings["gpis"] = time.perf_counter() - clock
        clock = time.perf_counter()
        recon = self._surface(fit, (low, high), p.gpis_resolution)
        timings["surface"] = time.perf_counter() - clock
        return recon

    def _surface(self, fit, bounds, resolution):
        """The :class:`Reconstruction` of ``fit``: its zero level set on ``resolution``
        cells of the box ``bounds``, with the variance at up to ``variance_points``
        vertices."""
        vertices, faces = zero_level_surface(fit, bounds, resolution)
        variance, subset = np.zeros(len(vertices)), None
        if len(vertices):
            count = min(self._p.variance_points, len(vertices))
            subset = self.rng.choice(len(vertices), count, replace=False)
            variance[subset] = fit.variance(vertices[subset])
            if count < len(vertices):
                # Other vertices show the variance of the nearest evaluated one.
                nearest = cKDTree(vertices[subset]).query(vertices)[1]
                variance = variance[subset][nearest]
        return Reconstruction(vertices, faces, variance, subset, fit, resolution)

    def _final_surface(self, recon, map_vertices, contacts, timings):
        """The reconstruction a stopping session reports: the same fit at
        ``final_resolution`` (thin parts between the exploration grid's samples appear)."""
        if recon is None or recon.empty or (self._p.final_resolution
                                             == self._p.gpis_resolution):
            return recon
        clock = time.perf_counter()
        low, high, _ = self._gpis_box(map_vertices, contacts)
        final = self._surface(recon.fit, (low, high), self._p.final_resolution)
        timings["surface"] = timings.get("surface", 0.0) + time.perf_counter() - clock
        return recon if final.empty else final

    def _next_target(self, surface, reachable, recon, model, rotation, translation, contacts):
        """``(target, outward normal, estimate)``: the novel or the known rule of
        :mod:`.exploration`, with the estimate whose inside the probe depth is taken from."""
        if recon is not None and not recon.empty:
            index = variance_target(recon.vertices, recon.variance, recon.subset, reachable,
                                    contacts, self._p.eps if self._p.target_uncovered
                                    else None)
            target = recon.vertices[index]
            _, gradient = recon.fit.mean(target[None])
            return target, normalise_rows(gradient)[0], recon.fit.mean_value
        index = np.flatnonzero(reachable)[farthest_vertex(surface[reachable], contacts)]
        normal = model.mesh.vertex_normals[index] @ rotation.T
        estimate = ValueOf(self._prior(model, rotation, translation))
        return surface[index], normalise_rows(normal[None])[0], estimate

    # ---------------------------------------------------------------- learning
    def learned_model(self, name, snapshot=None, resolution=None):
        """The reconstructed surface of a novel snapshot as a new :class:`ObjectModel`.

        The snapshot's GPIS posterior mean (its contacts, MAP prior and kernel scale) is
        extracted at ``resolution`` (default ``params.learned_resolution``; a stopped
        session's last surface is already at ``params.final_resolution``); the
        largest connected piece of the zero level set is kept, and the model is checked and
        normalised like any loaded mesh.
        """
        snapshot = snapshot or self.latest
        if snapshot is None or snapshot.gpis_faces is None or len(snapshot.gpis_faces) == 0:
            raise SessionError("no reconstructed surface to learn from: the object was not "
                               "judged novel in this step")
        resolution = resolution or self._p.learned_resolution
        vertices, faces = snapshot.gpis_vertices, snapshot.gpis_faces
        if resolution != snapshot.gpis_resolution:
            vertices, faces = self._surface_at(snapshot, resolution)
        return learned_model_from_surface(vertices, faces, name,
                                          params=self.library[snapshot.map_class].params
                                          if snapshot.map_class in self.library else None)

    def _surface_at(self, snapshot, resolution):
        """The snapshot's GPIS zero level set on a grid of ``resolution`` cells."""
        model = self.filter.models[self.filter.class_names.index(snapshot.map_class)]
        self._use_lengths(model)
        prior = self._gpis_prior(model, snapshot.map_rotation, snapshot.map_translation,
                                 snapshot.contacts, snapshot.noncontacts, snapshot.free_space)
        low, high, kernel = self._gpis_box(snapshot.map_vertices, snapshot.contacts)
        fit = self._fit(kernel, snapshot.contacts, snapshot.normals,
                        self._noncontact_points(snapshot.noncontacts, snapshot.free_space),
                        prior,
                        snapshot.gpis_scale, newton=False)
        vertices, faces = zero_level_surface(fit, (low, high), resolution)
        if len(faces) == 0:
            raise SessionError("the reconstruction has no surface at the learned resolution")
        return vertices, faces

    # ---------------------------------------------------------------- persistence
    def save(self, path):
        """Save the session (its set-up and its observation history) to an ``.npz`` file;
        see :func:`tactile_viz.engine.persistence.save_session`."""
        from .persistence import save_session

        return save_session(self, path)

    @classmethod
    def load(cls, path, callback=None):
        """Rebuild a saved session by replaying its steps; see
        :func:`tactile_viz.engine.persistence.load_session`."""
        from .persistence import load_session

        return load_session(path, callback)


class RecordedSession(Session):
    """A session that steps through recorded touches: :meth:`step` gives the next recorded
    step to :meth:`~Session.observe`, and the session ends with the recording (not at the
    stop rule, which a recording may have passed long before).

    Parameters
    ----------
    steps : list of RecordedStep
        From :func:`~tactile_viz.engine.observation_file.read_observations`.
    library, strategy, params, seed
        As for :class:`Session` (the recording's seed reproduces its estimates exactly).
    source : str, optional
        Where the recording came from (shown by viewers).
    """

    def __init__(self, steps, library, strategy="gpis-dhd", params=None, seed=0, source=None,
                 sensor_noise=(0.0, 0.0)):
        super().__init__(None, library, strategy, params, seed, sensor_noise)
        self.recording = list(steps)
        self.source = source
        self.replayed = 0  # recorded steps given to the session (misses first are held)

    @property
    def terminated(self):
        return self.replayed >= len(self.recording)

    def step(self):
        """Replay recorded steps until one gives a snapshot (misses before the first
        contact join its step); at the recording's end without a contact, None."""
        if self.terminated:
            raise SessionError("the recording has been replayed to its end")
        snapshot = None
        while snapshot is None and not self.terminated:
            recorded = self.recording[self.replayed]
            snapshot = self.observe(recorded.observations, recorded.free_space)
            self.replayed += 1
        if snapshot is None:
            raise SessionError("the recording holds no contact: there is nothing to "
                               "estimate from misses alone")
        return snapshot


def free_space_points(points, path, spacing):
    """``points`` plus samples of a missed probe ``path``, one per grid cell of ``spacing``.

    Returns
    -------
    (k, 3) float
    """
    length = float(np.linalg.norm(path[-1] - path[0]))
    count = max(2, int(np.ceil(length / spacing)) + 1)
    samples = path[0] + np.linspace(0.0, 1.0, count)[:, None] * (path[-1] - path[0])
    return thin_points(np.vstack([points, samples]), spacing)


def thin_points(points, spacing):
    """The first of ``points`` in each grid cell of size ``spacing`` (order kept)."""
    if len(points) == 0:
        return points
    _, first = np.unique(np.floor(points / spacing).astype(np.int64), axis=0, return_index=True)
    return points[np.sort(first)]


def deepest_inside(estimate, target, normal, max_depth, samples=21):
    """How far to probe inward from ``target``: to the point the estimated surface puts
    deepest inside (within ``max_depth``), so that a miss there is a non-contact that the
    estimate most strongly contradicts; probing farther could leave a thin part again."""
    depths = np.linspace(0.0, max_depth, samples)
    values = estimate(target - depths[:, None] * normal)
    return float(max(depths[int(np.argmin(values))], max_depth / (samples - 1)))


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


def learned_model_from_surface(vertices, faces, name, params=None):
    """An :class:`ObjectModel` from a reconstructed surface (largest connected piece).

    The surface keeps its measured size: it is in the same world units as the object it was
    learned from, whereas scaling its (pose-dependent) bounding box to the bundled objects'
    size would change its size and spoil every later match.
    """
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    pieces = mesh.split(only_watertight=False)
    if len(pieces):
        mesh = max(pieces, key=lambda piece: abs(piece.area))
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, name, params=params,
                                   longest_side=None, learned=True)


def make_truth(model, rng=None, max_translation=1.0):
    """The ground truth of a trial: ``model`` at a random pose, translated up to
    ``max_translation`` size units (a sixth of its longest side each)."""
    rotation, translation = random_pose(rng, max_translation * model.size_unit)
    return GroundTruth(model, rotation, translation)


__all__ = ["Move", "Reconstruction", "RecordedSession", "Session", "SessionError", "SessionParams", "Snapshot", "Target",
           "session_preset", "SESSION_PRESETS", "learned_model_from_surface", "make_truth"]
