"""A robot at a table that is not the simulator, driving a session in both styles.

The robot carries out guarded moves, the one thing the engine asks of a sensor: move the
tip's centre along a polyline (world frame, metres) and stop at the first contact,
answering with the contact (the touched surface point, the outward normal) or with a
non-contact where the centre ended. This one does it by ray casting (trimesh), as a real
arm with a touch probe would by moving until the probe trips:

- the object is a bundled object scaled to a real size, resting at a stable pose on a
  table (z = 0, up +z);
- the probe is a sphere (5 mm radius by default): its centre touches the object where it
  reaches the mesh inflated by the radius (vertices moved along their normals), and the
  table where it reaches the plane raised by the radius; a contact reports the centre
  minus the radius times the normal (``Scene.surface_point``), a table contact a point on
  the plane with the normal up, which the engine recognises as a miss of the object;
- like a real controller it refuses (raises :class:`MoveRefused`) a path whose centre
  goes below the table or that travels outside its reach cone (60 degrees about straight
  down by default).

The engine, not the robot, does contact enforcement: after a miss it asks for the way back
to the nearest contact and for short moves along the surface toward the target. It is told
the robot's world with ``Session(..., scene=scene)`` and plans every path within it.

    python examples/robot.py                          # a 10 cm mug on a table, both styles
    python examples/robot.py --object vase_2          # a novel object: reconstructed
    python examples/robot.py --tip-radius 0.002 --reach-angle 45
    python examples/robot.py --no-table --reach-angle 180 --tip-radius 0   # floating, point
"""

import argparse

import numpy as np
import trimesh

from tactile_viz.assetgen.catalog import SIZES_M  # plausible sizes of the bundled objects
from tactile_viz.engine import Contact, NonContact, PriorLibrary
from tactile_viz.engine.errors import ParameterError
from tactile_viz.engine.explore.simulator import GroundTruth
from tactile_viz.engine.scene import FREE, Scene
from tactile_viz.engine.session import Session
from tactile_viz.engine.shape.metrics import error_threshold, pose_difference, two_way_hausdorff
from tactile_viz.engine.shape.objects import bundled_names, load_bundled
from tactile_viz.engine.shape.resting import resting_pose
from tactile_viz.engine.transforms import random_pose

SLACK = 1e-6  # metres: how far below the table the controller lets a waypoint be (rounding)
TOUCHING = 1e-9  # metres: a centre this near the raised table plane rests on it


class MoveRefused(RuntimeError):
    """The controller will not carry out a path (below the table, outside the reach)."""


class RayCastingRobot:
    """Guarded moves of a spherical tip on a mesh in the world frame, over a table.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The object where it stands, world frame, metres (watertight).
    scene : Scene, optional
        The table, the reach cone and the tip's radius (metres); default the paper's free
        space (no table, any direction, a point tip).

    Attributes
    ----------
    moves, touches, table_touches : int
        Guarded moves carried out; how many ended on the object, on the table.
    """

    def __init__(self, mesh, scene=None):
        self.mesh = mesh
        self.scene = FREE if scene is None else scene
        radius = self.scene.tip_radius
        # Where the tip's centre touches: the surface moved out by the radius. Face i of
        # the inflated mesh is face i of the object's (the same faces, moved vertices).
        inflated = trimesh.Trimesh(mesh.vertices + radius * mesh.vertex_normals, mesh.faces,
                                   process=False)
        self.rays = trimesh.ray.ray_triangle.RayMeshIntersector(inflated)
        self.moves = self.touches = self.table_touches = 0

    def probe(self, path):
        """Move the tip's centre along ``path`` ((k, 3) metres) until the first contact;
        the contact (surface point, outward normal), or a non-contact at the path's end.

        Raises
        ------
        MoveRefused
            For a path below the table or outside the reach cone: nothing moved.
        """
        path = np.atleast_2d(np.asarray(path, dtype=float))
        try:
            self.scene.check_path(path, SLACK)
        except ParameterError as error:
            raise MoveRefused(f"the controller refuses the move: {error}") from None
        self.moves += 1
        result, where = self._first_contact(path)
        if where == "object":
            self.touches += 1
        elif where == "table":
            self.table_touches += 1
        return result

    def _first_contact(self, path):
        """The result of a path the controller accepted, and what it touched: "object",
        "table" or None."""
        scene, start = self.scene, path[0]
        if self._start_touches(start):  # started in contact: the nearest surface point
            closest, _, face = trimesh.proximity.closest_point(self.mesh, start[None])
            return Contact(closest[0], self.mesh.face_normals[face[0]]), "object"
        for start, end in zip(path[:-1], path[1:]):
            length = float(np.linalg.norm(end - start))
            if length == 0:
                continue
            direction = (end - start) / length
            table = self._table_distance(start, end, length)
            points, _, faces = self.rays.intersects_location([start], [direction])
            ahead = np.reshape(points, (-1, 3)) @ direction - start @ direction  # (h,)
            first = int(np.argmin(ahead)) if len(ahead) else None
            if first is not None and ahead[first] <= min(length, table):
                normal = self.mesh.face_normals[faces[first]]
                # A robot measures its tip's centre; the contract wants the surface point.
                return Contact(scene.surface_point(points[first], normal), normal), "object"
            if table <= length:
                centre = start + table * direction
                return Contact(scene.surface_point(centre, scene.up), scene.up), "table"
        return NonContact(path[-1]), None

    def _start_touches(self, centre):
        """Whether the tip at ``centre`` already touches or is inside the object."""
        if self.mesh.contains(centre[None])[0]:
            return True
        radius = self.scene.tip_radius
        if radius == 0:
            return False
        _, distance, _ = trimesh.proximity.closest_point(self.mesh, centre[None])
        return distance[0] < radius

    def _table_distance(self, start, end, length):
        """How far along the segment the tip's centre reaches the table plane raised by the
        radius (inf: it does not, or there is no table)."""
        scene = self.scene
        if not scene.has_table:
            return np.inf
        low, high = scene.height(np.stack([start, end])) - scene.tip_radius
        if high >= low or high > TOUCHING:  # not down, or it ends above the table
            return np.inf
        if low <= TOUCHING:  # resting on the table, moving down into it
            return 0.0
        return min(length, length * low / (low - high))


def metric_library():
    """The ten known objects at plausible sizes, metres."""
    return PriorLibrary(load_bundled(name, size=SIZES_M[name])
                        for name in bundled_names("known"))


def place(name, seed, scene=None):
    """The object ``name`` where the robot finds it: with a ``scene`` that has a table, at
    a random stable pose on it (``resting_pose``), else at a random pose within 5 cm of the
    origin. Its model, the world mesh the robot touches, and the same placement for the
    simulator (a ``GroundTruth``)."""
    model = load_bundled(name, size=SIZES_M[name])
    if scene is not None and scene.has_table:
        rotation, translation = resting_pose(model, scene, [seed, 0])
    else:
        rotation, translation = random_pose(seed, 0.05)
    mesh = model.mesh.copy()
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, translation
    mesh.apply_transform(transform)
    return model, mesh, GroundTruth(model, rotation, translation)


def callback_style(library, robot, seed, steps, scene=None):
    """The robot as the session's sensor: ``step()`` asks it for each move."""
    session = Session(library, seed=seed, sensor=robot, scene=scene)
    session.run(max_steps=steps)
    return session


def ask_tell_style(library, robot, seed, steps, scene=None):
    """Event-driven robot software: ask for a move, carry it out, tell the result; at most
    ``steps`` steps (a step may take several moves)."""
    session = Session(library, seed=seed, scene=scene)
    while session.step_count < steps and not session.terminated:
        move = session.propose()               # a guarded move: move.path, the tip's centre
        result = robot.probe(move.path)        # here the robot's own motion code
        session.observe(result)                # a Snapshot once the step is complete
    return session


def report(session, mesh, truth=None):
    """Class, novelty, whether it is decided, touches of the object, the MAP pose's
    rotation error (degrees, up to the shape's symmetries) and translation error (mm)
    against ``truth`` (None for another class), and the estimate's distance to the object
    (metres and % of size)."""
    last = session.latest
    size = float(mesh.extents.max())
    truth_points = mesh.sample(3000, seed=0) if hasattr(mesh, "sample") else mesh.vertices
    shape = (last.gpis_vertices if last.novel and last.gpis_vertices is not None
             else last.map_vertices)
    error = two_way_hausdorff(shape, truth_points)
    angle = distance = None
    if truth is not None:
        angle, distance = pose_difference(session.library[last.map_class], last.map_rotation,
                                          last.map_translation, truth)
    return {"steps": last.step, "map_class": last.map_class, "novel": last.novel,
            "decided": last.decided,
            "decided_at": next((s.step for s in session.snapshots if s.decided), None),
            "touches": int(len(last.contacts)),
            "rotation_error_deg": angle,
            "translation_error_mm": None if distance is None else 1000 * distance,
            "error_m": error, "error_percent": 100 * error / size,
            "success": error < error_threshold(size)}


def describe(name, result):
    """One readable line of a result."""
    state = ("novel" if result["novel"] else
             f"known, decided at step {result['decided_at']}" if result["decided"] else
             "known, undecided")
    pose = ("pose: another class" if result["rotation_error_deg"] is None else
            f"rotation error {result['rotation_error_deg']:.1f} deg, translation error "
            f"{result['translation_error_mm']:.1f} mm")
    moves = (f" ({result['moves']} moves, {result['table_touches']} table touches)"
             if "moves" in result else "")
    return (f"{name:>9}: {result['map_class']} ({state}) after {result['steps']} steps, "
            f"{result['touches']} touches{moves}; {pose}; shape error "
            f"{1000 * result['error_m']:.1f} mm ({result['error_percent']:.1f}% of size)")


def scene_of(args):
    """The robot's world of the options, metres (the engine's ``Scene``)."""
    if args.table:
        return Scene.on_table(args.table_height, args.reach_angle, args.tip_radius)
    if args.reach_angle == 180 and args.tip_radius == 0:
        return FREE
    return Scene(None, (0.0, 0.0, 1.0), args.reach_angle, args.tip_radius)


def main(argv=None, sessions=None):
    """Run the example; the results by style ("simulator", "callback", "ask/tell").
    ``sessions``, a dict, receives the sessions by style."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="mug_1", choices=sorted(SIZES_M))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=60, help="steps at most (default 60)")
    parser.add_argument("--table", action=argparse.BooleanOptionalAction, default=True,
                        help="the object rests on a table at a stable pose (default); "
                             "--no-table: it floats at a random pose")
    parser.add_argument("--table-height", type=float, default=0.0, metavar="H",
                        help="the table's height z, metres (default 0)")
    parser.add_argument("--reach-angle", type=float, default=60.0, metavar="DEG",
                        help="half-angle of the reach cone about straight down, degrees in "
                             "(0, 180] (default 60; 180: any direction)")
    parser.add_argument("--tip-radius", type=float, default=0.005, metavar="R",
                        help="radius of the spherical tip, metres (default 0.005; 0: a point)")
    parser.add_argument("--no-simulator", action="store_true",
                        help="skip the simulator's run on the same placement (a reference)")
    args = parser.parse_args(argv)
    try:
        scene = scene_of(args)
    except ParameterError as error:
        parser.error(str(error))
    library = metric_library()
    model, mesh, truth = place(args.object, args.seed, scene)
    where = ("on a table" if scene.has_table else "floating")
    print(f"{args.object} ({model.length * 100:.0f} cm) {where}, tip radius "
          f"{scene.tip_radius * 1000:g} mm, reach {scene.reach_angle_deg:g} deg, seed "
          f"{args.seed}, at most {args.steps} steps")
    results = {}
    if not args.no_simulator:
        reference = Session.simulated(truth, library, seed=args.seed, scene=scene)  # for comparison
        reference.run(max_steps=args.steps)
        if sessions is not None:
            sessions["simulator"] = reference
        results["simulator"] = report(reference, mesh, truth)
        print(describe("simulator", results["simulator"]))
    for style, drive in (("callback", callback_style), ("ask/tell", ask_tell_style)):
        robot = RayCastingRobot(mesh, scene)
        session = drive(library, robot, args.seed, args.steps, scene)
        results[style] = report(session, mesh, truth)
        results[style].update(moves=robot.moves, object_touches=robot.touches,
                              table_touches=robot.table_touches)
        if sessions is not None:
            sessions[style] = session
        print(describe(style, results[style]))
    return results


if __name__ == "__main__":
    main()
