"""The guarded moves of a step: l.7 of Algorithm 2 (reach for the target the last step
chose) or the first touch, a check, an RRT step, each a generator that yields a path and is
sent what the sensor found (:class:`~.loop.Session` drives it move by move)."""

import numpy as np

from ..explore.exploration import enforce_contact_moves, first_contact_moves, rrt_moves
from ..explore.scene_moves import first_moves, reach_moves, rrt_scene_moves
from ..params import PAPER_SIZE
from .fields import deepest_inside, free_approach
from .planner import SWEEP_RADIUS

# Lengths in size units (a sixth of the object's longest side; see ..params):
RRT_MARGIN = 3.0  # the RRT's workspace: the contacts' box grown by this
FIRST_LINE_REACH = 10.0  # the random first lines run this far on either side of the origin


def one_move(path):
    """A procedure of one guarded move: returns ``([path], [result])``."""
    result = yield path
    return [path], [result]


def step_procedure(part, rng, sensor_step=None):
    """``(kind, generator of guarded moves)`` for the step.

    Parameters
    ----------
    part : Bookkeeper
        The step's bookkeeper (:meth:`~.loop.Session.parts`): its context, filter and
        exploration state say what the step does.
    rng : numpy.random.Generator
        The step's own generator (replayed from the state at the step's start).
    sensor_step : float or None
        How finely the sensor samples a path (scene units; None: 1/300 of the size).

    Returns
    -------
    kind : {"first", "rrt", "check", "target"}
    procedure : generator
    """
    context, filter_, state = part.context, part.filter, part.state
    contacts, normals = filter_.contact_positions, filter_.contact_normals
    p, unit, scene, strategy = context.p, context.unit, context.scene, context.strategy
    if len(contacts) == 0 or (state.target is None and state.check is None
                              and strategy != "rrt"):
        reach = FIRST_LINE_REACH * context.filter_unit
        if scene.is_free:
            return "first", first_contact_moves(np.zeros(3), rng, radius=reach,
                                                unit=context.filter_unit)
        centre = scene.table_point if scene.has_table else np.zeros(3)
        return "first", first_moves(scene, centre, rng, reach, unit=context.filter_unit)
    if strategy == "rrt":
        box = contacts.min(axis=0) - RRT_MARGIN * unit, contacts.max(axis=0) + RRT_MARGIN * unit
        if scene.is_free:
            return "rrt", rrt_moves(contacts, normals, box, rng, p.rrt_step, p.probe_depth,
                                    0.5 * unit, unit)
        return "rrt", rrt_scene_moves(scene, contacts, normals, box, rng, p.rrt_step,
                                      p.probe_depth, p.approach_clearance, unit)
    if state.check is not None:
        return "check", one_move(state.check.path)
    target, normal, estimate = state.target
    depth = deepest_inside(estimate, target, normal, p.probe_depth)
    # The way back ends two sensor steps inside the anchor (1/150 of the size), and three
    # position-noise stds more with a noisy sensor.
    step = unit * PAPER_SIZE / 300 if sensor_step is None else sensor_step
    back = 2 * step + 3 * context.sensor_noise[0]
    if scene.is_free:
        clearance = free_approach(estimate, target, normal, p.approach_clearance, unit)
        return "target", enforce_contact_moves(
            target, normal, contacts, normals, depth, clearance, p.follow_step,
            p.contact_spacing, p.max_follow, back, p.way_back_anchors)
    if part.novel_on_table():
        # A guarded move goes on to the table: past a part the reconstruction holds but
        # the object lacks (a GPIS's phantom handle), to what lies beyond it.
        depth = max(depth, SWEEP_RADIUS * unit)
    return "target", reach_moves(scene, target, normal, contacts, normals, depth,
                                 p.approach_clearance, p.follow_step, p.contact_spacing,
                                 p.max_follow, back, p.way_back_anchors, estimate, unit)
