"""What the parts of a step are given: a :class:`StepContext` (the parameters with their
lengths in scene units, the size unit, the sensor model, the scene), the filter, the
exploration state, the session's generator and its snapshots.

The parts (:class:`~.estimate.Estimator`, :class:`~.planner.Planner`,
:class:`~.bookkeeping.Bookkeeper`) are plain objects built from these inputs, so each is
tested without a :class:`~.loop.Session`; a session builds them afresh whenever its
lengths change (:meth:`~.loop.Session.parts`). And what a session asks of its sensor
(:class:`Sensor`).
"""

from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, Union

import numpy as np

from ..explore.observations import Contact, NonContact
from ..scene import FREE, Scene


@dataclass(frozen=True)
class StepContext:
    """The lengths and the sensor model a step's parts work with.

    Attributes
    ----------
    p : SessionParams
        The session's parameters with their lengths in scene units
        (:func:`~.lengths.session_lengths`).
    unit : float
        Scene units of a size unit (a sixth of the MAP object's longest side).
    filter_unit : float
        The library's size unit (what the filter's lengths are in).
    sensor_noise : tuple of float
        ``(position std in scene units, normal std in degrees)`` the model assumes.
    scene : Scene
        The robot's world (:data:`~..scene.FREE`: the paper's free space).
    strategy : str
        ``"gpis-dhd"`` or ``"rrt"``.
    tolerance : float or None
        How precisely the sensor places a contact (scene units; None: unknown).
    own_size : bool
        The object is explored at its own size, much smaller or larger than its MAP prior
        (``own_size_share``; :func:`~.lengths.own_unit`).
    """

    p: Any
    unit: float
    filter_unit: float
    sensor_noise: tuple = (0.0, 0.0)
    scene: Scene = FREE
    strategy: str = "gpis-dhd"
    tolerance: float | None = None
    own_size: bool = False


class Part:
    """A part of a step: its inputs, held as named attributes.

    Parameters
    ----------
    context : StepContext
    filter : ParticleFilter
        The belief: its contacts, non-contacts, models and bank are read, never changed.
    state : ExplorationState
        What the step changes besides the filter (each part's docstring says what it
        writes).
    rng : numpy.random.Generator, optional
        The session's exploration generator (draws in the step's order); a part built
        without one must not draw.
    snapshots : sequence of Snapshot
        The steps so far.
    """

    def __init__(self, context, filter, state, rng=None, snapshots=()):
        self.context, self.p, self.unit = context, context.p, context.unit
        self.sensor_noise, self.scene = context.sensor_noise, context.scene
        self.filter, self.state, self.snapshots = filter, state, snapshots
        self.rng = rng


class Parts(NamedTuple):
    """The parts of a step, built from one context (:meth:`~.loop.Session.parts`)."""

    estimator: Any
    planner: Any
    bookkeeper: Any


Observation = Union[Contact, NonContact]


class Sensor(Protocol):
    """What a session asks of a sensor: one guarded move (see :class:`~.snapshot.Move`)."""

    def probe(self, path: np.ndarray) -> Observation:
        """Move along ``path`` ((k, 3) world frame, scene units) until the first contact;
        the contact, or a non-contact at the path's end."""

    # Optional, read when present: ``step`` and ``tolerance`` (scene units), how finely
    # the sensor samples a path and places a contact; ``finish_step(observations)``, the
    # step's observations as the sensor revises them once its moves are done (the
    # simulator's wrong readings).
