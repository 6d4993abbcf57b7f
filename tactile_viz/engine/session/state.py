"""The exploration state of a session: everything a step changes besides the filter, the
random generators and the snapshots, in one dataclass that is checkpointed, sent to the
engine process, pickled and restored whole (adding a field needs no other edit)."""

from dataclasses import dataclass, field, fields, replace
from typing import Any, NamedTuple

import numpy as np


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


@dataclass
class ExplorationState:
    """What exploration remembers from step to step.

    Attributes
    ----------
    gpis_scale : float
        The GPIS kernel scale ``a`` of the last fit (its Newton update starts there).
    gpis_radius : float or None
        The thin-plate ``R`` kept from fit to fit (``gpis_box_tolerance``).
    gpis_spacing : float or None
        The surface grid's cell kept from step to step (``gpis_box_tolerance``).
    gpis_fits : int
        Fits since the scale's last Newton step (``gpis_refit_every``).
    gpis_cache : GramCache or None
        The last fit's Gram matrix and factor (:mod:`~tactile_viz.engine.gpis_incremental`;
        immutable, keyed by content: a fit extends it only where the content agrees).
    variance_cache : NodeVariance or None
        The last surface's lattice-node variances (:mod:`~tactile_viz.engine.gpis_variance`).
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
    telling_apart : bool
        Whether ``target`` is where rival hypotheses disagree (beyond the paper).
    check : Check or None
        The check the next step sweeps.
    check_directions : list of (3,) float
        The directions of the checks so far.
    checks_passed : int
        Checks in a row that touched nothing unpredicted.
    hypotheses : tuple of Hypothesis
        The plausible hypotheses of the last decision, weighed again at the next
        (:func:`~tactile_viz.engine.decision.decide`).
    decision_checks : int
        Checks in a row around a MAP ready to be decided that touched nothing it does not
        predict.
    confirming : bool
        Whether ``check`` is such a check.
    telling_steps : int
        Steps whose target was where rival hypotheses disagree.
    moves_rng : dict or None
        The session rng's state when the step in progress began (None between steps).
    results : list of Contact or NonContact
        The results of the step's guarded moves so far.
    held : tuple or None
        ``(observations, free space)`` given before the first contact ever, kept for its step.
    """

    gpis_scale: float = 1.0
    gpis_radius: Any = None
    gpis_spacing: Any = None
    gpis_fits: int = 0
    gpis_cache: Any = None
    variance_cache: Any = None
    target: Any = None
    given_up: list = field(default_factory=list)
    free_space: np.ndarray = field(default_factory=_points)
    swept: np.ndarray = field(default_factory=_points)
    missed: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    frontier: list = field(default_factory=list)
    frontier_target: bool = False
    telling_apart: bool = False
    check: Any = None
    check_directions: list = field(default_factory=list)
    checks_passed: int = 0
    hypotheses: tuple = ()
    decision_checks: int = 0
    confirming: bool = False
    telling_steps: int = 0
    moves_rng: Any = None
    results: list = field(default_factory=list)
    held: Any = None

    def copy(self):
        """A copy whose lists are new (arrays and tuples are replaced, never changed)."""
        return replace(self, **{f.name: list(getattr(self, f.name)) for f in fields(self)
                                if isinstance(getattr(self, f.name), list)})
