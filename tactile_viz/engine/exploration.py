"""Active data acquisition: target selection and contact enforcement (paper, III-F).

A step of exploration returns the sensor paths it ran and the observations they gave:
usually one contact, sometimes a non-contact before it. Every function takes the
simulator (the only thing that touches the ground truth) and an ``rng``.
"""

import numpy as np
from scipy.spatial import cKDTree

from .errors import TactileVizError
from .observations import Contact
from .sdf import normalise_rows

STRATEGIES = ("gpis-dhd", "rrt")


def farthest_vertex(vertices, contacts):
    """Index of the vertex farthest from every contact (the DHD target): int."""
    distance = cKDTree(contacts).query(vertices)[0]
    return int(np.argmax(distance))


def first_contact(simulator, centre, rng, radius=10.0, attempts=50):
    """The random first touch: straight lines through the workspace from random directions.

    Returns
    -------
    paths : list of (2, 3) arrays
    observations : list
        Non-contacts for lines that missed, then the contact.
    """
    paths, observations = [], []
    for _ in range(attempts):
        direction = normalise_rows(rng.normal(size=(1, 3)))[0]
        offset = rng.uniform(-0.5, 0.5, size=3)
        path = np.stack([centre + offset + radius * direction, centre + offset - radius * direction])
        observation = simulator.probe(path)
        paths.append(path)
        observations.append(observation)
        if isinstance(observation, Contact):
            return paths, observations
    raise TactileVizError(f"no contact after {attempts} random lines through the workspace: "
                          "is the object near the origin?")


def enforce_contact(simulator, target, normal, contacts, contact_normals, depth=1.0,
                    clearance=0.5, follow_step=0.3):
    """Reach for a target; if the surface is not there, follow the surface toward it.

    The sensor moves from just outside ``target`` inward along ``-normal`` up to ``depth``.
    A miss is recorded as a non-contact; the sensor then goes back to the nearest contact and
    takes one step along its tangent plane toward the target, probing inward there.

    Returns
    -------
    paths : list of (k, 3) arrays
    observations : list of Contact / NonContact
    """
    path = np.stack([target + clearance * normal, target - depth * normal])
    observation = simulator.probe(path)
    if isinstance(observation, Contact):
        return [path], [observation]
    paths, observations = follow_surface(simulator, target, contacts, contact_normals,
                                         follow_step, depth, clearance)
    return [path] + paths, [observation] + observations


def follow_surface(simulator, toward, contacts, contact_normals, step=0.3, depth=1.0,
                   clearance=0.5):
    """One surface-following step from the contact nearest ``toward``, along its tangent."""
    nearest = int(cKDTree(contacts).query(toward)[1])
    start, normal = contacts[nearest], contact_normals[nearest]
    tangent = toward - start
    tangent -= (tangent @ normal) * normal
    length = np.linalg.norm(tangent)
    if length < 1e-9:
        tangent = np.cross(normal, [1.0, 0.0, 0.0])
        if np.linalg.norm(tangent) < 1e-6:
            tangent = np.cross(normal, [0.0, 1.0, 0.0])
        length = np.linalg.norm(tangent)
    moved = start + min(step, max(length, 1e-3)) * tangent / length
    path = np.stack([moved + clearance * normal, moved - depth * normal])
    observation = simulator.probe(path)
    if isinstance(observation, Contact):
        return [path], [observation]
    # Off an edge: come back toward the known contact, which must cross the surface.
    back = np.stack([moved + clearance * normal, start - 0.2 * normal])
    return [path, back], [simulator.probe(back)]


def rrt_step(simulator, contacts, contact_normals, workspace, rng, step=0.3, depth=1.0,
             clearance=0.5):
    """RRT-style exploration: a random workspace sample, projected on the tangent plane at
    its nearest contact, and a small surface-constrained step toward it."""
    low, high = workspace
    sample = rng.uniform(low, high)
    return follow_surface(simulator, sample, contacts, contact_normals, step, depth, clearance)
