"""Named presets on the speed/accuracy trade, and filter parameters matched to a noisy
sensor.

``recommended`` (the default) is the project's configuration, ``paper`` the paper exactly;
``fast``, ``refined`` and ``accurate`` move along the trade (docs/bench-tradeoff.md). Each
is one row of :data:`PRESET_TABLE`.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from .errors import ParameterError
from .param_schema import check_real
from .params import FilterParams, SessionParams, declaration, with_changes

# Every preset, once: name -> the declared parameters it changes from the defaults.
PRESET_TABLE = {
    # The project's configuration, the default: the paper's values plus shape transfer that
    # keeps the prior where the data agree (carved prior, prior coverage, check lines,
    # frontier) and the learned prior's pose refined.
    "recommended": {},
    # The paper exactly: its filter (without the discrimination of near twins and the
    # learned prior's refinement, which are beyond it), its GPIS as written (thin-plate
    # kernel with R the largest distance, contacts only), the stop as soon as the estimate
    # is covered.
    "paper": {"contenders": 0, "refine_learned": 0, "learned_noise": False,
              "gpis_kernel": "thin-plate",
              "gpis_radius_factor": 1.0, "gpis_noncontacts": False, "gpis_carve_radius": 0.0,
              "gpis_incremental": False, "gpis_refit_every": 1, "gpis_box_tolerance": 0.0,
              "cover_prior": False, "check_lines": 0, "approach_clearance": 0.5,
              "decision_targets": False, "decision_hold": False, "decision_refresh": 1,
              "decision_contacts": 0, "decision_normals": False, "decision_any_class": False,
              "decision_normals_p": 0.0,
              "sdf_max_resolution": 0,
              "final_candidates": 0, "final_wall_cells": 0.0, "final_support_near": False,
              "variance_points": 1500,
              "way_back_anchors": 1,
              "misfit_novelty": 0.0, "gpis_agnostic": False, "gpis_prior_hold": "never",
              "target_noise_stds": 0.0, "gpis_edge_tilt": 0.0,
              "target_farthest": False,
              "cover_noise_stds": 0.0, "own_size_share": 0.0, "missed_parts": 0,
              "follow_unheld": False},
    # A robot that only needs to know what and where the object is: the default, stopped
    # as soon as the object is decided, on grids exact only near the surface (a library
    # builds faster; a novel object's reconstruction is worse).
    "recognise": {"stop_at_decision": True, "sdf_exact_band": 4.0},
    # Coarser grids and fewer feature points, and the GPIS kept from step to step: about
    # half the time per step.
    "fast": {"n_features": 120, "sdf_resolution": 48, "n_s": 15, "max_new_per_class": 800,
             "gpis_resolution": 24, "final_resolution": 48, "variance_points": 250,
             "metric_samples": 2000, "gpis_incremental": True},
    # The default plus the local refinement of the MAP pose (beyond the paper).
    "refined": {"refine_map": True},
    # Finer grids, neighbour-bin look-up and MAP refinement.
    "accurate": {"n_features": 300, "sdf_resolution": 96, "neighbour_bins": 2,
                 "init_rotations": 4, "max_new_per_class": 4000, "refine_map": True,
                 "gpis_resolution": 48, "variance_points": 3000, "metric_samples": 5000},
}
# The filter presets (:func:`preset`) are the filter's part of these rows, except that the
# filter preset ``paper`` keeps the learned prior's refinement (as it always has).
FILTER_PRESET_NAMES = ("fast", "paper", "refined", "accurate")
_FILTER_PRESET_KEEPS = {"paper": ("refine_learned",)}


def _filter_preset(name):
    kept = _FILTER_PRESET_KEEPS.get(name, ())
    return FilterParams(**{key: value for key, value in PRESET_TABLE[name].items()
                           if declaration(key).component == "filter" and key not in kept})


PRESETS = {name: _filter_preset(name) for name in FILTER_PRESET_NAMES}


def preset(name: str, **overrides) -> FilterParams:
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
    of std ``s`` radians moves a unit normal by about ``s``), and the novelty test allows
    for the position noise (``position_noise``). Once the noise reaches a
    quarter of a point-pair key bin (distance ``distance_step``, angles ``angle_step_deg``)
    observed pairs often fall into a neighbouring bin, so the neighbour-bin look-up is
    turned on: the nearest neighbouring bins (``neighbour_bins=1``, 24 bins rather than
    all 81 of ``2``), so that noise multiplies the candidates less.

    Parameters
    ----------
    params : FilterParams
    position_noise : float
        Standard deviation of the reported positions, in the units of ``params``' lengths
        (scene units once :func:`scaled_lengths` made them so).
    normal_noise_deg : float
        Standard deviation of the tilt of the reported normals, degrees.

    Returns
    -------
    FilterParams
    """
    check_real("position_noise", position_noise)
    check_real("normal_noise_deg", normal_noise_deg)
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
                   position_noise=float(position_noise),
                   neighbour_bins=max(params.neighbour_bins, 1) if coarse
                   else params.neighbour_bins)


SESSION_PRESETS = {name: with_changes(SessionParams(), **changes)
                   for name, changes in PRESET_TABLE.items()}


DEFAULT_PRESET = "recommended"
# Old names still accepted, with a message: "faithful" was the paper's exact configuration
# before it took the name "paper" (which was the project's configuration, now "recommended").
RENAMED_PRESETS = {"faithful": "paper"}


def preset_name(name):
    """The current name of a preset name (an old one gives a FutureWarning)."""
    if name in RENAMED_PRESETS:
        warnings.warn(FutureWarning(f"the preset {name!r} is now called "
                                    f"{RENAMED_PRESETS[name]!r}"), stacklevel=3)
        return RENAMED_PRESETS[name]
    return name


def session_preset(name: str, **overrides) -> SessionParams:
    """Session parameters of a named preset (the keys of :data:`SESSION_PRESETS`; an old
    name of :data:`RENAMED_PRESETS` gives a FutureWarning)."""
    name = preset_name(name)
    try:
        return replace(SESSION_PRESETS[name], **overrides)
    except KeyError:
        raise ParameterError(f"unknown preset {name!r}; choose from "
                             f"{', '.join(SESSION_PRESETS)}") from None
