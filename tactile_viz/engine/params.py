"""Parameters of the filter in one dataclass, with the paper's values as defaults, and
named presets on the speed/accuracy trade."""

from dataclasses import asdict, dataclass, fields, replace

import numpy as np


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
        positive = ("sigma_d", "sigma_n", "distance_step", "angle_step_deg")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        for name in ("lam", "known_fraction", "noncontact_fraction"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise ValueError(f"{name} must lie in (0, 1], got {value!r}")
        at_least_one = ("n_s", "init_rotations", "max_new_per_class", "max_particles",
                        "n_features", "refine_iterations")
        for name in at_least_one:
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)!r}")
        if self.neighbour_bins not in (0, 1):
            raise ValueError(f"neighbour_bins must be 0 or 1, got {self.neighbour_bins!r}")
        if self.n_features < 3:
            raise ValueError("n_features must be at least 3")
        if self.sdf_resolution < 8:
            raise ValueError("sdf_resolution must be at least 8")

    def to_dict(self):
        return asdict(self)

    @classmethod
    def from_dict(cls, values):
        """Build from a dict, refusing unknown keys (a typo should not pass silently)."""
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown filter parameter(s): {', '.join(sorted(unknown))}")
        return cls(**values)


PRESETS = {
    # Coarser grids and fewer feature points: about half the time per step.
    "fast": FilterParams(n_features=120, sdf_resolution=48, n_s=15, max_new_per_class=800),
    # The paper's values.
    "paper": FilterParams(),
    # Finer grids, neighbour-bin look-up and MAP refinement.
    "accurate": FilterParams(n_features=300, sdf_resolution=96, neighbour_bins=1,
                             init_rotations=4, max_new_per_class=4000, refine_map=True),
}


def preset(name, **overrides):
    """A named preset, optionally with some parameters changed."""
    try:
        base = PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}") from None
    return replace(base, **overrides)
