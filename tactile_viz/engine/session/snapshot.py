"""What a session hands out: immutable snapshots of each step, the guarded moves it asks
of a sensor, the targets it reaches for and the reconstruction of a novel object."""

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from ..shape.gpis_variance import lattice_low
from ..shape.level_set import box_closure

HYPOTHESES = 4  # poses after the MAP in each snapshot (the viewer's belief ghosts)


def frozen(array):
    array = np.array(array)
    array.flags.writeable = False
    return array


class _Deferred:
    """A field that may be given as a zero-argument callable, called on first read and
    kept (read-only): what only a viewer reads is computed only if one does. A pickled
    snapshot carries the value."""

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, instance, owner=None):
        if instance is None:
            raise AttributeError(self.name)  # (to dataclasses: a field without a default)
        value = instance.__dict__[self.name]
        if callable(value):
            value = instance.__dict__[self.name] = frozen(value())
        return value

    def __set__(self, instance, value):
        instance.__dict__[self.name] = value


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything a viewer or a benchmark needs after one step (arrays are read-only).

    Frames: everything is in the world frame. ``truth_coverage``, ``pose_error`` and
    ``recon_error`` (the paper's TWD on samples) are None in a session without a simulated
    object; ``recon_surface_error`` is the reconstruction's TWD from samples to the other
    surface, without the samples' floor, on the step that stops (None before)
    (:func:`~tactile_viz.engine.shape.metrics.surface_hausdorff`). ``gpis_resolution``
    is the marching-cubes cells of the GPIS surface (``final_resolution`` on the step that
    stops; None without a surface); ``gpis_radius`` its kernel's reach and ``gpis_spacing``
    its grid's cell when kept from step to step (else None); ``gpis_shape`` the
    object-agnostic prior mean its fit started from (None: the MAP shape's). ``decided`` (beyond the
    paper): the object is judged known and no other class or pose mode fits the contacts
    comparably
    (:mod:`~tactile_viz.engine.belief.decision`); ``decision_confidence`` the share the MAP holds.
    """

    step: int
    new_observations: tuple
    paths: tuple
    contacts: np.ndarray
    normals: np.ndarray
    noncontacts: np.ndarray
    free_space: np.ndarray
    map_class: str
    map_rotation: np.ndarray
    map_translation: np.ndarray
    map_vertices: np.ndarray
    map_faces: np.ndarray
    class_posterior: dict
    n_particles: int
    log_evidence: float
    log_threshold: float
    novel: bool
    gpis_vertices: object
    gpis_faces: object
    gpis_variance: object = _Deferred()
    gpis_scale: object
    target: object
    dhd: float
    truth_coverage: object
    pose_error: object
    recon_error: object
    terminated: bool
    timings: dict
    hypotheses: tuple = ()
    gpis_resolution: object = None
    gpis_radius: object = None
    gpis_spacing: object = None
    gpis_shape: object = None
    rotation_error_deg: object = None
    translation_error: object = None
    decided: bool = False
    decision_confidence: float = 0.0
    recon_surface_error: object = None

    def __getstate__(self):
        return {**self.__dict__, "gpis_variance": self.gpis_variance}

    @property
    def gpis_prior(self):
        """What the GPIS started from: the MAP class's name, the kind of a fitted
        superquadric (``"ellipsoid"``, ``"rounded box"``, ``"box"``), or None (no GPIS)."""
        if self.gpis_vertices is None:
            return None
        return self.map_class if self.gpis_shape is None else self.gpis_shape.kind

    def record(self):
        """The JSON record of this step (the ``trial`` command's contract)."""
        return {"t": self.step, "map_class": self.map_class, "pose_error": self.pose_error,
                "dhd": self.dhd, "truth_coverage": self.truth_coverage, "novel": self.novel,
                "recon_error": self.recon_error,
                "recon_surface_error": self.recon_surface_error,
                "n_particles": self.n_particles, "n_contacts": int(len(self.contacts)),
                "n_noncontacts": int(len(self.noncontacts)),
                "step_seconds": float(sum(self.timings.values())),
                "timings": {k: float(v) for k, v in self.timings.items()},
                "rotation_error_deg": self.rotation_error_deg,
                "translation_error": self.translation_error,
                "gpis_scale": self.gpis_scale, "gpis_prior": self.gpis_prior,
                "decided": bool(self.decided),
                "decision_confidence": float(self.decision_confidence),
                "map_rotation": self.map_rotation.tolist(),
                "map_translation": self.map_translation.tolist()}


def hypotheses(state, count=HYPOTHESES):
    """The ``count`` heaviest distinct poses of the filter after its MAP, as
    ``(class name, rotation, translation, weight)`` (weights of the duplicates summed)."""
    particles = getattr(state, "particles", None)
    if particles is None or len(particles) < 2:
        return ()
    weights = np.exp(particles.log_weights)
    keys = np.column_stack([particles.classes, particles.translations.round(3),
                            particles.rotations.reshape(len(particles), -1).round(3)])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    totals = np.bincount(inverse, weights, minlength=len(first))
    map_index = np.argmax(particles.log_weights) if state.map_index is None else state.map_index
    map_group = inverse[map_index]  # drawn on its own
    order = [k for k in np.argsort(-totals) if k != map_group][:count]
    return tuple((state.class_names[particles.classes[first[k]]],
                  frozen(particles.rotations[first[k]]),
                  frozen(particles.translations[first[k]]), float(totals[k]))
                 for k in order)


@dataclass(frozen=True)
class Reconstruction:
    """The GPIS estimate of a novel object in one step.

    Attributes
    ----------
    vertices : (v, 3) float
        The zero level set of the posterior mean (marching cubes), world frame.
    faces : (f, 3) int
    subset : (k,) int or None
        The vertices where the variance was evaluated (the target's candidates).
    candidate_variance : (k,) float
        Posterior variance at ``vertices[subset]``.
    fit : GPISFit
    resolution : int
        Marching-cubes cells along the box's longest side.
    spacing : float or None
        The grid's cell when kept from step to step (``gpis_incremental``), on a lattice
        anchored at the origin; None: the box's longest side over ``resolution``.
    vertex_variance : (v,) float or None
        The variance at every vertex where it was interpolated along the grid's edges
        (with ``spacing``); None: :attr:`variance` spreads the candidates'.
    bounds : ((3,) float, (3,) float) or None
        The box the surface was extracted in (world frame).
    """

    vertices: np.ndarray
    faces: np.ndarray
    subset: object
    candidate_variance: np.ndarray
    fit: object
    resolution: int
    spacing: object = None
    vertex_variance: object = None
    bounds: object = None

    @property
    def empty(self):
        return len(self.vertices) == 0

    def restricted(self, keep):
        """The same estimate on the vertices of mask ``keep`` (whole parts: a face is kept
        when its three vertices are) and the faces among them; with no variance sample
        left on them, no variance (zero)."""
        index = np.full(len(self.vertices), -1)
        index[keep] = np.arange(np.count_nonzero(keep))
        faces = index[self.faces[keep[self.faces].all(axis=1)]]
        subset, candidates = self.subset, self.candidate_variance
        if subset is not None:
            mine = keep[subset]
            subset, candidates = index[subset[mine]], candidates[mine]
            subset = subset if len(subset) else None
        vertex_variance = None if self.vertex_variance is None else self.vertex_variance[keep]
        return replace(self, vertices=self.vertices[keep], faces=faces, subset=subset,
                       candidate_variance=candidates, vertex_variance=vertex_variance)

    @cached_property
    def closure(self):
        """Mask of the vertices where the surface closes at its box, not where the fit
        crosses zero (:func:`~..shape.level_set.box_closure`), (v,) bool (none without
        ``bounds``)."""
        if self.bounds is None or self.empty:
            return np.zeros(len(self.vertices), bool)
        low = self.bounds[0] if self.spacing is None else lattice_low(self.bounds[0],
                                                                        self.spacing)
        return box_closure(self.vertices, (low, self.bounds[1]), self.resolution, self.spacing)

    @cached_property
    def variance(self):
        """Posterior variance at every vertex, (v,) float: ``vertex_variance``, else
        :func:`spread_variance` of the candidates' (computed when first read)."""
        if self.vertex_variance is not None:
            return self.vertex_variance
        if self.subset is None:
            return np.zeros(len(self.vertices))
        return spread_variance(self.vertices, self.subset, self.candidate_variance)

    def deferred_variance(self):
        """:attr:`variance`, or a callable that computes it without this object (a
        snapshot keeps what a viewer may draw, not the fit)."""
        if self.vertex_variance is not None or self.subset is None:
            return frozen(self.variance)
        vertices, subset, values = self.vertices, self.subset, self.candidate_variance
        return lambda: spread_variance(vertices, subset, values)


def spread_variance(vertices, subset, values, neighbours=4):
    """Values known at ``vertices[subset]`` spread to every vertex: each other vertex gets
    the inverse-distance mean of its ``neighbours`` nearest known ones (for display: the
    target is drawn from the subset).

    Parameters
    ----------
    vertices : (v, 3) float
    subset : (k,) int
    values : (k,) float

    Returns
    -------
    (v,) float
    """
    values = np.asarray(values, dtype=float)
    spread = np.empty(len(vertices))
    if len(subset) < len(vertices):
        k = min(neighbours, len(subset))  # as a list, k keeps the (v, k) shape at 1
        distance, nearest = cKDTree(vertices[subset]).query(vertices, k=list(range(1, k + 1)))
        weights = 1.0 / np.maximum(distance, 1e-12)
        spread = np.sum(weights * values[nearest], axis=1) / np.sum(weights, axis=1)
    spread[subset] = values
    return spread


@dataclass(frozen=True)
class Move:
    """A guarded move the session asks of the sensor: move along ``path`` and stop at the
    first contact.

    Attributes
    ----------
    path : (k, 3) float
        The polyline, world frame, scene units (k >= 2).
    kind : {"first", "target", "check", "rrt"}
        The procedure the move belongs to: random lines until the first contact, contact
        enforcement toward a target (the probe, then after a miss the way back to the
        nearest contact and the in-contact steps along the surface), a check line, an RRT
        step.
    number : int
        The move's place in its step (0 first).
    target : (3,) float or None
        The target the step reaches for (``kind == "target"``).
    """

    path: np.ndarray
    kind: str
    number: int
    target: object = None


def step_snapshot(step, filter, state, belief, estimate, recon, plan, decision, moves, errors):
    """The :class:`Snapshot` of a step.

    Parameters
    ----------
    step : int
        Its number (1 first).
    filter : ParticleFilter
        After the step's update (its contacts, normals and non-contacts).
    state : ExplorationState
        After the step adopted its plan.
    belief : BeliefState
        What the step reports (its MAP class, or a decided lead's).
    estimate : tuple
        ``(model, (rotation, translation), map_vertices)`` reported.
    recon : Reconstruction or None
        The reported surface.
    plan : Plan
    decision : Decision
    moves : tuple
        ``(paths, observations, timings)`` of the step.
    errors : dict
        The evaluator's fields (empty without a truth).
    """
    model, (rotation, translation), map_vertices = estimate
    paths, observations, timings = moves
    contacts, normals = filter.contact_positions, filter.contact_normals
    return Snapshot(
        step=step, new_observations=tuple(observations),
        paths=tuple(frozen(p) for p in paths), contacts=frozen(contacts),
        normals=frozen(normals), noncontacts=frozen(filter.noncontact_positions),
        free_space=frozen(state.free_space),
        map_class=belief.map_class, map_rotation=frozen(rotation),
        map_translation=frozen(translation), map_vertices=frozen(map_vertices),
        map_faces=model.mesh.faces, class_posterior=dict(belief.class_posterior),
        n_particles=belief.n_particles, log_evidence=float(belief.log_evidence),
        log_threshold=float(belief.log_threshold), novel=bool(belief.novel),
        gpis_vertices=None if recon is None else frozen(recon.vertices),
        gpis_faces=None if recon is None else frozen(recon.faces),
        gpis_variance=None if recon is None else recon.deferred_variance(),
        gpis_scale=float(state.gpis.scale) if recon is not None else None,
        target=None if state.target is None else frozen(state.target.position),
        dhd=float(plan.dhd), truth_coverage=errors.get("truth_coverage"),
        pose_error=errors.get("pose_error"), recon_error=errors.get("recon_error"),
        recon_surface_error=errors.get("recon_surface_error"),
        terminated=plan.terminated, timings=timings,
        hypotheses=hypotheses(belief),
        gpis_resolution=None if recon is None else recon.resolution,
        gpis_radius=None if recon is None else float(recon.fit.radius),
        gpis_spacing=None if recon is None else recon.spacing,
        gpis_shape=None if recon is None else state.gpis.shape,
        decided=bool(plan.decided), decision_confidence=decision.confidence,
        rotation_error_deg=errors.get("rotation_error_deg"),
        translation_error=errors.get("translation_error"))
