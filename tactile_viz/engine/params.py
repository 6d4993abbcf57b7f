"""Parameters of the filter and of a session, each in one dataclass with the paper's values as
defaults. Every parameter is declared once, by its field (:func:`~.param_schema.param`):
component, kind, valid range, unit, the range a control offers and a one-line doc; the
validation, the docstrings' Attributes and the declarations for the GUI, the command line and
the benchmarks (:func:`declarations`) come from there. Named presets are in :mod:`.presets`.

Lengths
-------
Every length parameter is given in *size units*: one size unit is a sixth of an object's
longest side, so the paper's values, written for objects normalised to a longest side of 6,
keep their proportion to objects of any size in any unit (``eps = 0.6`` is 10% of the
object's size, in metres for a metric scene). A session turns them into scene units
(:func:`scaled_lengths`): the filter's (``sigma_d``, ``distance_step``, ``merge_distance``)
with the library's reference size (the median longest side of its priors), which all
classes share so that their likelihoods compare; the exploration's and the stop's with the
MAP object's longest side. ``SessionParams.length_unit`` fixes one size unit for all of
them instead (1: every length in scene units as written). On the paper's objects a size unit
is one scene unit, so the paper's configuration is unchanged. Fields that are lengths carry
``metadata["length"]``, the power of length in their unit.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from .errors import ParameterError
from .param_schema import (
    Declaration,
    check_fields,
    declarations_of,
    documented,
    length_fields,
    param,
)

PAPER_SIZE = 6.0  # longest side of the paper's normalised objects: one size unit is 1/6 of it
GPIS_KERNELS = ("wendland", "thin-plate")
CHECK_LINE_AIMS = ("gap", "gap-weakest", "contact")
CARVE_ESTIMATE = PRIOR_HOLDS = ("never", "noisy", "always")  # with a noisy sensor: "noisy"
_filter = functools.partial(param, component="filter")
_session = functools.partial(param, component="session")
_gpis = functools.partial(param, component="gpis")
_POSITIVE, _AT_LEAST_0, _AT_LEAST_1 = "(0, inf)", "[0, inf)", "[1, inf)"


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


@documented
@dataclass(frozen=True)
class FilterParams:
    """Knobs of the particle filter (paper, Table I and Sections III-A to III-C)."""

    sigma_d: float = _filter(
        0.5, "Std of the signed-distance likelihood (paper 0.5).", valid=_POSITIVE, length=1,
        control=(1e-3, 100.0), notes="Larger forgives misfit.")
    sigma_n: float = _filter(
        1.5, "Std of the normal likelihood (paper 1.5).", valid=_POSITIVE, control=(1e-3, 100.0))
    n_s: int = _filter(
        30, "Earlier contacts paired with each new one for point-pair sampling (paper 30).",
        kind="int", valid=_AT_LEAST_1, control=(1, 500))
    lam: float = _filter(
        0.97, "Sampling gate lambda (paper 0.97).", valid="(0, 1]", control=(0.01, 1.0),
        notes="New particles are sampled while the per-observation geometric mean of the "
              "MAP evidence relative to its maximum is below it.")
    known_fraction: float = _filter(
        0.9, "Novelty test: known iff the MAP evidence on the contacts reaches this fraction "
        "of its maximum per contact (paper 0.9) ...", valid="(0, 1]")
    noncontact_fraction: float = _filter(
        0.5, "... and its evidence on the non-contacts this probability per non-contact "
        "(paper 0.5).", valid="(0, 1]", notes="Each kind is tested on its own.")
    distance_step: float = _filter(
        0.1, "Point-pair key resolution of the distance (paper 0.1).", valid=_POSITIVE, length=1)
    angle_step_deg: float = _filter(
        12.0, "Point-pair key resolution of the angles (paper 12).", valid=_POSITIVE,
        unit="degrees")
    neighbour_bins: int = _filter(
        0, "0 looks up a pair's own key bin; 1 also the nearest neighbouring bins (24 bins, "
        "noise tolerance); 2 all neighbouring bins (81).", kind="int", valid="[0, 2]",
        notes="1 finds every model pair within one key step of the observed one in distance "
              "(two positions' noise) and half a step in each angle; 2 within one step in "
              "every component, at over three times the look-ups.")
    init_rotations: int = _filter(
        1, "Turns about the normal per feature point at the start.", kind="int", valid=_AT_LEAST_1)
    max_new_per_class: int = _filter(
        2000, "Particles sampled per class and step at most (a random subset).", kind="int",
        valid=_AT_LEAST_1)
    max_particles: int = _filter(
        20000, "Cap on the number of draws of the resampling step, and on the hypotheses the "
        "first touch spawns.", kind="int", valid=_AT_LEAST_1,
        notes="Beyond it a random subset of every feature point of every class.")
    max_candidates: int = _filter(
        4000, "Point-pair candidates scored on the whole subset of earlier contacts per new "
        "contact (beyond the paper, for large libraries; 0: all).", kind="int",
        valid=_AT_LEAST_0, notes="Beyond it, every candidate is first scored on four of the "
        "subset's contacts and only the best this many go on.")
    max_new_particles: int = _filter(
        0, "Particle budget (beyond the paper): at most this many of a step's new point-pair "
        "particles are kept, the heaviest (those resampling would keep anyway); 0 keeps "
        "all.", kind="int", valid=_AT_LEAST_0)
    support_sigma: float = _filter(
        0.15, "With a table (beyond the paper): std of a hypothesis' lowest point off the "
        "plane.", valid=_POSITIVE, length=1, control=(1e-3, 10.0),
        notes="A pose prior: a hypothesis floating above or sinking through the table by d "
        "costs (d / s)^2 / 2 nats, s this in quadrature with twice the position noise.")
    seed_stable_poses: bool = _filter(
        False, "With a table (beyond the paper): the first touch also seeds hypotheses "
        "resting in each prior's stable poses, turned about the vertical.", kind="bool",
        notes="trimesh's stable poses of at least 2% probability; a feature point on the "
        "contact fixes the turn and the translation.")
    merge_distance: float = _filter(
        0.0, "Particle merging (beyond the paper; 0 off): the translation cell size.",
        valid=_AT_LEAST_0, length=1, notes="After each step, particles of one class whose "
        "translations share a cell of this size and whose rotation vectors share a cell of "
        "merge_angle_deg become one, with their summed weight.")
    merge_angle_deg: float = _filter(
        1.0, "Particle merging: the rotation-vector cell size.", valid=_POSITIVE, unit="degrees")
    refine_map: bool = _filter(
        False, "Add a Gauss-Newton refinement of the MAP pose as a particle (beyond the paper).",
        kind="bool")
    refine_learned: int = _filter(
        3, "The same refinement of this many of the heaviest particles of each learned prior "
        "(beyond the paper; 0 off).", kind="int", valid=_AT_LEAST_0,
        notes="A learned shape's feature normals come from a reconstruction: its point-pair "
              "poses are coarser than a mesh's, and the novelty test failed at them.")
    learned_noise: bool = _filter(
        True, "The novelty test and the decision grant a learned MAP its own errors, "
        "shape_error and normal_error (beyond the paper).", kind="bool", notes="docs/novel.md.")
    refine_iterations: int = _filter(
        10, "Gauss-Newton steps of each pose refinement.", kind="int", valid=_AT_LEAST_1)
    refine_warm_iterations: int = _filter(
        3, "Under sensor noise, the steps of a contender's refinement that starts from its "
        "pose refined at the last step (0: every refinement starts afresh).", kind="int",
        valid=_AT_LEAST_0, notes="A particle that survived resampling was refined on all "
        "but the newest contact: a few steps from that pose suffice.")
    contenders: int = _filter(
        4, "Classes whose heaviest particles are refined to tell near twins apart (beyond "
        "the paper; 0 off).", kind="int", valid=_AT_LEAST_0, control=(0, 50),
        notes="For libraries of near twins (:mod:`.discrimination`): while several classes "
              "contend the MAP is the one whose refined pose fits best.")
    contender_mass: float = _filter(
        0.05, "The share of the posterior a class must hold to contend (0-1).", valid="[0, 1]")
    outlier_probability: float = _filter(
        0.0, "The chance that a contact is a wrong reading (beyond the paper; 0: the paper's "
        "Gaussian).", valid="[0, 0.5)", control=(0.0, 0.49),
        notes="A mixture with a flat density (see :mod:`.likelihood`), so that one outlier "
              "cannot kill the true hypothesis.")
    position_noise: float = _filter(
        0.0, "The sensor's position noise the novelty test allows for (0: the paper's test).",
        valid=_AT_LEAST_0, length=1, control=(0.0, 10.0),
        notes="Set by :func:`~.presets.noise_matched`: a reported contact may lie up to two "
              "stds off the surface along its normal; where such an offset crosses a fold "
              "(the grid's normal turns over 60 degrees: past a thin wall's middle) a "
              "contact's term is the best over the offsets, an offset costing as a distance "
              "does; the MAP is taken refined.")
    n_features: int = _filter(
        200, "Poisson-disk feature points per object (paper 200).", kind="int", valid="[3, inf)")
    sdf_resolution: int = _filter(
        64, "Voxels along the longest side of each prior's SDF grid.", kind="int", valid="[8, inf)")
    sdf_max_resolution: int = _filter(
        256, "Up to how many voxels a prior's SDF grid is refined for thin parts (at most "
        "sdf_resolution: never).", kind="int", valid="[0, inf)",
        notes="Doubled while over 1% of the surface sees the grid's normal over 60 degrees "
              "off (a fork's tines), up to about 10 MB a grid; exact within 4 voxels of the "
              "surface, and beyond as exact as the sdf_resolution grid (or its band).")
    sdf_exact_band: float = _filter(
        0.0, "Voxels from the surface within which a prior's SDF grid is exact; farther "
        "nodes are interpolated from coarser grids (0: exact at every node).", valid="[0, inf)",
        notes="4 in the recognise preset: 16,000-face priors build 2-3x faster; beyond the "
              "band a value is off by up to 15-25% of the distance, never in sign. A novel "
              "object's contacts lie far from every prior's: worse with a band.")

    def __post_init__(self):
        check_fields(self)

    def to_dict(self):
        return asdict(self)

    @classmethod
    def from_dict(cls, values):
        """Build from a dict, refusing unknown keys (a typo should not pass silently)."""
        if not isinstance(values, dict):
            raise ParameterError(f"filter parameters must be a dict, got {type(values).__name__}")
        unknown = set(values) - {f.name for f in fields(cls)}
        if unknown:
            raise ParameterError(f"unknown filter parameter(s): {', '.join(sorted(unknown))}")
        return cls(**values)


@documented
@dataclass(frozen=True)
class SessionParams:
    """Knobs of a session beyond the filter's (paper, Table I and Section III-H); ``filter``
    holds the filter's (:class:`FilterParams`)."""

    filter: FilterParams = field(default_factory=FilterParams)
    eps: float = _session(
        0.6, "Termination threshold on the DHD from the estimated surface to the contacts.",
        valid=_POSITIVE, length=1, control=(0.05, 10.0),
        notes="With cover_prior the MAP prior of a novel object counts too; the surface near "
              "targets the sensor could not reach and near missed probes' paths is left out.")
    max_steps_known: int = _session(
        300, "Step cap while judged known (paper 300).", kind="int", valid=_AT_LEAST_1)
    max_steps_novel: int = _session(
        400, "Step cap while judged novel (paper 400).", kind="int", valid=_AT_LEAST_1)
    gpis_noise: float = _gpis(
        1e-4, "Observation noise variance of the GPIS (paper 1e-4).", valid=_POSITIVE, length=2)
    gpis_edge_tilt: float = _gpis(
        1.0, "Under position noise s, a contact's GPIS gradient rows allow its normal a tilt "
        "of this x sqrt(s / size) rad (beyond the paper; 0: the sensor's normal noise alone).",
        valid="[0, 10]", notes="A contact the noise moves across an edge or a thin wall carries "
        "a normal from its other side; their share of the contacts grows as s / size.")
    gpis_scale: float = _gpis(
        1.0, "Initial kernel scale a_0 of the GPIS.", valid=_POSITIVE, length=-1,
        unit="per size unit (thin-plate; Wendland: size units squared)")
    gpis_resolution: int = _gpis(
        32, "Marching-cubes cells along the reconstruction box's longest side.", kind="int",
        valid="[8, inf)")
    gpis_margin: float = _gpis(
        0.6, "Margin of the reconstruction box about the MAP shape and contacts.", valid=_POSITIVE,
        length=1)
    gpis_kernel: str = _gpis(
        "thin-plate", "The GPIS kernel: the paper's thin-plate, or the compact Wendland.",
        kind="choice", choices=GPIS_KERNELS,
        notes="thin-plate corrects the whole box (as accurate, fails less badly, half the "
              "time: docs/bench-novel.md); wendland only within gpis_support.")
    gpis_support: float = _gpis(
        4.0, "Support radius c of the Wendland kernel.", valid=_POSITIVE, length=1)
    gpis_radius_factor: float = _gpis(
        1.2, "Thin-plate R over the reconstruction box's diagonal.", valid=_POSITIVE,
        notes="1.0 is the paper's \"largest distance\" (its indefinite Gram matrix is "
              "projected on the PSD cone); 1.2 makes it positive definite.")
    gpis_noncontacts: bool = _gpis(
        False, "Non-contacts inside the prior observe f = gpis_noncontact_value (beyond the "
        "paper).", kind="bool", notes="Value only, which removes the prior's surface where "
        "a probe passed through it.")
    gpis_noncontact_value: float = _gpis(
        0.1, "The GPIS value a non-contact observes (gpis_noncontacts, gpis_refute_rounds).",
        valid=_POSITIVE, length=1)
    gpis_refute_rounds: int = _gpis(
        0, "Refits, at most, with the non-contacts the fit puts inside observing f = "
        "gpis_noncontact_value (beyond the paper; 0: none).", kind="int", valid="[0, 10]",
        notes="A miss far from every contact removes a bulge of the fit; mixed (docs/gpis.md).")
    gpis_carve_radius: float = _gpis(
        0.6, "Radius of the balls cut out of the GPIS prior mean around non-contacts (beyond "
        "the paper; 0 keeps the prior whole).", valid=_AT_LEAST_0, length=1,
        notes="At most the distance to the nearest contact, around every non-contact and "
              "missed probe's sample: a probe through a wrong prior's phantom removes it.")
    gpis_carve_disk: float = _gpis(
        1.0, "No carve ball reaches a contact's disc of this many contact_spacing in its "
        "tangent plane (beyond the paper; 0: the contact alone).", valid=_AT_LEAST_0,
        control=(0.0, 3.0), notes="A disc ends at a free point beside it: docs/gpis.md.")
    gpis_fill_radius: float = _gpis(
        0.0, "Largest solid ball added to the GPIS prior mean behind a contact that the prior "
        "puts in its empty space (beyond the paper; 0 keeps the prior as it is).",
        valid=_AT_LEAST_0, length=1, control=(0.0, 6.0),
        notes="The ball tangent at the contact holding no other contact or free point. It "
              "mends a ball against a mug's cavity but fills a thin wall's cavity before "
              "its inside is touched (the protocol worse): off (docs/novel.md).")
    gpis_carve_outside: bool = _gpis(
        True, "Free-space points outside the prior's solid cut their balls out of it too "
        "(beyond the paper; False: only those a probe found inside it).", kind="bool",
        notes="Off, a probe beside a real part (a sofa's foot) spares it, but priors of the "
              "wrong class keep their phantoms (the dragon, worse): docs/gpis.md.")
    gpis_fill_voids: bool = _gpis(
        False, "Fill the GPIS estimate's voids, outside regions enclosed by its solid, before "
        "its surface is extracted (beyond the paper): the surface is the one a probe could "
        "reach if the estimate were right.", kind="bool",
        notes="A void can be an opening closed too early (the dragon was worse with it): "
              "off by default (docs/novel.md).")
    gpis_agnostic: bool = _gpis(
        True, "The GPIS prior mean is a superquadric fitted to the contacts (an ellipsoid, a "
        "rounded or a sharp box) while their GP evidence favours it over the MAP shape's "
        "(beyond the paper).", kind="bool",
        notes="The contacts' log marginal likelihood under each prior mean, at one fit's "
              "kernel and scale; the prior in force changes when another is ahead by 10 "
              "nats and a tenth of its own. A library of a few unlike priors leaves parts "
              "of the MAP shape that nothing supports (a mug's cavity inside a ball); with "
              "a superquadric in force the MAP prior's surface need not be covered "
              "(cover_prior). docs/novel.md.")
    gpis_prior_hold: str = _gpis(
        "noisy", "A novel object's GPIS prior keeps the MAP shape's last pose until the MAP "
        "particle's is 10 nats ahead in the contacts' GP evidence (beyond the paper): never, "
        "with a noisy sensor, or always.", kind="choice", choices=PRIOR_HOLDS,
        notes="Targets, prior cover and snapshot follow the pose held; noiseless it was "
              "mixed on bench learn and the protocol (docs/novel.md).")
    gpis_carve_estimate: str = _gpis(
        "never", "Cut the carve's balls out of the GPIS posterior mean too, the estimate "
        "itself, where no contact is within eps (beyond the paper): never, with a noisy "
        "sensor, or always.", kind="choice", choices=CARVE_ESTIMATE,
        notes="It removes the fit's phantoms but dents thin true parts a probe passed "
              "near: mixed on the protocol and on bench learn (docs/journal/not-kept.md).")
    gpis_incremental: bool = _gpis(
        False, "Extend the GPIS factor by a block per new contact and sum its mean by a "
        "compiled loop (beyond the paper; False: refit in full each step).", kind="bool",
        notes="On in the fast preset; off by default: it changes the trajectories and is "
              "no faster beside 400 variance points (docs/gpis.md).")
    gpis_refit_every: int = _gpis(
        10, "The kernel scale's Newton step every this many fits (1: all, the paper's).",
        kind="int", valid="[1, 100]",
        notes="A full fit without it is one Cholesky factorisation instead of two and the "
              "inverse. Under 10 contacts every fit takes it, then every contacts // 10 fits up "
              "to this many. gpis_incremental also refits when gpis_refit_score asks.")
    gpis_refit_score: float = _gpis(
        4.0, "With gpis_incremental: also refit when the likelihood's gradient in the log "
        "scale exceeds this many standard deviations.", valid="[0.5, 100]")
    gpis_box_tolerance: float = _gpis(
        0.1, "With gpis_incremental: R and the grid cell are kept while the box stays within "
        "this share of theirs.", valid="[0, 1]")
    cover_prior: bool = _session(
        True, "A novel object's exploration also has to cover the MAP prior's surface "
        "(beyond the paper).", kind="bool",
        notes="Within eps of a contact, or refuted by a missed probe: a reconstruction "
              "that shrank away from the untouched prior cannot pass the stop.")
    cover_prior_poses: int = _session(
        8, "The prior cover asks only for MAP vertices within eps / 2 of the class's SDF "
        "averaged over this many of its heaviest poses: a part they place apart is no "
        "prediction (beyond the paper; 1: all; docs/novel.md).", kind="int", valid="[1, 64]")
    missed_parts: int = _session(
        10, "Targets given up on a detached part of a novel estimate that no contact comes "
        "within eps of, after which exploration leaves the whole part out (beyond the paper; "
        "0: never).", kind="int", valid=_AT_LEAST_0)
    follow_unheld: bool = _session(
        True, "A contact a novel estimate leaves farther than a check's surprise from its surface "
        "queues frontier targets contact_spacing about it, once (beyond the paper).", kind="bool")
    target_uncovered: bool = _session(
        False, "The GPIS-DHD target is the largest variance among the surface vertices still "
        "farther than eps from every contact (beyond the paper).", kind="bool")
    target_farthest: bool = _session(
        True, "Where the GPIS variance does not grow away from the contacts, the novel target "
        "is the candidate farthest from them (beyond the paper).", kind="bool", notes="Once "
        "the fitted scale falls to the noise's order, the largest variance lies beside the "
        "contacts (engine/explore/exploration.py, grows_away).")
    target_noise_stds: float = _session(
        4.0, "Under position noise, the GPIS-DHD target and a check's surprise lie farther "
        "than this many noise standard deviations from every contact (beyond the paper; 0: "
        "the paper's target).", valid="[0, 20]",
        notes="Under noise the GPIS variance is nearly flat over the surface, so the "
              "paper's target falls as often beside a contact as far from one.")
    cover_noise_stds: float = _session(
        2.0, "Under position noise, a known object's surface counts as covered within "
        "hypot(eps, this many noise standard deviations) of a contact (beyond the paper; 0: "
        "within eps).", valid="[0, 20]",
        notes="A small object's eps (10% of its size) can be the noise itself: contacts "
              "never come nearer its far corners than the noise allows. A novel object "
              "keeps eps (its estimate is what the touches make it).")
    own_size_share: float = _session(
        0.5, "A novel object whose contacts span under this share of its MAP prior's size "
        "(or its diameter / 1.25, or over 1.25 times it) explores at its own size: eps and "
        "the probes' lengths follow the contacts' diameter (beyond the paper; 0: the prior's).",
        valid="[0, 1]", control=(0.0, 1.0),
        notes="Once judged novel ten steps in a row and the span stopped growing (the "
              "last ten contacts, forty under the diameter / 1.25, widened it by at most a "
              "tenth): a thin object's first contacts span less than it (docs/novel.md).")
    check_lines: int = _session(
        48, "Checks that must touch nothing unpredicted before a covered novel object stops "
        "(beyond the paper; 0: the paper's stop).", kind="int", valid=_AT_LEAST_0,
        notes="Each must touch nothing farther than contact_spacing from the estimate and "
              "every contact; one that does restarts the count and grows a frontier: targets "
              "eps along four tangents, each surprising contact growing it again; no stop "
              "while one is queued (docs/bench-novel.md).")
    check_refit_every: int = _session(
        1, "While checks touch the object beside the estimate, no miss, fit it every this many "
        "steps (1: each; a stop fits afresh; docs/bench-speed.md).", kind="int", valid="[1, 100]")
    check_line_aim: str = _session(
        "gap-weakest", "Where each check sweeps: the widest gap, also the estimate's weakest "
        "support, or through a contact.", kind="choice", choices=CHECK_LINE_AIMS,
        notes="gap: the widest gap that nothing observed or estimated is near; "
              "gap-weakest: after every two, one about the estimate's vertex farthest from "
              "every contact; contact: a line through a random contact (docs/engine.md).")
    check_shell_inward: bool = _session(
        True, "A shell check's lattice reaches in to the band beside the estimate: its "
        "centre moves toward the estimate (beyond the paper).", kind="bool",
        notes="The shell's widest gap lies on its far rim, 2 eps out, and its lattice never "
              "met a part beside the estimate (an elephant's ear tip, docs/journal/novel.md).")
    check_shell_observed: bool = _session(
        True, "A check in the shell outside the estimate sweeps the place farthest from "
        "what was observed, not also from the estimated surface (beyond the paper; the "
        "surface is no observation).", kind="bool")
    variance_points: int = _gpis(
        400, "Surface vertices at which the GPIS variance is evaluated (a random subset).",
        kind="int", valid=_AT_LEAST_1,
        notes="The target is their largest variance; other vertices show the 4 nearest's "
              "inverse-distance mean. Each costs a solve against the factor (O(m^2)).")
    final_support_open: bool = _gpis(
        True, "The reported surface's support (final_candidates) leaves out the vertices "
        "the stop does: near given-up targets and missed probes.", kind="bool")
    final_support_near: bool = _gpis(
        True, "Under position noise, where misses refute the reported surface (final_candidates), "
        "a contact supports it within contact_spacing or target_noise_stds noise stds, not eps "
        "(beyond the paper).", kind="bool", notes="docs/gpis.md.")
    final_resolution: int = _gpis(
        64, "Marching-cubes cells along the longest side of the reconstruction reported when "
        "a novel session stops.", kind="int", valid="[8, inf)",
        notes="The steps' posterior mean sampled finer: at 32 cells a sofa's foot thinner "
              "than a cell can vanish (docs/bench-novel.md).")
    final_candidates: int = _gpis(
        10, "When a novel session stops with part of its reconstruction farther than eps "
        "from every contact, the reported surface is the newest one the contacts cover of "
        "this and the last this many steps' MAP priors (then, with gpis_agnostic, of the "
        "superquadrics fitted to the contacts), each without and with the carve's cut, "
        "else the best supported of them, without parts no contact comes within eps of "
        "(beyond the paper; 0: the step's own prior, whole).", kind="int", valid="[0, 100]",
        notes="A novel object's MAP prior switches from step to step, and a switch at the "
              "last step can leave surface far from every contact. Covered: every vertex "
              "within eps of a contact, the stop's own test (docs/gpis.md).")
    final_screen_resolution: int = _gpis(
        32, "Marching-cubes cells along the longest side of the surfaces the final candidates "
        "are screened on; only those that could be covered or win are extracted at "
        "final_resolution (0: all of them, docs/gpis.md).", kind="int", valid="[0, inf)")
    final_wall_cells: float = _gpis(
        2.0, "The final and learned surfaces: at least this many cells across the median "
        "wall touched on both sides, up to about 3,000 vertices, and a small one in its own "
        "box (beyond the paper; 0: both off).",
        valid="[0, 10]", notes="A 4 mm tine one cell across is a blob (docs/gpis.md).")
    learned_resolution: int = _gpis(
        64, "Marching-cubes cells along the longest side when a reconstruction is kept as a "
        "new prior (at final_resolution a stopped session's last surface, as reported).",
        kind="int", valid="[8, inf)")
    probe_depth: float = _session(
        1.0, "How deep contact enforcement reaches at most (the estimate's deepest point "
        "within it is probed).", valid=_POSITIVE, length=1)
    approach_clearance: float = _session(
        2.0, "How far outside a target the probe starts, along the estimated normal, at "
        "most.", valid=_POSITIVE, length=1,
        notes="It stops short of where the estimate predicts the object again: a long "
              "approach bumps into parts nothing predicted (the paper preset: 0.5).")
    follow_step: float = _session(
        0.1, "Length of one in-contact surface-following step of contact enforcement.",
        valid=_POSITIVE, length=1)
    contact_spacing: float = _session(
        0.3, "Surface following stops at a contact this far from every earlier one.",
        valid=_POSITIVE, length=1, notes="A target whose procedure ends nearer is given up.")
    max_follow: float = _session(
        3.0, "Longest surface-following path of one step.", valid=_POSITIVE, length=1)
    way_back_anchors: int = _session(
        3, "Contacts a missed target's way back tries in turn, nearest first (the paper: "
        "one).", kind="int", valid=_AT_LEAST_1, control=(1, 10),
        notes="A noisy reading can lie off a thin part (2 mm beside a fork's 3 mm tine): "
              "the way back to it touches nothing, and the steps after add no contact.")
    rrt_step: float = _session(
        0.3, "Length of one step of the RRT strategy.", valid=_POSITIVE, length=1)
    metric_samples: int = _session(
        3000, "Surface samples per shape for the error metrics.", kind="int", valid=_AT_LEAST_1)
    decision_confidence: float = _session(
        0.99, "A known object is decided once the MAP class and the MAP hold this share of "
        "their posteriors (beyond the paper).", valid="[0.5, 1)", control=(0.5, 0.999999),
        notes="The MAP class's share of the class posterior and the MAP's of the fit "
              "posterior of the distinct hypotheses (:mod:`~tactile_viz.engine.belief.decision`).")
    decision_pose_error: float = _session(
        0.05, "A decision also needs the MAP's pose known within this share of its longest "
        "side, or a learned shape's own error (at decision_confidence).", valid=_POSITIVE,
        control=(1e-3, 1.0), notes="The fit's Gauss-Newton covariance, as the displacement "
        "of the MAP surface along its normals; the success threshold is 10% (TWD).")
    decision_floor: float = _session(
        0.01, "How far a right hypothesis's contacts may lie off its surface besides the "
        "sensor's noise and the grid's own error.", valid=_POSITIVE, length=1,
        control=(1e-4, 1.0), notes="The contact's localisation (the simulator's is within "
        "0.01), shared by a place's contacts: on a robot, at least the scans' accuracy.")
    decision_cover: float = _session(
        2.4, "A decision also needs every point of the MAP surface within this distance of a "
        "contact (its DHD).", valid=_POSITIVE, length=1, control=(0.1, 12.0),
        notes="2.4 is 40% of the object's longest side: a wrong pose or class can fit "
              "contacts on one part within the noise.")
    decision_checks: int = _session(
        2, "With decision_targets: sweeps just outside the MAP that must touch nothing it "
        "does not predict before the object is decided.", kind="int", valid=_AT_LEAST_0,
        control=(0, 10), notes="Check lines, as a novel object's (a novel object can hold "
        "a part that a known one fits, a trident a knife).")
    decision_same_mode: float = _session(
        0.1, "Poses of one class whose surfaces agree within this distance (all but 1% of "
        "them; or twice the position noise) are one hypothesis.", valid=_POSITIVE, length=1,
        control=(1e-3, 2.0), notes="Symmetries of the shape are not rivals.")
    decision_refresh: int = _session(
        4, "Contacts between the decision's full searches, the only ones that decide (1: "
        "afresh every touch).", kind="int", valid=_AT_LEAST_1, control=(1, 50))
    decision_budget: int = _session(
        4, "New hypotheses a touch between full searches refines at most, besides the MAP's.",
        kind="int", valid=_AT_LEAST_0, control=(0, 50))
    decision_contacts: int = _session(
        64, "While a known MAP misfits, the contacts a decision search fits first, spread "
        "over the object; its lead is then tested on all, searched on all if it fits (0: all).",
        kind="int", valid=_AT_LEAST_0, control=(0, 1000))
    decision_normals: bool = _session(
        True, "The decided pose is fitted to the contacts' normals too, and a pose mode they "
        "refute is not open (beyond the paper).", kind="bool")
    decision_normals_p: float = _session(
        1e-4, "A lead whose contacts' normals misfit it at a chi-squared p-value below this is "
        "not decided (beyond the paper; 0: not tested).", valid="[0, 0.5]", control=(0.0, 0.1))
    decision_any_class: bool = _session(
        True, "The decision may be about a class its fits hold, not the filter's MAP; "
        "decided, that class is reported (beyond the paper).", kind="bool")
    decision_targets: bool = _session(
        True, "While undecided, touch where the plausible hypotheses' surfaces disagree "
        "most (beyond the paper; at most decision_patience steps).", kind="bool")
    decision_patience: int = _session(
        30, "Steps aimed at rivals at most (then the paper's targets and stop).", kind="int",
        valid=_AT_LEAST_0, control=(0, 300))
    decision_hold: bool = _session(
        True, "Once decided, each touch only refits the decided pose and keeps the decision "
        "while the contacts fit it within the noise (False: decide afresh every touch).",
        kind="bool", notes="A misfit, another MAP class or a lower posterior decides afresh.")
    decision_candidates: int = _session(
        2000, "Surface points of each hypothesis a telling target is chosen from (0: its "
        "feature points).", kind="int", valid=_AT_LEAST_0, control=(0, 20000),
        notes="A telling part can be small (a screwdriver's tip). Cost: distances at each.")
    misfit_novelty: float = _session(
        1e-6, "An object the paper's test judges known is novel once its MAP's refined "
        "residuals have a chi-squared p-value below this, all of them, their means by "
        "place or their stretch, 5 steps in a row with contacts all around it (beyond the "
        "paper; 0: the paper's test alone).", valid="[0, 0.5]", control=(0.0, 0.01),
        notes="The paper's sigma_d is 8% of the size: a look-alike of equal size passes its "
              "test. By place or as a stretch, the noise averages out and a misfit does not "
              "(engine/belief/grouped.py, stretch.py, docs/novel.md).")
    stop_at_decision: bool = _session(
        False, "Stop as soon as the object is decided (a robot that only needs to "
        "recognise).", kind="bool", notes="False: go on to the DHD stop for shape.")
    length_unit: object = _session(
        None, "Scene units per size unit for every length parameter (None: from the "
        "objects' sizes).", kind="optional-float", valid=_POSITIVE,
        notes="None (the default): the filter's lengths scale with the library's reference "
              "size and the others with the MAP object's longest side (one size unit is a "
              "sixth of it); a number fixes it for all (1: lengths in scene units as "
              "written). See the module's docstring.")

    def __post_init__(self):
        if not isinstance(self.filter, FilterParams):
            raise ParameterError(f"filter must be FilterParams, got {type(self.filter).__name__}")
        check_fields(self)

    def to_dict(self):
        values = asdict(self)
        values["filter"] = self.filter.to_dict()
        return values

    @classmethod
    def from_dict(cls, values):
        if not isinstance(values, dict):
            raise ParameterError(f"session parameters must be a dict, got {type(values).__name__}")
        values = dict(values)
        unknown = set(values) - {f.name for f in fields(cls)}
        if unknown:
            raise ParameterError(f"unknown session parameter(s): {', '.join(sorted(unknown))}")
        values["filter"] = FilterParams.from_dict(values.get("filter", {}))
        return cls(**values)


# ------------------------------------------------------------------ declarations
@functools.cache
def declarations() -> dict[str, Declaration]:
    """Every parameter's :class:`~.param_schema.Declaration`, by name (the filter's and the
    session's)."""
    return {**declarations_of(FilterParams), **declarations_of(SessionParams)}


def declaration(name: str) -> Declaration:
    """One parameter's :class:`~.param_schema.Declaration` (ParameterError if unknown)."""
    try:
        return declarations()[name]
    except KeyError:
        raise ParameterError(f"unknown parameter {name!r}") from None


def with_changes(params: SessionParams, **changes) -> SessionParams:
    """``params`` (SessionParams) with declared parameters changed, the filter's in
    ``params.filter``."""
    ours = {"filter": {}, "session": {}}
    for name, value in changes.items():
        ours["filter" if declaration(name).component == "filter" else "session"][name] = value
    return replace(params, filter=replace(params.filter, **ours["filter"]), **ours["session"])


__all__ = ["CARVE_ESTIMATE", "CHECK_LINE_AIMS", "Declaration", "FilterParams", "GPIS_KERNELS",
           "PAPER_SIZE", "PRIOR_HOLDS", "SessionParams", "declaration", "declarations",
           "length_fields", "scaled_lengths", "with_changes"]
