"""The inference session: Algorithm 2 of the paper, one step at a time.

A :class:`Session` couples a ground truth (through the simulator), a prior library, the
particle filter, the GPIS and an exploration strategy. Each :meth:`Session.step` touches
once (after the random first contact: reach for the target chosen last step, or an RRT
step), updates the belief, reconstructs the surface when the object is judged novel,
measures coverage (DHD) and errors against the truth, picks the next target and returns an
immutable :class:`Snapshot`.
"""

import io
import json
import time
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .files import write_atomic
from .errors import ParameterError, TactileVizError
from .exploration import (STRATEGIES, enforce_contact, farthest_vertex, first_contact,
                          next_sweep_direction, rrt_step, sweep_line)
from .gpis import (ThinPlateKernel, WendlandKernel, carved_prior, fit_gpis,
                   zero_level_surface)
from .library import PriorLibrary
from .metrics import directed_hausdorff, surface_samples, two_way_hausdorff
from .metrics import pose_error as metric_pose_error
from .objects import ObjectModel
from .meshes import check_arrays
from .observations import Contact
from .params import FilterParams, _check_integer, _check_real, preset
from .particle_filter import ParticleFilter
from .sdf import normalise_rows
from .simulator import ContactSimulator, GroundTruth
from .transforms import random_pose, transform_points


class SessionError(TactileVizError):
    """A session cannot be run, saved or loaded as asked."""


GPIS_KERNELS = ("wendland", "thin-plate")
HYPOTHESES = 4  # poses after the MAP in each snapshot (the viewer's belief ghosts)


@dataclass(frozen=True)
class SessionParams:
    """Knobs of a session beyond the filter's (paper, Table I and Section III-H).

    Attributes
    ----------
    filter : FilterParams
    eps : float
        Termination threshold on the DHD from the estimated surface (and, with
        ``cover_prior``, the MAP prior of a novel object) to the contacts; the surface near
        targets the sensor could not reach and near missed probes' paths is left out.
    max_steps_known, max_steps_novel : int
        Step caps while the object is judged known / novel (paper 300 / 400).
    gpis_noise : float
        Observation noise variance of the GPIS (paper 1e-4).
    gpis_scale : float
        Initial kernel scale ``a_0``.
    gpis_resolution : int
        Marching-cubes cells along the longest side of the reconstruction box.
    gpis_margin : float
        Margin of the reconstruction box around the MAP shape and the contacts.
    gpis_kernel : {"thin-plate", "wendland"}
        ``thin-plate``: the paper's kernel, whose correction reaches the whole box (the
        default: with the carved prior and prior coverage it reconstructed 10 novel trials
        to a mean TWD of 0.80 against the Wendland kernel's 1.08, in 33 s against 55 s per
        trial, docs/benchmarks.md); ``wendland``: compactly supported, a contact corrects
        the prior only within ``gpis_support``.
    gpis_support : float
        Support radius ``c`` of the Wendland kernel.
    gpis_radius_factor : float
        Thin-plate ``R`` over the reconstruction box's diagonal (which bounds every
        distance involved): 1.0 is the paper's "largest distance" (the indefinite Gram
        matrix is projected on the PSD cone), 1.2 makes it positive definite.
    gpis_noncontacts : bool
        Beyond the paper: non-contacts where the prior puts the inside observe
        ``f = gpis_noncontact_value`` (value only), which removes the prior's surface where
        a probe passed through it.
    gpis_noncontact_value : float
    gpis_carve_radius : float
        Beyond the paper: the GPIS prior mean has a ball of this radius (at most the
        distance to the nearest contact) cut out of the MAP shape around every non-contact
        and every sample of a missed probe's path, so a probe through a phantom part of a
        wrong prior removes it there; 0 keeps the prior whole.
    cover_prior : bool
        Beyond the paper: a novel object's exploration also has to cover the MAP prior's
        surface (within ``eps`` of a contact, or refuted by a missed probe), so that a
        reconstruction that shrank away from the untouched prior cannot pass the stop.
    target_uncovered : bool
        Beyond the paper: the GPIS-DHD target is the largest variance among the surface
        vertices still farther than ``eps`` from every contact (the paper's, the default:
        among all; restricting it stopped home_chair and noisy_dino earlier with less of
        the object touched, seed 0).
    check_lines : int
        Beyond the paper: once a novel object's estimate is covered, this many straight
        lines (from directions spread over the sphere, each through a random contact moved
        by about ``eps``) must each touch nothing farther than ``eps`` from the estimate and from every
        contact before the session stops; a line that does restarts the count, since part of
        the object was never predicted. 0: stop as soon as the estimate is covered (paper).
    variance_points : int
        Surface vertices at which the GPIS variance is evaluated (a random subset).
    learned_resolution : int
        Marching-cubes cells along the longest side when a reconstruction is kept as a new
        prior: the same posterior mean as the step's surface, sampled finer, since a learned
        shape is extracted once and matched against every later contact.
    probe_depth : float
        How deep contact enforcement reaches at most (the estimate's deepest point within
        it is probed).
    follow_step : float
        Length of one in-contact surface-following step of contact enforcement.
    contact_spacing : float
        Surface following stops at a contact this far from every earlier one; a target
        whose procedure ends nearer is given up.
    max_follow : float
        Longest surface-following path of one step.
    rrt_step : float
    metric_samples : int
        Surface samples per shape for the error metrics (TWD).
    """

    filter: FilterParams = field(default_factory=FilterParams)
    eps: float = 0.6
    max_steps_known: int = 300
    max_steps_novel: int = 400
    gpis_noise: float = 1e-4
    gpis_scale: float = 1.0
    gpis_resolution: int = 32
    gpis_margin: float = 0.6
    gpis_kernel: str = "thin-plate"
    gpis_support: float = 4.0
    gpis_radius_factor: float = 1.2
    gpis_noncontacts: bool = False
    gpis_noncontact_value: float = 0.1
    gpis_carve_radius: float = 0.6
    cover_prior: bool = True
    target_uncovered: bool = False
    check_lines: int = 0
    variance_points: int = 1500
    learned_resolution: int = 64
    probe_depth: float = 1.0
    follow_step: float = 0.1
    contact_spacing: float = 0.3
    max_follow: float = 3.0
    rrt_step: float = 0.3
    metric_samples: int = 3000

    def __post_init__(self):
        if not isinstance(self.filter, FilterParams):
            raise ParameterError(f"filter must be FilterParams, got {type(self.filter).__name__}")
        if self.gpis_kernel not in GPIS_KERNELS:
            raise ParameterError(f"gpis_kernel must be one of {', '.join(GPIS_KERNELS)}, "
                                 f"got {self.gpis_kernel!r}")
        for name in ("gpis_noncontacts", "cover_prior", "target_uncovered"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ParameterError(f"{name} must be True or False, "
                                     f"got {getattr(self, name)!r}")
        for name in ("eps", "gpis_noise", "gpis_scale", "gpis_margin", "gpis_support",
                     "gpis_radius_factor", "gpis_noncontact_value", "probe_depth",
                     "follow_step", "contact_spacing", "max_follow", "rrt_step"):
            value = getattr(self, name)
            _check_real(name, value)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
        _check_real("gpis_carve_radius", self.gpis_carve_radius)
        if not (np.isfinite(self.gpis_carve_radius) and self.gpis_carve_radius >= 0):
            raise ParameterError("gpis_carve_radius must be a finite number >= 0, "
                                 f"got {self.gpis_carve_radius!r}")
        object.__setattr__(self, "check_lines", _check_integer("check_lines", self.check_lines))
        if self.check_lines < 0:
            raise ParameterError(f"check_lines must be at least 0, got {self.check_lines!r}")
        for name in ("max_steps_known", "max_steps_novel", "variance_points", "metric_samples",
                     "gpis_resolution", "learned_resolution"):
            object.__setattr__(self, name, _check_integer(name, getattr(self, name)))
            if getattr(self, name) < 1:
                raise ParameterError(f"{name} must be at least 1, got {getattr(self, name)!r}")
        for name in ("gpis_resolution", "learned_resolution"):
            if getattr(self, name) < 8:
                raise ParameterError(f"{name} must be at least 8, got {getattr(self, name)!r}")

    def to_dict(self):
        values = asdict(self)
        values["filter"] = self.filter.to_dict()
        return values

    @classmethod
    def from_dict(cls, values):
        if not isinstance(values, dict):
            raise ParameterError(f"session parameters must be a dict, got {type(values).__name__}")
        values = dict(values)
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ParameterError(f"unknown session parameter(s): {', '.join(sorted(unknown))}")
        values["filter"] = FilterParams.from_dict(values.get("filter", {}))
        return cls(**values)


SESSION_PRESETS = {
    "fast": SessionParams(filter=preset("fast"), gpis_resolution=24, variance_points=800,
                          metric_samples=2000),
    "paper": SessionParams(),
    # The paper's GPIS as written: thin-plate kernel with R the largest distance, contacts
    # only (the shape-transfer shortfall of the README comes from it).
    "faithful": SessionParams(gpis_kernel="thin-plate", gpis_radius_factor=1.0,
                              gpis_noncontacts=False, gpis_carve_radius=0.0,
                              cover_prior=False, check_lines=0),
    "refined": SessionParams(filter=preset("refined")),
    "accurate": SessionParams(filter=preset("accurate"), gpis_resolution=48,
                              variance_points=3000, metric_samples=5000),
}


def session_preset(name, **overrides):
    """Session parameters of a named preset (the keys of :data:`SESSION_PRESETS`)."""
    try:
        return replace(SESSION_PRESETS[name], **overrides)
    except KeyError:
        raise ParameterError(f"unknown preset {name!r}; choose from "
                             f"{', '.join(SESSION_PRESETS)}") from None


def _frozen(array):
    array = np.array(array)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything a viewer or a benchmark needs after one step (arrays are read-only).

    Frames: everything is in the world frame.
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
    truth_coverage: float
    pose_error: float
    recon_error: object
    terminated: bool
    timings: dict
    hypotheses: tuple = ()

    def record(self):
        """The JSON record of this step (the ``trial`` command's contract)."""
        return {"t": self.step, "map_class": self.map_class, "pose_error": self.pose_error,
                "dhd": self.dhd, "truth_coverage": self.truth_coverage, "novel": self.novel, "recon_error": self.recon_error,
                "n_particles": self.n_particles, "n_contacts": int(len(self.contacts)),
                "n_noncontacts": int(len(self.noncontacts)),
                "step_seconds": float(sum(self.timings.values())),
                "timings": {k: float(v) for k, v in self.timings.items()},
                "gpis_scale": self.gpis_scale}


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


class Session:
    """Active exploration of one ground truth with one prior library.

    Parameters
    ----------
    truth : GroundTruth
    library : PriorLibrary
    strategy : {"gpis-dhd", "rrt"}
    params : SessionParams, optional
    seed : int
        Seeds the filter, the exploration and the simulator noise.
    sensor_noise : tuple of float
        ``(position std, normal std in degrees)`` of the simulated sensor.
    """

    def __init__(self, truth, library, strategy="gpis-dhd", params=None, seed=0,
                 sensor_noise=(0.0, 0.0)):
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
        self.simulator = ContactSimulator(truth, position_noise=self.sensor_noise[0],
                                          normal_noise_deg=self.sensor_noise[1],
                                          rng=np.random.default_rng([self.seed, 2]))
        self.filter = ParticleFilter(library, self.params.filter, rng=np.random.default_rng([self.seed, 3]))
        self.snapshots = []
        self._scale = self.params.gpis_scale
        self._target = None
        self._given_up_targets = []
        self._free_space = np.zeros((0, 3))
        self._check = None  # the estimate's vertices while a check line is due
        self._check_directions = []
        self._checks_passed = 0
        self._truth_samples = transform_points(
            surface_samples(truth.model, self.params.metric_samples), truth.rotation,
            truth.translation)

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
        """One time step of Algorithm 2; returns its :class:`Snapshot`.

        A step that fails leaves the session exactly as it was before it.
        """
        if self.terminated:
            raise SessionError("the session has terminated; start a new one")
        saved = self._checkpoint()
        try:
            return self._step()
        except BaseException:
            self._restore(saved)
            raise

    _FILTER_STATE = ("particles", "contact_positions", "contact_normals",
                     "noncontact_positions", "step_count", "state")

    def _checkpoint(self):
        # The filter replaces its arrays on update rather than writing into them, so keeping
        # references (and the generators' states) is enough to roll a step back.
        return ({name: getattr(self.filter, name) for name in self._FILTER_STATE},
                [g.bit_generator.state for g in self._generators()],
                (self._scale, self._target, list(self._given_up_targets), self._free_space,
                 len(self.snapshots)),
                (self._check, list(self._check_directions), self._checks_passed))

    def _restore(self, saved):
        filter_state, generator_states, (scale, target, given_up, free, count), check = saved
        self._check, self._check_directions, self._checks_passed = check
        for name, value in filter_state.items():
            setattr(self.filter, name, value)
        for generator, state in zip(self._generators(), generator_states):
            generator.bit_generator.state = state
        self._scale, self._target, self._given_up_targets = scale, target, given_up
        self._free_space = free
        del self.snapshots[count:]

    def _generators(self):
        return (self.rng, self.simulator.rng, self.filter.rng)

    def _step(self):
        timings = {}
        clock = time.perf_counter()
        paths, observations = self._touch()
        timings["simulator"] = time.perf_counter() - clock

        clock = time.perf_counter()
        state = self.filter.update(observations)
        timings["filter"] = time.perf_counter() - clock

        model = self.filter.models[self.filter.class_names.index(state.map_class)]
        rotation, translation = state.map_rotation, state.map_translation
        map_vertices = transform_points(model.mesh.vertices, rotation, translation)
        contacts, normals = self.filter.contact_positions, self.filter.contact_normals
        gpis = None
        if state.novel:
            gpis = self._reconstruct(model, rotation, translation, map_vertices, timings)
        clock = time.perf_counter()
        surface = gpis[0] if gpis is not None and len(gpis[0]) else map_vertices
        reachable = self._reachable(surface)
        dhd = directed_hausdorff(surface[reachable], contacts)
        prior_open, prior_dhd = None, 0.0
        if gpis is not None and self.params.cover_prior:
            # The prior is cut out around missed probes as far as the carve reaches.
            prior_open = self._reachable(map_vertices, max(self.params.contact_spacing,
                                                           self.params.gpis_carve_radius))
            prior_dhd = directed_hausdorff(map_vertices[prior_open], contacts)
        cap = self.params.max_steps_novel if state.novel else self.params.max_steps_known
        step = self.step_count + 1
        covered = max(dhd, prior_dhd) <= self.params.eps
        checking = covered and state.novel and self._checks_passed < self.params.check_lines
        terminated = bool((covered and not checking) or step >= cap)
        self._check = None
        if terminated:
            self._target = None
        elif checking:
            self._target = None
            self._check = surface
        elif dhd <= self.params.eps < prior_dhd:
            # The reconstruction is covered, but part of the prior it came from is neither
            # touched nor refuted: the object may extend there.
            self._target = self._next_target(map_vertices, prior_open, None, model, rotation,
                                             translation, contacts)
        else:
            self._target = self._next_target(surface, reachable, gpis, model, rotation,
                                             translation, contacts)
        dhd = max(dhd, prior_dhd)
        timings["target"] = time.perf_counter() - clock

        clock = time.perf_counter()
        pose_error = metric_pose_error(model, rotation, translation, self.truth,
                                       self.params.metric_samples)
        recon_error = None
        if gpis is not None and len(gpis[1]):
            recon = trimesh.Trimesh(gpis[0], gpis[1], process=False)
            samples, _ = trimesh.sample.sample_surface(recon, self.params.metric_samples, seed=0)
            recon_error = two_way_hausdorff(samples, self._truth_samples)
        timings["metrics"] = time.perf_counter() - clock

        snapshot = Snapshot(
            step=step, new_observations=tuple(observations),
            paths=tuple(_frozen(p) for p in paths), contacts=_frozen(contacts),
            normals=_frozen(normals), noncontacts=_frozen(self.filter.noncontact_positions),
            free_space=_frozen(self._free_space),
            map_class=state.map_class, map_rotation=_frozen(rotation),
            map_translation=_frozen(translation), map_vertices=_frozen(map_vertices),
            map_faces=model.mesh.faces, class_posterior=dict(state.class_posterior),
            n_particles=state.n_particles, log_evidence=float(state.log_evidence),
            log_threshold=float(state.log_threshold), novel=bool(state.novel),
            gpis_vertices=None if gpis is None else _frozen(gpis[0]),
            gpis_faces=None if gpis is None else _frozen(gpis[1]),
            gpis_variance=None if gpis is None else _frozen(gpis[2]),
            gpis_scale=float(self._scale) if gpis is not None else None,
            target=None if self._target is None else _frozen(self._target[0]),
            dhd=float(dhd), truth_coverage=directed_hausdorff(self._truth_samples, contacts),
            pose_error=float(pose_error),
            recon_error=None if recon_error is None else float(recon_error),
            terminated=terminated, timings=timings, hypotheses=_hypotheses(state))
        self.snapshots.append(snapshot)
        return snapshot

    # ---------------------------------------------------------------- pieces
    def _touch(self):
        contacts = self.filter.contact_positions
        if len(contacts) == 0:
            return first_contact(self.simulator, np.zeros(3), self.rng)
        p = self.params
        if self.strategy == "rrt":
            low, high = contacts.min(axis=0) - 3.0, contacts.max(axis=0) + 3.0
            return rrt_step(self.simulator, contacts, self.filter.contact_normals, (low, high),
                            self.rng, p.rrt_step, p.probe_depth)
        if self._check is not None:
            return self._check_line(contacts)
        target, normal, estimate = self._target
        depth = deepest_inside(estimate, target, normal, p.probe_depth)
        paths, observations, reached = enforce_contact(
            self.simulator, target, normal, contacts, self.filter.contact_normals, depth,
            follow_step=p.follow_step, spacing=p.contact_spacing, max_follow=p.max_follow)
        if not reached or self._repeats_contact(observations[-1]):
            self._given_up_targets.append(target)
        if not isinstance(observations[0], Contact):
            self._free_space = free_space_points(self._free_space, paths[0],
                                                 p.contact_spacing)
        return paths, observations

    def _check_line(self, contacts):
        """One check line (``check_lines``); counts it as passed unless it touched the
        object farther than ``eps`` from the estimate and from every contact."""
        estimate = self._check
        direction = next_sweep_direction(self._check_directions, self.rng)
        self._check_directions.append(direction)
        through = contacts[self.rng.integers(len(contacts))] + self.rng.normal(
            0.0, self.params.eps, size=3)
        paths, observations = sweep_line(self.simulator, through, direction)
        touched = observations[0]
        surprise = isinstance(touched, Contact) and min(
            cKDTree(contacts).query(touched.position)[0],
            cKDTree(estimate).query(touched.position)[0]) > self.params.eps
        self._checks_passed = 0 if surprise else self._checks_passed + 1
        if not isinstance(touched, Contact):
            self._free_space = free_space_points(self._free_space, paths[0],
                                                 self.params.contact_spacing)
        return paths, observations

    def _repeats_contact(self, observation):
        """Whether a contact lands where an earlier one did (within the sensor noise).

        Such a touch taught nothing: something in front of the target (or a crevice the
        probe cannot enter) took it, and aiming at the same target again would repeat it.
        """
        contacts = self.filter.contact_positions
        if not isinstance(observation, Contact) or len(contacts) == 0:
            return False
        tolerance = max(4.0 * self.sensor_noise[0], 1e-9)
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
        radius = self.params.contact_spacing if radius is None else radius
        far = cKDTree(refuted).query(vertices)[0] >= radius
        return far if far.any() else np.ones(len(vertices), bool)

    def _noncontact_points(self, noncontacts=None, free_space=None):
        """Where the sensor found no object: the non-contacts and the points along missed
        probes, one per quarter of the kernel's reach (what the GPIS's non-contact switch
        constrains)."""
        noncontacts = self.filter.noncontact_positions if noncontacts is None else noncontacts
        free_space = self._free_space if free_space is None else free_space
        reach = self.params.gpis_support if self.params.gpis_kernel == "wendland" else 1.0
        return np.vstack([noncontacts, thin_points(free_space, reach / 4)])

    def _prior(self, model, rotation, translation):
        sdf = model.sdf

        def prior(points):
            values, gradients = sdf.evaluate((np.atleast_2d(points) - translation) @ rotation)
            return values, gradients @ rotation.T

        return prior

    def _gpis_prior(self, model, rotation, translation, contacts, noncontacts, free_space):
        """The GPIS prior mean: the MAP shape with the refuted space cut out."""
        return carved_prior(self._prior(model, rotation, translation),
                            np.vstack([noncontacts, free_space]), contacts,
                            self.params.gpis_carve_radius)

    def _gpis_box(self, map_vertices, contacts):
        """The reconstruction box (low, high) and the GPIS kernel."""
        p = self.params
        low = np.minimum(map_vertices.min(axis=0), contacts.min(axis=0)) - p.gpis_margin
        high = np.maximum(map_vertices.max(axis=0), contacts.max(axis=0)) + p.gpis_margin
        if p.gpis_kernel == "wendland":
            return low, high, WendlandKernel(p.gpis_support)
        return low, high, ThinPlateKernel(p.gpis_radius_factor * float(np.linalg.norm(high - low)))

    def _fit(self, kernel, contacts, normals, noncontacts, prior, scale, newton=True):
        p = self.params
        return fit_gpis(contacts, normals, prior, kernel, scale=scale,
                        noise_variance=p.gpis_noise, newton=newton,
                        noncontacts=noncontacts if p.gpis_noncontacts else None,
                        noncontact_value=p.gpis_noncontact_value)

    def _reconstruct(self, model, rotation, translation, map_vertices, timings):
        p = self.params
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
        vertices, faces = zero_level_surface(fit, (low, high), p.gpis_resolution)
        variance = np.zeros(len(vertices))
        if len(vertices):
            count = min(p.variance_points, len(vertices))
            subset = self.rng.choice(len(vertices), count, replace=False)
            variance[subset] = fit.variance(vertices[subset])
            if count < len(vertices):
                # Other vertices show the variance of the nearest evaluated one.
                nearest = cKDTree(vertices[subset]).query(vertices)[1]
                variance = variance[subset][nearest]
        timings["surface"] = time.perf_counter() - clock
        return vertices, faces, variance, subset if len(vertices) else None, fit

    def _next_target(self, surface, reachable, gpis, model, rotation, translation, contacts):
        if gpis is not None and len(gpis[0]):
            vertices, _, variance, subset, fit = gpis
            score = variance[subset]
            distance = cKDTree(contacts).query(vertices[subset])[0]
            # Only vertices that keep the stop from holding are worth a touch (beyond the
            # paper, whose maximum variance can sit within eps of a contact while a vertex
            # the sensor still has to reach has a lower one).
            uncovered = distance > (self.params.eps if self.params.target_uncovered else -1.0)
            for usable in (reachable[subset] & uncovered, reachable[subset]):
                if usable.any():
                    score = np.where(usable, score, -np.inf)
                    break
            # Beyond a compact kernel's support the variance is the prior's everywhere: the
            # tie goes to the vertex farthest from the contacts.
            best = score >= score.max() - 1e-9 * abs(score.max())
            index = subset[int(np.argmax(np.where(best, distance, -np.inf)))]
            target = vertices[index]
            _, gradient = fit.mean(target[None])
            return target, normalise_rows(gradient)[0], fit.mean_value
        index = np.flatnonzero(reachable)[farthest_vertex(surface[reachable], contacts)]
        normal = model.mesh.vertex_normals[index] @ rotation.T
        estimate = self._prior(model, rotation, translation)
        return surface[index], normalise_rows(normal[None])[0], lambda x: estimate(x)[0]

    # ---------------------------------------------------------------- learning
    def learned_model(self, name, snapshot=None, resolution=None):
        """The reconstructed surface of a novel snapshot as a new :class:`ObjectModel`.

        The snapshot's GPIS posterior mean (its contacts, MAP prior and kernel scale) is
        extracted again at ``resolution`` (default ``params.learned_resolution``); the
        largest connected piece of the zero level set is kept, and the model is checked and
        normalised like any loaded mesh.
        """
        snapshot = snapshot or self.latest
        if snapshot is None or snapshot.gpis_faces is None or len(snapshot.gpis_faces) == 0:
            raise SessionError("no reconstructed surface to learn from: the object was not "
                               "judged novel in this step")
        resolution = resolution or self.params.learned_resolution
        vertices, faces = snapshot.gpis_vertices, snapshot.gpis_faces
        if resolution != self.params.gpis_resolution:
            vertices, faces = self._surface_at(snapshot, resolution)
        return learned_model_from_surface(vertices, faces, name,
                                          params=self.library[snapshot.map_class].params
                                          if snapshot.map_class in self.library else None)

    def _surface_at(self, snapshot, resolution):
        """The snapshot's GPIS zero level set on a grid of ``resolution`` cells."""
        model = self.filter.models[self.filter.class_names.index(snapshot.map_class)]
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
        """Save the session (its set-up and its observation history) to an ``.npz`` file."""
        config = {"format": "tactile_viz-session", "version": 1, "strategy": self.strategy,
                  "seed": self.seed, "params": self.params.to_dict(),
                  "sensor_noise": list(self.sensor_noise), "steps": self.step_count,
                  "truth_name": self.truth.model.name, "library": self.library.names}
        arrays = {"config": np.frombuffer(json.dumps(config).encode(), dtype=np.uint8),
                  "truth_rotation": self.truth.rotation, "truth_translation": self.truth.translation,
                  "truth_vertices": self.truth.model.mesh.vertices,
                  "truth_faces": self.truth.model.mesh.faces,
                  "contacts": self.filter.contact_positions,
                  "noncontacts": self.filter.noncontact_positions}
        for index, model in enumerate(self.library):
            arrays[f"prior{index}_vertices"] = model.mesh.vertices
            arrays[f"prior{index}_faces"] = model.mesh.faces
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        try:
            write_atomic(path, buffer.getvalue())
        except OSError as error:
            raise SessionError(f"cannot save the session to {path}: {error}") from error
        return path

    @classmethod
    def load(cls, path, callback=None):
        """Rebuild a saved session by replaying its steps (deterministic from its seed)."""
        try:
            with np.load(path, allow_pickle=False) as stored:
                arrays = {name: stored[name] for name in stored.files}
            config = json.loads(arrays["config"].tobytes().decode())
            if config.get("format") != "tactile_viz-session":
                raise ValueError("not a tactile_viz session file")
            truth_model = _model_from_arrays(config["truth_name"], arrays["truth_vertices"],
                                             arrays["truth_faces"], "the truth mesh")
            library = PriorLibrary(_model_from_arrays(name, arrays[f"prior{i}_vertices"],
                                                      arrays[f"prior{i}_faces"],
                                                      f"the mesh of prior {name!r}")
                                   for i, name in enumerate(config["library"]))
            rotation, translation = _checked_pose(arrays["truth_rotation"],
                                                  arrays["truth_translation"])
            truth = GroundTruth(truth_model, rotation, translation)
            session = cls(truth, library, config["strategy"],
                          SessionParams.from_dict(config["params"]), config["seed"],
                          tuple(config["sensor_noise"]))
            steps = _check_integer("steps", config["steps"])
            cap = max(session.params.max_steps_known, session.params.max_steps_novel)
            if not 0 <= steps <= cap:
                raise ValueError(f"steps must lie in [0, {cap}], got {steps}")
            contacts = np.asarray(arrays["contacts"], dtype=float)
        except (OSError, ValueError, KeyError, TypeError, EOFError) as error:
            raise SessionError(f"{path}: not a readable session file ({error})") from error
        except Exception as error:  # zipfile.BadZipFile and friends from a truncated file
            raise SessionError(f"{path}: not a readable session file ({error!r})") from error
        for _ in range(steps):
            try:
                snapshot = session.step()
            except (TactileVizError, ValueError, TypeError, IndexError, ArithmeticError,
                    np.linalg.LinAlgError) as error:
                raise SessionError(f"{path}: replaying step {session.step_count + 1} failed "
                                   f"({error!r})") from error
            if callback is not None:
                callback(snapshot)
        if (contacts.shape != session.filter.contact_positions.shape
                or not np.allclose(session.filter.contact_positions, contacts)):
            raise SessionError(f"{path}: replaying the session did not reproduce its contacts")
        return session


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


def _model_from_arrays(name, vertices, faces, what="the mesh"):
    """A model from stored (already normalised) arrays, checked but not re-processed."""
    if not isinstance(name, str):
        raise TypeError(f"the name of {what} must be a string, got {name!r}")
    vertices, faces = check_arrays(vertices, faces, what)
    return ObjectModel(name, trimesh.Trimesh(vertices, faces, process=False))


def _checked_pose(rotation, translation):
    """A stored ``object_to_world`` pose: a proper rotation and a finite translation."""
    rotation = np.asarray(rotation, dtype=float)
    translation = np.asarray(translation, dtype=float)
    if rotation.shape != (3, 3) or translation.shape != (3,):
        raise ValueError(f"the truth pose has shapes {rotation.shape} and {translation.shape}, "
                         "not (3, 3) and (3,)")
    if not (np.isfinite(rotation).all() and np.isfinite(translation).all()):
        raise ValueError("the truth pose is not finite")
    if (np.abs(rotation.T @ rotation - np.eye(3)).max() > 1e-6
            or not abs(np.linalg.det(rotation) - 1) < 1e-6):
        raise ValueError("the truth rotation is not a rotation matrix")
    if np.abs(translation).max() > 1e6:
        raise ValueError("the truth translation is out of range")
    return rotation, translation


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
                                   longest_side=None)


def make_truth(model, rng=None, max_translation=1.0):
    """The ground truth of a trial: ``model`` at a random pose."""
    rotation, translation = random_pose(rng, max_translation)
    return GroundTruth(model, rotation, translation)


__all__ = ["Session", "SessionError", "SessionParams", "Snapshot", "session_preset",
           "SESSION_PRESETS", "learned_model_from_surface", "make_truth"]
