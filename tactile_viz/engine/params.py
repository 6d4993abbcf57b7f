"""Parameters of the filter and of a session, each in one dataclass with the paper's values as
defaults; their declarations (component, unit, doc, range) for the GUI, the command line and
the benchmarks. Named presets are in :mod:`.presets`. Lengths are in *size units*, a sixth
of an object's longest side, turned into scene units by :func:`scaled_lengths` (docs/units.md);
length fields carry ``metadata["length"]``, the power of length in their unit.
"""

from __future__ import annotations

import functools
import numbers
import re
from dataclasses import MISSING, asdict, dataclass, field, fields, replace

import numpy as np

from .errors import ParameterError

PAPER_SIZE = 6.0  # longest side of the paper's normalised objects: one size unit is 1/6 of it


def _length(default, power=1, low=None, high=None):
    """A dataclass field in size units (``power``: length squared for a variance, ...),
    with the range a control offers (``low``, ``high``; None: only the validation's)."""
    return field(default=default, metadata={"length": power, "range": (low, high)})


def _ranged(default, low, high):
    """A dataclass field with the range a control offers."""
    return field(default=default, metadata={"range": (low, high)})


def length_fields(cls):
    """``{name: power of length}`` of the length fields of a parameter dataclass."""
    return {f.name: f.metadata["length"] for f in fields(cls) if "length" in f.metadata}


def scaled_lengths(params, unit):
    """``params`` with every length field in scene units (nested dataclasses untouched).

    Parameters
    ----------
    params : FilterParams or SessionParams
    unit : float
        Scene units per size unit (the object's longest side / 6); 1 returns ``params``.

    Returns
    -------
    same type as ``params``
    """
    unit = float(unit)
    if unit == 1.0:
        return params
    if not (np.isfinite(unit) and unit > 0):
        raise ParameterError(f"the size unit must be a positive finite number, got {unit!r}")
    powers = length_fields(type(params))
    if getattr(params, "gpis_kernel", None) == "wendland":
        powers["gpis_scale"] = 2  # Wendland's k(0) is the scale itself, thin-plate's a R^3
    return replace(params, **{name: getattr(params, name) * unit**power
                              for name, power in powers.items()})


def _check_real(name, value):
    """A real number (not a bool, string or None), else ParameterError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a number, got {value!r}")


def _check_integer(name, value):
    """``value`` as an int (an integral float such as ``30.0`` is accepted), else
    ParameterError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    if isinstance(value, numbers.Integral):
        return int(value)
    if not (np.isfinite(value) and float(value).is_integer()):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class FilterParams:
    """Knobs of the particle filter (paper, Table I and Sections III-A to III-C).

    Attributes
    ----------
    sigma_d : float, size units
        Std of the signed-distance likelihood (paper 0.5). Larger forgives misfit.
    sigma_n : float
        Std of the normal likelihood (paper 1.5).
    n_s : int
        Earlier contacts paired with each new one for point-pair sampling (paper 30).
    lam : float
        Sampling gate lambda: new particles are sampled while the per-observation geometric
        mean of the MAP evidence relative to its maximum is below it (paper 0.97).
    known_fraction : float
        Novelty test: known iff the MAP evidence on the contacts reaches this fraction of
        its maximum per contact (paper 0.9) ...
    noncontact_fraction : float
        ... and its evidence on the non-contacts this probability per non-contact (paper
        0.5); each kind is tested on its own.
    distance_step : float, size units
        Point-pair key resolution of the distance (paper 0.1).
    angle_step_deg : float
        Point-pair key resolution of the angles in degrees (paper 12).
    neighbour_bins : int
        0 looks up a pair's own key bin; 1 also all neighbouring bins (noise tolerance).
    init_rotations : int
        Rotations about the contact normal per feature point when initialising.
    max_new_per_class : int
        Cap on particles sampled per class and step (a random subset beyond it).
    max_particles : int
        Cap on the number of draws of the resampling step, and on the hypotheses the first
        touch spawns (beyond it a random subset of every feature point of every class).
    max_candidates : int
        Beyond the paper (0: all), for large libraries: point-pair candidates scored on the
        whole subset of earlier contacts per new contact. Beyond it, every candidate is
        first scored on four of the subset's contacts and only the best this many go on.
    max_new_particles : int
        Particle budget (beyond the paper): at most this many of a step's new point-pair
        particles are kept, the heaviest (those resampling would keep anyway); 0 keeps all.
    merge_distance : float, size units
        Particle merging (beyond the paper; 0 off): after each step, particles of one class
        whose translations share a cell of this size and whose rotation vectors share a
        cell of ``merge_angle_deg`` become one, with their summed weight.
    merge_angle_deg : float
    refine_map : bool
        Add a Gauss-Newton refinement of the MAP pose as a particle (beyond the paper).
    refine_learned : int
        The same refinement of this many of the heaviest particles of each learned prior
        (beyond the paper; 0 off): a learned shape's feature normals come from a
        reconstruction, so its point-pair poses are coarser than a given mesh's (on the
        learned home chair the MAP's normals missed the contacts' by a median 33-39 degrees,
        against 8.5 on the bundled chair), and the novelty test failed at them.
    refine_iterations : int
    contenders : int
        Beyond the paper (0 off), for libraries of near twins (:mod:`.discrimination`):
        the heaviest particle of each of this many heaviest classes holding at least
        ``contender_mass`` of the posterior, and this many classes that fit the contacts
        best at the MAP's pose, have their poses refined (``refine_iterations`` steps); a
        lookalike that fits better than every contender joins the belief, and while
        several classes contend the MAP is the one whose refined pose fits best.
    contender_mass : float
        The share of the posterior a class must hold to contend (0-1).
    outlier_probability : float
        Beyond the paper (0 off, the paper's Gaussian): the chance that a contact is a
        wrong reading, a mixture with a flat density (see :mod:`.likelihood`), so that one
        outlier cannot kill the true hypothesis.
    position_noise : float, size units
        The sensor's position noise the novelty test allows for (0: the paper's test; set
        by :func:`~.presets.noise_matched`): a reported contact may lie up to two stds off
        the surface along its normal; where such an offset crosses a fold (the grid's normal
        turns over 60 degrees: past a thin wall's middle) a contact's term is the best over
        the offsets, an offset costing as a distance does; the MAP is taken refined.
    n_features : int
        Poisson-disk feature points per object (paper 200).
    sdf_resolution : int
        Voxels along the longest side of each prior's SDF grid.
    """

    sigma_d: float = _length(0.5, low=1e-3, high=100.0)
    sigma_n: float = _ranged(1.5, 1e-3, 100.0)
    n_s: int = _ranged(30, 1, 500)
    lam: float = _ranged(0.97, 0.01, 1.0)
    known_fraction: float = 0.9
    noncontact_fraction: float = 0.5
    distance_step: float = _length(0.1)
    angle_step_deg: float = 12.0
    neighbour_bins: int = 0
    init_rotations: int = 1
    max_new_per_class: int = 2000
    max_particles: int = 20000
    max_candidates: int = 4000
    max_new_particles: int = 0
    merge_distance: float = _length(0.0)
    merge_angle_deg: float = 1.0
    refine_map: bool = False
    refine_learned: int = 3
    refine_iterations: int = 10
    contenders: int = _ranged(4, 0, 50)
    contender_mass: float = _ranged(0.05, 0.0, 1.0)
    outlier_probability: float = _ranged(0.0, 0.0, 0.49)
    position_noise: float = _length(0.0, low=0.0, high=10.0)
    n_features: int = 200
    sdf_resolution: int = 64

    def __post_init__(self):
        integers = ("n_s", "init_rotations", "max_new_per_class", "max_particles",
                    "max_new_particles", "n_features", "refine_iterations", "neighbour_bins",
                    "max_candidates", "contenders",
                    "sdf_resolution", "refine_learned")
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name in integers:
                object.__setattr__(self, item.name, _check_integer(item.name, value))
            elif item.name == "refine_map":
                if not isinstance(value, (bool, np.bool_)):
                    raise ParameterError(f"{item.name} must be True or False, got {value!r}")
            else:
                _check_real(item.name, value)
        positive = ("sigma_d", "sigma_n", "distance_step", "angle_step_deg")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
        _check_real("position_noise", self.position_noise)
        if not (np.isfinite(self.position_noise) and self.position_noise >= 0):
            raise ParameterError("position_noise must be a finite number >= 0, "
                                 f"got {self.position_noise!r}")
        if not 0 <= self.outlier_probability < 0.5:
            raise ParameterError("outlier_probability must lie in [0, 0.5), "
                                 f"got {self.outlier_probability!r}")
        for name in ("lam", "known_fraction", "noncontact_fraction"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise ParameterError(f"{name} must lie in (0, 1], got {value!r}")
        at_least_one = ("n_s", "init_rotations", "max_new_per_class", "max_particles",
                        "n_features", "refine_iterations")
        for name in at_least_one:
            if int(getattr(self, name)) < 1:
                raise ParameterError(f"{name} must be at least 1, got {getattr(self, name)!r}")
        if self.merge_distance < 0:
            raise ParameterError("merge_distance must be at least 0 (0: no merging), "
                                 f"got {self.merge_distance!r}")
        if not self.merge_angle_deg > 0:
            raise ParameterError(f"merge_angle_deg must be positive, got {self.merge_angle_deg!r}")
        if self.refine_learned < 0:
            raise ParameterError("refine_learned must be at least 0 (0: off), "
                                 f"got {self.refine_learned!r}")
        if self.contenders < 0:
            raise ParameterError(f"contenders must be at least 0 (0: off), got {self.contenders!r}")
        if not 0 <= self.contender_mass <= 1:
            raise ParameterError(f"contender_mass must lie in [0, 1], got {self.contender_mass!r}")
        if self.max_candidates < 0:
            raise ParameterError("max_candidates must be at least 0 (0: all), "
                                 f"got {self.max_candidates!r}")
        if self.max_new_particles < 0:
            raise ParameterError("max_new_particles must be at least 0 (0: no budget), "
                                 f"got {self.max_new_particles!r}")
        if self.neighbour_bins not in (0, 1):
            raise ParameterError(f"neighbour_bins must be 0 or 1, got {self.neighbour_bins!r}")
        if self.n_features < 3:
            raise ParameterError(f"n_features must be at least 3, got {self.n_features!r}")
        if self.sdf_resolution < 8:
            raise ParameterError(f"sdf_resolution must be at least 8, got {self.sdf_resolution!r}")

    def to_dict(self):
        return asdict(self)

    @classmethod
    def from_dict(cls, values):
        """Build from a dict, refusing unknown keys (a typo should not pass silently)."""
        if not isinstance(values, dict):
            raise ParameterError(f"filter parameters must be a dict, got {type(values).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ParameterError(f"unknown filter parameter(s): {', '.join(sorted(unknown))}")
        return cls(**values)


GPIS_KERNELS = ("wendland", "thin-plate")
CHECK_LINE_AIMS = ("gap", "gap-weakest", "contact")


@dataclass(frozen=True)
class SessionParams:
    """Knobs of a session beyond the filter's (paper, Table I and Section III-H).

    Attributes
    ----------
    filter : FilterParams
    eps : float, size units
        Termination threshold on the DHD from the estimated surface (and, with
        ``cover_prior``, the MAP prior of a novel object) to the contacts; the surface near
        targets the sensor could not reach and near missed probes' paths is left out.
    max_steps_known, max_steps_novel : int
        Step caps while the object is judged known / novel (paper 300 / 400).
    gpis_noise : float, size units squared
        Observation noise variance of the GPIS (paper 1e-4).
    gpis_scale : float, per size unit (thin-plate; Wendland: size units squared)
        Initial kernel scale ``a_0``.
    gpis_resolution : int
        Marching-cubes cells along the longest side of the reconstruction box.
    gpis_margin : float, size units
        Margin of the reconstruction box around the MAP shape and the contacts.
    gpis_kernel : {"thin-plate", "wendland"}
        ``thin-plate``: the paper's kernel, whose correction reaches the whole box (the
        default: 0.80 mean TWD against 1.08 on 10 novel trials, docs/benchmarks.md);
        ``wendland``: compactly supported, corrects the prior within ``gpis_support``.
    gpis_support : float, size units
        Support radius ``c`` of the Wendland kernel.
    gpis_radius_factor : float
        Thin-plate ``R`` over the reconstruction box's diagonal (which bounds every
        distance involved): 1.0 is the paper's "largest distance" (the indefinite Gram
        matrix is projected on the PSD cone), 1.2 makes it positive definite.
    gpis_noncontacts : bool
        Beyond the paper: non-contacts where the prior puts the inside observe
        ``f = gpis_noncontact_value`` (value only), which removes the prior's surface where
        a probe passed through it.
    gpis_noncontact_value : float, size units
    gpis_incremental : bool
        Beyond the paper: the GPIS factor is extended by a block per new contact and its
        mean summed by a compiled loop (docs/gpis.md); False refits in full each step.
    gpis_refit_every : int
        With ``gpis_incremental``: the scale's Newton step every this many fits (1: all).
    gpis_refit_score : float
        With ``gpis_incremental``: also refit when the likelihood's gradient exceeds this (in sds).
    gpis_box_tolerance : float
        With ``gpis_incremental``: ``R`` and grid cell kept while within this share of the box's.
    gpis_carve_radius : float, size units
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
        Beyond the paper: once a novel object's estimate is covered, this many checks must
        each touch nothing farther than ``contact_spacing`` from the estimate and from every
        contact before the session stops; a check that does restarts the count (part of
        the object was never predicted) and grows a frontier from the contact: targets
        ``eps`` along four tangents, each contact on new ground growing it again, and the
        session does not stop while one is queued. 0: stop as soon as the estimate is
        covered (the paper, the ``paper`` preset).
    check_line_aim : {"gap", "gap-weakest", "contact"}
        ``gap``: each check sweeps the widest gap that no contact, swept path or estimated
        surface is near, alternately inside the contacts' convex hull and in a shell of
        ``2 eps`` around the estimate: in from a direction with a clear way, then a lattice
        of rows 0.2 apart through the cube inside the gap's ball; ``gap-weakest``: after
        every two gap checks one more sweeps that lattice about the estimate's vertex
        farthest from every contact (where the object may lie up to ``eps`` off the
        estimate unseen); it does not count toward ``check_lines`` unless it surprises;
        ``contact``: a line through a random contact moved by about ``eps``, from the least
        used direction.
    variance_points : int
        Surface vertices at which the GPIS variance is evaluated (a random subset).
    final_resolution : int
        Marching-cubes cells along the longest side of the reconstruction reported when a
        novel session stops: the same posterior mean as the steps' surfaces, sampled finer
        (at 32 cells a sofa's foot or a chair's rung thinner than a cell can fall between
        the samples and vanish; the protocol's home_chair error fell from 0.591 to 0.507,
        docs/benchmarks.md). Exploration keeps ``gpis_resolution``.
    learned_resolution : int
        Marching-cubes cells along the longest side when a reconstruction is kept as a new
        prior: the same posterior mean as the step's surface, sampled finer, since a learned
        shape is extracted once and matched against every later contact.
    probe_depth : float, size units
        How deep contact enforcement reaches at most (the estimate's deepest point within
        it is probed).
    approach_clearance : float, size units
        How far outside a target the probe starts, along the estimated normal, at most: the
        approach stops short of where the estimate predicts the object again. A long
        approach bumps into parts that nothing predicted (beyond the paper, which leaves the
        start open; the ``paper`` preset starts 0.5 outside).
    follow_step : float, size units
        Length of one in-contact surface-following step of contact enforcement.
    contact_spacing : float, size units
        Surface following stops at a contact this far from every earlier one; a target
        whose procedure ends nearer is given up.
    max_follow : float, size units
        Longest surface-following path of one step.
    rrt_step : float, size units
    metric_samples : int
        Surface samples per shape for the error metrics (TWD).
    decision_confidence : float
        Beyond the paper: a known object is decided once the MAP class holds this share of
        the class posterior and the MAP this share of the fit posterior of the distinct
        hypotheses (:mod:`~tactile_viz.engine.decision`).
    decision_floor : float, size units
        How far a right hypothesis's contacts may lie off its surface besides the sensor's
        noise and the grid's own error (both added in quadrature): the contact's
        localisation (the simulator's is within 0.01).
    decision_cover : float, size units
        A decision also needs every point of the MAP surface within this distance of a
        contact (its DHD; 2.4 is 40% of the object's longest side): a wrong pose or class
        can fit contacts on one part within the noise.
    decision_checks : int
        With ``decision_targets``: sweeps just outside the MAP (check lines, as a novel
        object's) that must touch nothing it does not predict before the object is decided
        (a novel object can hold a part that a known one fits, a trident a knife).
    decision_same_mode : float, size units
        Poses of one class whose surfaces agree within this RMS distance (or twice the
        position noise) are one hypothesis: symmetries of the shape are not rivals.
    decision_targets : bool
        Beyond the paper: while the object is known but not decided and its MAP fits
        within the noise, touch where the plausible hypotheses' surfaces disagree most (holding
        the DHD stop), for ``decision_patience`` steps at most; the MAP pose reported and
        aimed from is its refined fit. False: the paper's targets, stop and MAP particle.
    decision_patience : int
        Steps of a session aimed at rival hypotheses at most (then the paper's targets and
        stop).
    stop_at_decision : bool
        Stop as soon as the object is decided (a robot that only needs to recognise);
        False: go on to the DHD stop for shape.
    length_unit : float or None
        Scene units per size unit for every length parameter. None (the default): the
        filter's lengths scale with the library's reference size and the others with the
        MAP object's longest side (one size unit is a sixth of it); a number fixes it for
        all (1: lengths in scene units as written). See the module's docstring.
    """

    filter: FilterParams = field(default_factory=FilterParams)
    eps: float = _length(0.6, low=0.05, high=10.0)
    max_steps_known: int = 300
    max_steps_novel: int = 400
    gpis_noise: float = _length(1e-4, power=2)
    gpis_scale: float = _length(1.0, power=-1)
    gpis_resolution: int = 32
    gpis_margin: float = _length(0.6)
    gpis_kernel: str = "thin-plate"
    gpis_support: float = _length(4.0)
    gpis_radius_factor: float = 1.2
    gpis_noncontacts: bool = False
    gpis_noncontact_value: float = _length(0.1)
    gpis_carve_radius: float = _length(0.6)
    gpis_incremental: bool = True
    gpis_refit_every: int = _ranged(10, 1, 100)
    gpis_refit_score: float = _ranged(4.0, 0.5, 100.0)
    gpis_box_tolerance: float = _ranged(0.1, 0.0, 1.0)
    cover_prior: bool = True
    target_uncovered: bool = False
    check_lines: int = 24
    check_line_aim: str = "gap-weakest"
    variance_points: int = 1500
    final_resolution: int = 64
    learned_resolution: int = 64
    probe_depth: float = _length(1.0)
    approach_clearance: float = _length(2.0)
    follow_step: float = _length(0.1)
    contact_spacing: float = _length(0.3)
    max_follow: float = _length(3.0)
    rrt_step: float = _length(0.3)
    metric_samples: int = 3000
    decision_confidence: float = _ranged(0.99, 0.5, 0.999999)
    decision_floor: float = _length(0.01, low=1e-4, high=1.0)
    decision_cover: float = _length(2.4, low=0.1, high=12.0)
    decision_checks: int = _ranged(2, 0, 10)
    decision_same_mode: float = _length(0.1, low=1e-3, high=2.0)
    decision_targets: bool = True
    decision_patience: int = _ranged(30, 0, 300)
    stop_at_decision: bool = False
    length_unit: object = None

    def __post_init__(self):
        if self.length_unit is not None:
            _check_real("length_unit", self.length_unit)
            if not (np.isfinite(self.length_unit) and self.length_unit > 0):
                raise ParameterError("length_unit must be None or a positive finite number, "
                                     f"got {self.length_unit!r}")
            object.__setattr__(self, "length_unit", float(self.length_unit))
        if not isinstance(self.filter, FilterParams):
            raise ParameterError(f"filter must be FilterParams, got {type(self.filter).__name__}")
        if self.check_line_aim not in CHECK_LINE_AIMS:
            raise ParameterError(f"check_line_aim must be one of {', '.join(CHECK_LINE_AIMS)}, "
                                 f"got {self.check_line_aim!r}")
        if self.gpis_kernel not in GPIS_KERNELS:
            raise ParameterError(f"gpis_kernel must be one of {', '.join(GPIS_KERNELS)}, "
                                 f"got {self.gpis_kernel!r}")
        for name in ("gpis_noncontacts", "cover_prior", "target_uncovered", "decision_targets",
                     "stop_at_decision", "gpis_incremental"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ParameterError(f"{name} must be True or False, "
                                     f"got {getattr(self, name)!r}")
        for name in ("eps", "gpis_noise", "gpis_scale", "gpis_margin", "gpis_support",
                     "gpis_radius_factor", "gpis_noncontact_value", "gpis_refit_score",
                     "probe_depth", "approach_clearance",
                     "follow_step", "contact_spacing", "max_follow", "rrt_step",
                     "decision_floor", "decision_cover", "decision_same_mode"):
            value = getattr(self, name)
            _check_real(name, value)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
        for name in ("gpis_carve_radius", "gpis_box_tolerance"):
            _check_real(name, getattr(self, name))
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ParameterError(f"{name} must be a finite number >= 0, "
                                     f"got {getattr(self, name)!r}")
        _check_real("decision_confidence", self.decision_confidence)
        if not 0.5 <= self.decision_confidence < 1:
            raise ParameterError("decision_confidence must be in [0.5, 1), "
                                 f"got {self.decision_confidence!r}")
        for name in ("decision_patience", "decision_checks"):
            object.__setattr__(self, name, _check_integer(name, getattr(self, name)))
            if getattr(self, name) < 0:
                raise ParameterError(f"{name} must be at least 0, got {getattr(self, name)!r}")
        object.__setattr__(self, "check_lines", _check_integer("check_lines", self.check_lines))
        if self.check_lines < 0:
            raise ParameterError(f"check_lines must be at least 0, got {self.check_lines!r}")
        for name in ("max_steps_known", "max_steps_novel", "variance_points", "metric_samples",
                     "gpis_resolution", "final_resolution", "learned_resolution",
                     "gpis_refit_every"):
            object.__setattr__(self, name, _check_integer(name, getattr(self, name)))
            if getattr(self, name) < 1:
                raise ParameterError(f"{name} must be at least 1, got {getattr(self, name)!r}")
        for name in ("gpis_resolution", "final_resolution", "learned_resolution"):
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


# ------------------------------------------------------------------ declarations
@dataclass(frozen=True)
class Declaration:
    """One parameter as the GUI, the command line, presets and benchmarks see it, read from
    its field in :class:`FilterParams` or :class:`SessionParams` (the one place it is
    declared): its component, default, unit, one-line doc and the range a control offers.
    """

    name: str
    component: str
    default: object
    unit: str
    doc: str
    low: object = None
    high: object = None
    length: int = 0  # the power of length of its unit (0: not a length)


def _docstring_entries(cls):
    """``{name: (unit, first sentence)}`` of the numpydoc Attributes of ``cls``."""
    entries, names, header = {}, [], None
    for line in (cls.__doc__ or "").splitlines():
        match = re.match(r"^    (\w[\w, ]*) : (\{[^}]*\}|[^,]+)(?:, (.+))?$", line)
        if match:
            names = [n.strip() for n in match.group(1).split(",")]
            header = (match.group(3) or "").strip()
            for name in names:
                entries[name] = [header, ""]
        elif names and line.startswith("        ") and line.strip():
            for name in names:
                entries[name][1] += (" " if entries[name][1] else "") + line.strip()
        elif not line.strip():
            names = []
    return {name: (unit, _first_sentence(text)) for name, (unit, text) in entries.items()}


def _first_sentence(text):
    sentence = re.split(r"(?<=[.)])\s+(?=[A-Z(])", text, maxsplit=1)[0]
    return sentence.rstrip(".") + "." if sentence else ""


@functools.cache
def declarations() -> dict[str, Declaration]:
    """Every parameter's :class:`Declaration`, by name (filter's and session's)."""
    out = {}
    for component, cls in (("filter", FilterParams), ("session", SessionParams)):
        docs = _docstring_entries(cls)
        for item in fields(cls):
            if item.name == "filter":
                continue
            unit, doc = docs.get(item.name, ("", ""))
            if not unit and item.name.endswith("_deg"):
                unit = "degrees"
            default = (item.default_factory() if item.default_factory is not MISSING
                       else item.default)
            low, high = item.metadata.get("range", (None, None))
            out[item.name] = Declaration(item.name, component, default, unit, doc, low, high,
                                         item.metadata.get("length", 0))
    return out


def declaration(name: str) -> Declaration:
    """The :class:`Declaration` of one parameter (ParameterError for an unknown name)."""
    try:
        return declarations()[name]
    except KeyError:
        raise ParameterError(f"unknown parameter {name!r}") from None


def with_changes(params: SessionParams, **changes) -> SessionParams:
    """``params`` (SessionParams) with declared parameters changed, each in its component."""
    by_component = {"filter": {}, "session": {}}
    for name, value in changes.items():
        by_component[declaration(name).component][name] = value
    return replace(params, filter=replace(params.filter, **by_component["filter"]),
                   **by_component["session"])
