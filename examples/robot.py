"""A robot that is not the simulator, driving a session in both styles.

The robot carries out guarded moves, the one thing the engine asks of a sensor: move along
a polyline (world frame, metres) and stop at the first contact, answering with the contact
(position, outward normal) or with a non-contact at the end of the path. This one does it by
ray casting on a mesh placed in the world (trimesh), as a real arm with a touch probe would
by moving until the probe trips. The engine, not the robot, does contact enforcement: after
a miss it asks for the way back to the nearest contact and for short moves along the
surface toward the target.

    python examples/robot.py                    # a 10 cm mug, both styles
    python examples/robot.py --object vase_2    # a novel object: reconstructed
"""

import argparse

import numpy as np
import trimesh

from tactile_viz.engine import Contact, NonContact, PriorLibrary
from tactile_viz.engine.shape.metrics import error_threshold, two_way_hausdorff
from tactile_viz.engine.shape.objects import bundled_names, load_bundled
from tactile_viz.engine.session import Session
from tactile_viz.engine.explore.simulator import GroundTruth
from tactile_viz.engine.transforms import random_pose
from tactile_viz.experiments.sizes import SIZES_M  # plausible sizes of the bundled objects



class RayCastingRobot:
    """Guarded moves on a mesh in the world frame.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The object where it stands, world frame, metres.
    """

    def __init__(self, mesh):
        self.mesh = mesh
        self.rays = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)
        self.moves = 0

    def probe(self, path):
        """Move along ``path`` ((k, 3) metres) until the first contact; the contact, or a
        non-contact at the path's end."""
        self.moves += 1
        path = np.asarray(path, dtype=float)
        if self.mesh.contains(path[:1])[0]:  # started inside: the nearest surface point
            closest, _, face = trimesh.proximity.closest_point(self.mesh, path[:1])
            return Contact(closest[0], self.mesh.face_normals[face[0]])
        for start, end in zip(path[:-1], path[1:]):
            length = float(np.linalg.norm(end - start))
            if length == 0:
                continue
            direction = (end - start) / length
            points, _, faces = self.rays.intersects_location([start], [direction])
            if len(points):
                distance = (points - start) @ direction
                ahead = distance <= length
                if ahead.any():
                    first = int(np.argmin(np.where(ahead, distance, np.inf)))
                    return Contact(points[first], self.mesh.face_normals[faces[first]])
        return NonContact(path[-1])


def metric_library():
    """The ten known objects at plausible sizes, metres."""
    return PriorLibrary(load_bundled(name, size=SIZES_M[name])
                        for name in bundled_names("known"))


def place(name, seed):
    """The object ``name`` at a random pose (within 5 cm of the origin): its model, the
    world mesh the robot touches, and the same placement for the simulator."""
    model = load_bundled(name, size=SIZES_M[name])
    rotation, translation = random_pose(seed, 0.05)
    mesh = model.mesh.copy()
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, translation
    mesh.apply_transform(transform)
    return model, mesh, GroundTruth(model, rotation, translation)


def callback_style(library, robot, seed, steps):
    """The robot as the session's sensor: ``step()`` asks it for each move."""
    session = Session(None, library, seed=seed, sensor=robot)
    session.run(max_steps=steps)
    return session


def ask_tell_style(library, robot, seed, steps):
    """Event-driven robot software: ask for a move, carry it out, tell the result."""
    session = Session(None, library, seed=seed)
    while session.step_count < steps and not session.terminated:
        move = session.propose()               # a guarded move: move.path, metres
        result = robot.probe(move.path)        # here the robot's own motion code
        session.observe(result)                # a Snapshot once the step is complete
    return session


def report(session, mesh):
    """Class, novelty, whether it is decided, and the estimate's distance to the object
    (metres and % of size)."""
    last = session.latest
    size = float(mesh.extents.max())
    truth = mesh.sample(3000, seed=0) if hasattr(mesh, "sample") else mesh.vertices
    shape = (last.gpis_vertices if last.novel and last.gpis_vertices is not None
             else last.map_vertices)
    error = two_way_hausdorff(shape, truth)
    return {"steps": last.step, "map_class": last.map_class, "novel": last.novel,
            "decided": last.decided, "error_m": error, "error_percent": 100 * error / size,
            "success": error < error_threshold(size)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="mug_1", choices=sorted(SIZES_M))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=60)
    args = parser.parse_args(argv)
    library = metric_library()
    _, mesh, truth = place(args.object, args.seed)
    results = {}
    reference = Session(truth, library, seed=args.seed)  # the simulator, for comparison
    reference.run(max_steps=args.steps)
    results["simulator"] = report(reference, mesh)
    print(f"simulator: {results['simulator']}")
    for style, drive in (("callback", callback_style), ("ask/tell", ask_tell_style)):
        robot = RayCastingRobot(mesh)
        session = drive(library, robot, args.seed, args.steps)
        results[style] = report(session, mesh)
        results[style]["moves"] = robot.moves
        print(f"{style:>9}: {results[style]}")
    return results


if __name__ == "__main__":
    main()
