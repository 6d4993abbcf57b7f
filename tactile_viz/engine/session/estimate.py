"""The shape estimates: the MAP particle's posed prior (and the pose targets are aimed
from), and for a novel object the GPIS fit on the contacts with the MAP shape,
carved where probes found free space, as its prior mean (paper, Section III-E), and its
zero level set with the variance at the vertices.

A part of the step (:class:`~.context.Part`), built from its inputs without a session.
"""

import time
from dataclasses import replace

import numpy as np

from ..params import PAPER_SIZE
from ..shape.gpis import (
    ThinPlateKernel,
    WendlandKernel,
    carved_prior,
    cut_free_space,
    fit_gpis,
)
from ..shape.gpis_evidence import contact_evidence, fit_superquadrics
from ..shape.gpis_incremental import fit_gpis_incremental
from ..shape.gpis_prior import (
    CarvedPrior,
    contact_balls,
    edge_tilt,
    filled_prior,
    free_space_cut,
    refuted_fit,
)
from ..shape.gpis_variance import lattice_low, lattice_variance
from ..shape.level_set import zero_level_surface
from ..transforms import transform_points
from .context import Part
from .fields import PosedSDF, thin_points
from .final import FinalSurface
from .snapshot import Reconstruction

FILL_NOISE_STDS = 2.0  # a point this many position-noise stds behind a tangent plane bounds
FILL_SLACK = 0.02  # its ball, and this share of a size unit (a contact's localisation)
AGNOSTIC_MARGIN = 10.0  # nats another GPIS prior mean must gain to take over (hysteresis),
AGNOSTIC_SHARE = 0.1  # and at least this share of the evidence of the one in force
# A superquadric's box margin and least radius are at most this share of the contacts'
# extent (longest side of their box); the MAP prior's lengths cap them (eps / 2, the margin).
SHAPE_SHARE = 0.1
SHAPE_NOISE_STDS = 2.0  # and the least radius is at least this many position-noise stds


class Estimator(FinalSurface, Part):
    """MAP shape, GPIS fit and surface of a session (see the module).

    Reads its context, the filter, the exploration state and the snapshots; writes
    nothing. What the next fit goes on from (:class:`~.state.GpisState`) is returned
    beside the surface, and the step keeps it (``state.gpis``).
    """

    def aimed_pose(self, decision, model, pose, map_vertices):
        """The pose and vertices that targets are aimed from and snapshots report: with
        ``decision_targets`` the decision's refined MAP pose (beyond the paper)."""
        if decision.hypotheses and self.p.decision_targets:
            pose = decision.hypotheses[0].rotation, decision.hypotheses[0].translation
            map_vertices = transform_points(model.mesh.vertices, *pose)
        return pose, map_vertices

    def reconstruct(self, model, rotation, translation, map_vertices, timings):
        """The step's GPIS surface from the MAP prior ``model`` posed at ``(rotation,
        translation)`` (vertices ``map_vertices``): l.4, with ``timings`` given its
        ``"gpis"`` and ``"surface"`` seconds.

        Returns
        -------
        Reconstruction
        GpisState
            What the next fit goes on from (``state.gpis`` is left as it is).
        """
        p, gpis = self.p, self.state.gpis
        contacts, normals = self.filter.contact_positions, self.filter.contact_normals
        poses = [(rotation, translation)] + self._held_pose(model, rotation, translation)
        force = (("shape", gpis.shape.roundness) if gpis.shape is not None
                 else ("pose", len(poses) - 1))
        low, high, kernel = self.gpis_box(
            self._prior_vertices(model, poses, map_vertices, force), contacts, gpis.shape)
        clock = time.perf_counter()
        fit, fitted, chosen = self._prior_fit(kernel, model, poses, contacts, normals, gpis,
                                              force)
        if chosen != force and "pose" in (chosen[0], force[0]):
            # The prior mean switched between the MAP shape and a superquadric, or between
            # two poses of the MAP shape: fit again in the box of the one now in force.
            low, high, kernel = self.gpis_box(
                self._prior_vertices(model, poses, map_vertices, chosen), contacts,
                fitted.shape)
            fit, fitted, _ = self._prior_fit(kernel, model, poses, contacts, normals, fitted,
                                             chosen)
        gpis = fitted
        fit = self.cut_estimate(fit, contacts, normals, self.filter.noncontact_positions,
                                 self.state.free_space)
        timings["gpis"] = time.perf_counter() - clock
        clock = time.perf_counter()
        spacing = None
        if p.gpis_incremental and not p.gpis_noncontacts:
            # Non-contact rows follow the contacts' and change every step: the lattice's
            # reductions could not be extended, so those fits keep the exact variance.
            spacing, gpis = self._kept_spacing(float((high - low).max()) / p.gpis_resolution,
                                               gpis)
        recon, variance = self._surface(fit, (low, high), p.gpis_resolution, spacing,
                                        gpis.variance)
        timings["surface"] = time.perf_counter() - clock
        kept = recon if self.p.check_refit_every > 1 else None  # held only then
        return recon, replace(gpis, variance=variance, recon=kept, held=0, free=self._free())

    def estimate(self, model, rotation, translation, map_vertices, timings):
        """The step's estimate: the last fit's surface again where :meth:`held_estimate`
        allows, else :meth:`reconstruct` (the same arguments and returns)."""
        held = self.held_estimate()
        if held is not None:
            return held, replace(self.state.gpis, held=self.state.gpis.held + 1)
        return self.reconstruct(model, rotation, translation, map_vertices, timings)

    def held_estimate(self):
        """The last fit's surface if this step may plan on it again, else None: after a
        check that touched the object within ``contact_spacing`` of the estimate, up to
        ``check_refit_every - 1`` steps in a row, while no miss has added free space since
        the fit (a stale carve keeps phantom parts, which would pass a touch beside them as
        predicted); never through a check of a decision."""
        state, gpis = self.state, self.state.gpis
        if (gpis.recon is None or state.check is None or state.confirming
                or state.checks_passed == 0 or gpis.held + 1 >= self.p.check_refit_every
                or gpis.free != self._free()
                or not (self.snapshots and self.snapshots[-1].novel)):
            return None
        return gpis.recon

    def _free(self):
        """How many non-contacts and free-space points carve the prior now."""
        return len(self.filter.noncontact_positions), len(self.state.free_space)

    def _prior_fit(self, kernel, model, poses, contacts, normals, gpis, force):
        """The step's GPIS fit (:meth:`_step_fit`) from its prior mean: the MAP shape's at
        one of ``poses`` (the MAP particle's, then with ``gpis_prior_hold`` the one the
        last fit held) or, with ``gpis_agnostic``, a superquadric fitted to the contacts;
        the one in force (``force``: ``("pose", k)`` or ``("shape", roundness)``) unless
        another's evidence is ahead by ``AGNOSTIC_MARGIN`` nats (and, a superquadric
        either way, ``AGNOSTIC_SHARE`` of its own; beyond the paper). Returns the fit, the
        next :class:`~.state.GpisState` and the key of the prior mean it started from."""
        p = self.p
        free = self.filter.noncontact_positions, self.state.free_space
        shapes = (fit_superquadrics(contacts, normals, self._least_radius(contacts),
                                    faces=self.sensor_noise[0] > 0)
                  if p.gpis_agnostic else [])
        keys = [("pose", k) for k in range(len(poses))] + [
            ("shape", shape.roundness) for shape in shapes]
        candidates = [self.gpis_prior(model, *pose, contacts, *free, normals)
                      for pose in poses] + [
            self.gpis_prior(model, *poses[0], contacts, *free, normals, shape=shape)
            for shape in shapes]
        index = keys.index(force) if force in keys else 0
        fit, gpis = self._step_fit(kernel, contacts, normals, candidates[index], gpis)
        if len(candidates) > 1:
            evidence = [contact_evidence(fit, c, contacts, normals) for c in candidates]
            best = int(np.argmax(evidence))
            # Between two poses of one shape the margin is the nats alone: a share of a
            # look-alike's evidence (hundreds of nats) held a pose it had left far behind.
            share = AGNOSTIC_SHARE if "shape" in (keys[best][0], keys[index][0]) else 0.0
            margin = max(AGNOSTIC_MARGIN, share * abs(evidence[index]))
            if evidence[best] > evidence[index] + margin:  # another explains more
                index = best
                fit, gpis = self._step_fit(kernel, contacts, normals, candidates[index], gpis)
        shape = shapes[index - len(poses)] if index >= len(poses) else None
        pose = None if shape is not None else (model.name, *poses[index])
        return fit, replace(gpis, shape=shape, pose=pose), keys[index]

    def _held_pose(self, model, rotation, translation):
        """``[(rotation, translation)]`` the MAP shape's GPIS prior was held at by the
        last fit (``gpis_prior_hold``), if that is another pose of this step's MAP class;
        else ``[]``. A novel object's MAP pose can turn from touch to touch between poses
        the contacts tell apart no better (a 20 cm fork's flat-screwdriver prior turned
        half a turn 20 times in 80 touches), each bringing other uncovered prior surface."""
        held = self.state.gpis.pose
        if not self._switched_on(self.p.gpis_prior_hold) or held is None or held[0] != model.name:
            return []
        if np.array_equal(held[1], rotation) and np.array_equal(held[2], translation):
            return []
        return [(held[1], held[2])]

    def prior_pose(self, model, pose, map_vertices):
        """The MAP shape's pose and vertices as the GPIS prior holds them
        (``gpis_prior_hold``; else ``pose`` and ``map_vertices``): the targets, the prior
        cover and the snapshot follow the prior the estimate came from."""
        held = self._held_pose(model, *pose)
        if not held or self.state.gpis.shape is not None:
            return pose, map_vertices
        return held[0], transform_points(model.mesh.vertices, *held[0])

    @staticmethod
    def _prior_vertices(model, poses, map_vertices, key):
        """The vertices of the MAP shape at the pose ``key`` names (``map_vertices``
        for the MAP particle's, or for a superquadric)."""
        if key[0] == "pose" and key[1] > 0:
            return transform_points(model.mesh.vertices, *poses[key[1]])
        return map_vertices

    def _step_fit(self, kernel, contacts, normals, prior, gpis):
        """A step's GPIS fit from ``prior``: extending the kept factor
        (``gpis_incremental``) or in full, with the scale's Newton step when due; and the
        next :class:`~.state.GpisState`."""
        if self.p.gpis_incremental:
            kernel, gpis = self._kept_kernel(kernel, gpis)
            fit, gpis = self._fit_incremental(kernel, contacts, normals,
                                              self.noncontact_points(), prior, gpis)
        else:
            newton = self._newton_due(len(contacts), gpis.fits)
            fit = self._fit(kernel, contacts, normals, self.noncontact_points(), prior,
                            gpis.scale, newton=newton)
            gpis = replace(gpis, fits=0 if newton else gpis.fits + 1)
        return fit, replace(gpis, scale=fit.scale)

    def _surface(self, fit, bounds, resolution, spacing=None, variance=None, level=None):
        """The :class:`Reconstruction` of ``fit``: its zero level set on ``resolution``
        cells of the box ``bounds`` (``level``: that set's ``(vertices, faces)``, already
        extracted), with the variance at up to ``variance_points`` vertices; with a
        ``spacing``, on the lattice of that cell (the box's low corner moved down onto
        it) with the variance interpolated from its nodes at every vertex, from the
        nodes' ``variance`` kept (a ``NodeVariance``). Returns the surface and the nodes'
        variance to keep."""
        low = bounds[0] if spacing is None else lattice_low(bounds[0], spacing)
        vertices, faces = level or zero_level_surface(
            fit, (low, bounds[1]), resolution, spacing=spacing,
            fill_voids=self.p.gpis_fill_voids)
        subset, candidates, everywhere = None, np.zeros(0), None
        if len(vertices):
            count = min(self.p.variance_points, len(vertices))
            subset = self.rng.choice(len(vertices), count, replace=False)
            if spacing is not None:
                everywhere, variance = lattice_variance(fit, vertices, low, spacing,
                                                        variance)
                candidates = everywhere[subset]
            else:
                candidates = fit.variance(vertices[subset])
        return Reconstruction(vertices, faces, subset, candidates, fit, resolution, spacing,
                              everywhere, bounds), variance

    def _fit(self, kernel, contacts, normals, noncontacts, prior, scale, newton=True,
             factors=None):
        """A full fit, then refitted while it puts a non-contact farther than ``eps`` from
        every contact inside (beyond the paper: ``gpis_refute_rounds``, at the scale the
        first fit took); ``factors``: :func:`~..shape.gpis.fit_gpis`'s cache."""
        options = dict(self._observation_options(noncontacts), factors=factors)
        fit = fit_gpis(contacts, normals, prior, kernel, scale=scale, newton=newton, **options)
        return refuted_fit(
            fit, noncontacts, self.p.gpis_noncontact_value, self.p.gpis_refute_rounds,
            lambda refuting: fit_gpis(contacts, normals, prior, kernel, scale=fit.scale,
                                      newton=False, refuting=refuting, **options),
            contacts, self.p.eps)

    def _newton_due(self, contacts, fits):
        """Whether a full fit takes the scale's Newton step, ``fits`` fits after the last:
        every ``gpis_refit_every`` fits, and more often while there are few contacts
        (every ``contacts // 10`` fits: the data grow by at most a tenth between two
        steps)."""
        every = min(self.p.gpis_refit_every, max(1, contacts // 10))
        return fits + 1 >= every

    def _fit_incremental(self, kernel, contacts, normals, noncontacts, prior, gpis):
        """:meth:`_fit` extending the last fit's factor (kept in the state, so that a
        rolled-back or pickled session goes on identically), the scale's Newton step taken
        every ``gpis_refit_every`` fits or when ``gpis_refit_score`` asks; and the next
        :class:`~.state.GpisState`."""
        p = self.p
        fit, cache, refitted = fit_gpis_incremental(
            contacts, normals, prior, kernel, gpis.cache, gpis.scale,
            refit=gpis.fits + 1 >= p.gpis_refit_every, refit_score=p.gpis_refit_score,
            **self._observation_options(noncontacts))
        return fit, replace(gpis, cache=cache, fits=0 if refitted else gpis.fits + 1)

    def refit(self, kernel, contacts, normals, noncontacts, prior, scale):
        """The fit of a past step again, at its ``scale`` (no Newton step): the way the
        step fitted, from the state's factor where its content agrees (the last fit's is
        then reproduced exactly); the state is left as it is."""
        if not self.p.gpis_incremental:
            return self._fit(kernel, contacts, normals, noncontacts, prior, scale, newton=False)
        return fit_gpis_incremental(contacts, normals, prior, kernel, self.state.gpis.cache,
                                    scale, refit=False, refit_score=np.inf,
                                    **self._observation_options(noncontacts))[0]

    def _observation_options(self, noncontacts):
        """The fits' noise and non-contact keywords."""
        p = self.p
        # The sensor's noise adds to the GPIS's (variances): its position noise to the
        # values (lengths), its normal noise and the edge tilt its position noise brings to
        # the gradients: a tilt by an angle of std s about a random axis moves a unit normal
        # with variance s**2 / 2 along each tangent.
        position, normal_deg = self.sensor_noise
        tilt = np.hypot(np.radians(normal_deg),
                        edge_tilt(position, PAPER_SIZE * self.unit, p.gpis_edge_tilt))
        return {"noise_variance": p.gpis_noise + position**2,
                "gradient_noise_variance": p.gpis_noise + tilt**2 / 2,
                "noncontacts": noncontacts if p.gpis_noncontacts else None,
                "noncontact_value": p.gpis_noncontact_value}

    def _kept_spacing(self, spacing, gpis):
        """``spacing``, or the grid cell of the last surfaces (``gpis.spacing``) while
        within ``gpis_box_tolerance`` of it (successive grids then share their nodes);
        and the next :class:`~.state.GpisState`."""
        kept = gpis.spacing
        if kept is not None and abs(spacing / kept - 1) <= self.p.gpis_box_tolerance:
            return kept, gpis
        return spacing, replace(gpis, spacing=spacing)

    def _kept_kernel(self, kernel, gpis):
        """``kernel``, or the thin-plate kernel of the last fits (``gpis.radius``) while
        its ``R`` is within ``gpis_box_tolerance`` of ``kernel``'s (a changed ``R``
        changes every entry of the Gram matrix, which then is refactored in full); and the
        next :class:`~.state.GpisState`."""
        kept = gpis.radius
        if not isinstance(kernel, ThinPlateKernel):
            return kernel, gpis
        if kept is not None and abs(kernel.radius / kept - 1) <= self.p.gpis_box_tolerance:
            return ThinPlateKernel(kept), gpis
        return kernel, replace(gpis, radius=kernel.radius)

    def gpis_box(self, map_vertices, contacts, shape=None):
        """The reconstruction box (low, high) and the GPIS kernel: about the contacts and
        the prior mean in force, the MAP surface ``map_vertices`` or a superquadric
        ``shape`` (its margin at most ``SHAPE_SHARE`` of the contacts' extent: a 2 cm
        block's superquadric in a 30 cm knife's box had 1 cm cells)."""
        p = self.p
        margin = p.gpis_margin
        if shape is None:
            points = np.vstack([map_vertices, contacts])
        else:
            points = np.vstack([shape.corners, contacts])
            margin = min(margin, SHAPE_SHARE * _extent(contacts))
        low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
        if p.gpis_kernel == "wendland":
            return low, high, WendlandKernel(p.gpis_support)
        return low, high, ThinPlateKernel(p.gpis_radius_factor * float(np.linalg.norm(high - low)))

    def _least_radius(self, contacts):
        """A superquadric's least semi-axis: ``eps / 2``, or less for contacts spanning
        less than ``eps / (2 SHAPE_SHARE)`` (an object much smaller than the MAP prior),
        but at least ``SHAPE_NOISE_STDS`` position-noise stds."""
        return min(self.p.eps / 2, max(SHAPE_SHARE * _extent(contacts),
                                        SHAPE_NOISE_STDS * self.sensor_noise[0], 1e-9))

    def gpis_prior(self, model, rotation, translation, contacts, noncontacts, free_space,
                    normals, shape=None):
        """The GPIS prior mean: the MAP shape with the solid behind the contacts it puts in
        its empty space added (``gpis_fill_radius``), or the object-agnostic ``shape``
        (a :class:`Superquadric`), with the refuted space cut out."""
        p = self.p
        free = np.vstack([noncontacts, free_space])
        prior = self._prior(model, rotation, translation) if shape is None else shape
        if p.gpis_fill_radius > 0 and len(contacts) and shape is None:
            slack = FILL_NOISE_STDS * self.sensor_noise[0] + FILL_SLACK * self.unit
            # Only a contact the prior puts in its empty space is evidence against it.
            refuting = np.asarray(prior(contacts)[0], dtype=float) > slack
            prior = filled_prior(prior, contact_balls(
                contacts[refuting], normals[refuting], np.vstack([free, contacts]),
                p.gpis_fill_radius, slack))
        if not p.gpis_carve_outside:
            return carved_prior(prior, free, contacts, p.gpis_carve_radius, inside_only=True,
                                normals=normals, disk=self._disc())
        cut = self._carve(free, contacts, normals)
        return prior if cut is None else CarvedPrior(prior, cut)

    def _carve(self, free, contacts, normals):
        """The carve's balls (:func:`~..shape.gpis_prior.free_space_cut`) about ``free``,
        made once for the step's candidate priors, which are all carved alike."""
        inputs = (free, contacts, normals)
        kept = getattr(self, "_carved", None)
        if kept is None or not all(np.array_equal(a, b) for a, b in zip(kept[0], inputs)):
            kept = tuple(np.array(a) for a in inputs), free_space_cut(
                free, contacts, self.p.gpis_carve_radius, normals=normals, disk=self._disc())
            self._carved = kept
        return kept[1]

    def _disc(self):
        """The radius of a contact's disc that the carve's balls do not reach (scene
        units): ``gpis_carve_disk`` contact spacings."""
        return self.p.gpis_carve_disk * self.p.contact_spacing

    def cut_estimate(self, fit, contacts, normals, noncontacts, free_space):
        """``fit`` with the carve's balls cut out of its mean too (``gpis_carve_estimate``):
        :meth:`carve_estimate`."""
        if not self._switched_on(self.p.gpis_carve_estimate):
            return fit
        return self.carve_estimate(fit, contacts, normals, np.vstack([noncontacts,
                                                                      free_space]))

    def carve_estimate(self, fit, contacts, normals, free):
        """``fit`` with the carve's balls about ``free`` cut out of its mean where no
        contact is within ``eps`` (where the surface is not covered), each ball short of
        the contacts' discs (``normals``: the contacts' own)."""
        return cut_free_space(fit, free, contacts, self.p.gpis_carve_radius,
                              keep_within=self.p.eps, normals=normals, disk=self._disc())

    def _switched_on(self, when):
        """Whether a ``"never"``/``"noisy"``/``"always"`` switch is on for this sensor."""
        return when == "always" or (when == "noisy" and any(self.sensor_noise))

    def _prior(self, model, rotation, translation):
        return PosedSDF(model, rotation, translation)

    def noncontact_points(self, noncontacts=None, free_space=None):
        """Where the sensor found no object: the non-contacts and the points along missed
        probes, one per quarter of the kernel's reach (what the GPIS's non-contact switch
        constrains)."""
        noncontacts = self.filter.noncontact_positions if noncontacts is None else noncontacts
        free_space = self.state.free_space if free_space is None else free_space
        reach = self.p.gpis_support if self.p.gpis_kernel == "wendland" else self.unit
        return np.vstack([noncontacts, thin_points(free_space, reach / 4)])


def map_shape(filter, belief):
    """The MAP particle's prior, pose ``(rotation, translation)`` and surface vertices
    (world frame) of ``belief`` (a :class:`~..belief.particle_filter.BeliefState` of
    ``filter``)."""
    model = filter.models[filter.class_names.index(belief.map_class)]
    pose = belief.map_rotation, belief.map_translation
    return model, pose, transform_points(model.mesh.vertices, *pose)


def decided_class(filter, belief, decision, model, pose, map_vertices):
    """The belief, prior, pose and vertices a step reports: a decided lead of another
    class than the filter's MAP (``decision_any_class``) in place of the MAP's (beyond the
    paper); else the MAP's, as given."""
    lead = decision.hypotheses[0] if decision.decided else None
    if lead is None or belief.class_names[lead.class_index] == belief.map_class:
        return belief, model, pose, map_vertices
    model, pose = filter.models[lead.class_index], (lead.rotation, lead.translation)
    return (replace(belief, map_class=belief.class_names[lead.class_index]), model, pose,
            transform_points(model.mesh.vertices, *pose))


def _extent(points):
    """The longest side of the axis-aligned box of ``points`` (n, 3) (0 without any)."""
    return float(np.ptp(points, axis=0).max()) if len(points) else 0.0
