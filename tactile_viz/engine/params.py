"""Parameters of the filter in one dataclass, with the paper's values as defaults, and
named presets on the speed/accuracy trade."""

import numbers
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from .errors import ParameterError


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
    sigma_d : float
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
    distance_step : float
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
        Cap on the number of draws of the resampling step.
    refine_map : bool
        Add a Gauss-Newton refinement of the MAP pose as a particle (beyond the paper).
    refine_iterations : int
    n_features : int
        Poisson-disk feature points per object (paper 200).
    sdf_resolution : int
        Voxels along the longest side of each prior's SDF grid.
    """

    sigma_d: float = 0.5
    sigma_n: float = 1.5
    n_s: int = 30
    lam: float = 0.97
    known_fraction: float = 0.9
    noncontact_fraction: float = 0.5
    distance_step: float = 0.1
    angle_step_deg: float = 12.0
    neighbour_bins: int = 0
    init_rotations: int = 1
    max_new_per_class: int = 2000
    max_particles: int = 20000
    refine_map: bool = False
    refine_iterations: int = 10
    n_features: int = 200
    sdf_resolution: int = 64

    def __post_init__(self):
        integers = ("n_s", "init_rotations", "max_new_per_class", "max_particles",
                    "n_features", "refine_iterations", "neighbour_bins", "sdf_resolution")
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name in integers:
                object.__setattr__(self, item.name, _check_integer(item.name, value))
            elif item.name == "refine_map":
                if not isinstance(value, (bool, np.bool_)):
                    raise ParameterError(f"refine_map must be True or False, got {value!r}")
            else:
                _check_real(item.name, value)
        positive = ("sigma_d", "sigma_n", "distance_step", "angle_step_deg")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
        for name in ("lam", "known_fraction", "noncontact_fraction"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise ParameterError(f"{name} must lie in (0, 1], got {value!r}")
        at_least_one = ("n_s", "init_rotations", "max_new_per_class", "max_particles",
                        "n_features", "refine_iterations")
        for name in at_least_one:
            if int(getattr(self, name)) < 1:
                raise ParameterError(f"{name} must be at least 1, got {getattr(self, name)!r}")
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


PRESETS = {
    # Coarser grids and fewer feature points: about half the time per step.
    "fast": FilterParams(n_features=120, sdf_resolution=48, n_s=15, max_new_per_class=800),
    # The paper's values.
    "paper": FilterParams(),
    # The paper's values plus the local refinement of the MAP pose (beyond the paper).
    "refined": FilterParams(refine_map=True),
    # Finer grids, neighbour-bin look-up and MAP refinement.
    "accurate": FilterParams(n_features=300, sdf_resolution=96, neighbour_bins=1,
                             init_rotations=4, max_new_per_class=4000, refine_map=True),
}


def preset(name, **overrides):
    """A named preset, optionally with some parameters changed."""
    try:
        base = PRESETS[name]
    except KeyError:
        raise ParameterError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}") from None
    return replace(base, **overrides)



def noise_matched(params, position_noise, normal_noise_deg):
    """Filter parameters for a sensor with Gaussian position and normal noise.

    The likelihood widths grow in quadrature with the noise: ``sigma_d`` with the position
    noise and ``sigma_n`` with the expected length of the normal error (a tilt by an angle
    of std ``s`` radians moves a unit normal by about ``s``). Once the noise reaches a
    quarter of a point-pair key bin (distance ``distance_step``, angles ``angle_step_deg``)
    observed pairs often fall into a neighbouring bin, so the neighbour-bin look-up is
    turned on.

    Parameters
    ----------
    params : FilterParams
    position_noise : float
        Standard deviation of the reported positions, object units.
    normal_noise_deg : float
        Standard deviation of the tilt of the reported normals, degrees.

    Returns
    -------
    FilterParams
    """
    _check_real("position_noise", position_noise)
    _check_real("normal_noise_deg", normal_noise_deg)
    if not (np.isfinite(position_noise) and position_noise >= 0):
        raise ParameterError(f"position_noise must be a finite number >= 0, got {position_noise!r}")
    if not (np.isfinite(normal_noise_deg) and normal_noise_deg >= 0):
        raise ParameterError(f"normal_noise_deg must be a finite number >= 0, "
                             f"got {normal_noise_deg!r}")
    angle = np.radians(normal_noise_deg)
    # The pair distance carries the noise of two positions; the angles that of a normal.
    coarse = (np.sqrt(2) * position_noise >= params.distance_step / 4
              or normal_noise_deg >= params.angle_step_deg / 4)
    return replace(params,
                   sigma_d=float(np.hypot(params.sigma_d, position_noise)),
                   sigma_n=float(np.hypot(params.sigma_n, angle)),
                   neighbour_bins=1 if coarse else params.neighbour_bins)
