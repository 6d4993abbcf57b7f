"""The shape estimates: the MAP particle's posed prior (and the pose targets are aimed
from), and for a novel object the GPIS fit on the contacts with the MAP shape,
carved where probes found free space, as its prior mean (paper, Section III-E), and its
zero level set with the variance at the vertices.

A part of the step (:class:`~.context.Part`), built from its inputs without a session.
"""

import functools
import time
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from ..shape.gpis import (
    ThinPlateKernel,
    WendlandKernel,
    carved_prior,
    cut_free_space,
    fit_gpis,
    zero_level_surface,
)
from ..shape.gpis_evidence import contact_evidence, fit_superquadrics
from ..shape.gpis_incremental import fit_gpis_incremental
from ..shape.gpis_prior import (
    contact_balls,
    filled_prior,
    free_space_cut,
    joined_cut,
    refuted_fit,
)
from ..shape.gpis_variance import lattice_low, lattice_variance
from ..shape.metrics import wall_thickness
from ..transforms import transform_points
from .context import Part
from .fields import PosedSDF, thin_points
from .planner import open_vertices
from .reported import reported_parts
from .snapshot import Reconstruction

FILL_NOISE_STDS = 2.0  # a point this many position-noise stds behind a tangent plane bounds
FILL_SLACK = 0.02  # its ball, and this share of a size unit (a contact's localisation)
FINE_CANDIDATES = 3  # the best supported on the screen's surfaces, judged finer too
AGNOSTIC_MARGIN = 10.0  # nats another GPIS prior mean must gain to take over (hysteresis),
AGNOSTIC_SHARE = 0.1  # and at least this share of the evidence of the one in force
# A superquadric's box margin and least radius are at most this share of the contacts'
# extent (longest side of their box); the MAP prior's lengths cap them (eps / 2, the margin).
SHAPE_SHARE = 0.1
SHAPE_NOISE_STDS = 2.0  # and the least radius is at least this many position-noise stds
WALL_MOST = 4  # a thin wall's final surface takes at most this many times the resolution
# and about this many vertices: its extraction's time grows faster than its vertices (a 20
# cm fork has 800 at 64 cells; an 8 cm cup 3,300, whose two-sided walls are not refined)
WALL_VERTICES = 3000
# A final surface at most this share of its box across is extracted again in its own box,
# with this many of the first grid's cells of margin (the level set lies within a cell).
OWN_BOX_SHARE = 0.5
OWN_BOX_CELLS = 2


class Estimator(Part):
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
        low, high, kernel = self.gpis_box(map_vertices, contacts, gpis.shape)
        clock = time.perf_counter()
        fit, fitted = self._prior_fit(kernel, model, rotation, translation, contacts,
                                      normals, gpis)
        if (fitted.shape is None) != (gpis.shape is None):
            # The prior mean switched between the MAP shape and a superquadric: fit again
            # in the box of the one now in force.
            low, high, kernel = self.gpis_box(map_vertices, contacts, fitted.shape)
            fit, fitted = self._prior_fit(kernel, model, rotation, translation, contacts,
                                          normals, fitted)
        gpis = fitted
        fit = self.cut_estimate(fit, contacts, self.filter.noncontact_positions,
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
        return recon, replace(gpis, variance=variance)

    def _prior_fit(self, kernel, model, rotation, translation, contacts, normals, gpis):
        """The step's GPIS fit (:meth:`_step_fit`) from its prior mean: the MAP shape's or,
        with ``gpis_agnostic``, a superquadric fitted to the contacts; the one in force
        (``gpis.shape``) unless another's evidence is ahead by ``AGNOSTIC_MARGIN`` nats
        and ``AGNOSTIC_SHARE`` of its own (beyond the paper). Returns the fit and the
        next :class:`~.state.GpisState`."""
        p = self.p
        free = self.filter.noncontact_positions, self.state.free_space
        prior = self.gpis_prior(model, rotation, translation, contacts, *free, normals)
        shapes = (fit_superquadrics(contacts, normals, self._least_radius(contacts))
                  if p.gpis_agnostic else [])
        candidates = [prior] + [self.gpis_prior(model, rotation, translation, contacts, *free,
                                                 normals, shape=shape) for shape in shapes]
        kept = gpis.shape
        index = next((i + 1 for i, shape in enumerate(shapes)
                      if kept is not None and shape.roundness == kept.roundness), 0)
        fit, gpis = self._step_fit(kernel, contacts, normals, candidates[index], gpis)
        if len(candidates) > 1:
            evidence = [contact_evidence(fit, c, contacts, normals) for c in candidates]
            best = int(np.argmax(evidence))
            margin = max(AGNOSTIC_MARGIN, AGNOSTIC_SHARE * abs(evidence[index]))
            if evidence[best] > evidence[index] + margin:  # another explains more
                index = best
                fit, gpis = self._step_fit(kernel, contacts, normals, candidates[index], gpis)
        return fit, replace(gpis, shape=shapes[index - 1] if index else None)

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

    def final_surface(self, recon, map_vertices, contacts, timings, prior):
        """The reconstruction a stopping session reports: the same fit at
        ``final_resolution`` (thin parts between the exploration grid's samples appear;
        in the surface's own box where it is small in the prior's, :meth:`_own_box`),
        or, where part of it lies farther than ``eps`` from every contact, the newest
        reconstruction of a recent MAP prior that the contacts cover, else the best
        supported (:meth:`best_supported`; ``prior`` is the step's ``(class, rotation,
        translation)``); of that, without what misses refute (the holes this leaves
        closed), the parts some contact comes within ``eps`` of (:meth:`_supported`): a
        part no contact comes near is a phantom of the prior mean or the kernel (an 8 cm
        cup's ended with a blob 5 cm off every contact).

        Returns
        -------
        Reconstruction or None
        GpisState
            ``state.gpis`` with the shape of the prior mean the surface comes from.
        """
        gpis = self.state.gpis
        if recon is None or recon.empty:
            return recon, gpis
        p = self.p
        clock = time.perf_counter()
        final = recon
        if p.final_resolution != p.gpis_resolution:
            low, high, _ = self.gpis_box(map_vertices, contacts, gpis.shape)
            final = self._surface(recon.fit, (low, high), p.final_resolution)[0]
            final = recon if final.empty else final
        if p.final_candidates:
            final, shape = self.best_supported(final, contacts, prior)
            gpis = replace(gpis, shape=shape)
        final = self._thin_walls(self._own_box(final), contacts)
        if p.final_candidates:
            final = self._supported(final, contacts, close=True)
        if final is not recon:
            timings["surface"] = timings.get("surface", 0.0) + time.perf_counter() - clock
        return final, gpis

    def reported(self, recon, contacts, timings):
        """The step's surface as a snapshot reports it: with ``final_candidates`` (as the
        final surface), without what misses refute, only the parts some contact comes
        within ``eps`` of (:meth:`_supported`); the planner keeps the whole estimate. A
        part no contact comes near is a phantom of the prior mean or the kernel, and it
        comes and goes from step to step (an 8 cm cup's error between 10 and 90 mm on
        consecutive touches)."""
        if recon is None or recon.empty or not self.p.final_candidates:
            return recon
        clock = time.perf_counter()
        recon = self._supported(recon, contacts)
        timings["surface"] = timings.get("surface", 0.0) + time.perf_counter() - clock
        return recon

    def _supported(self, recon, contacts, close=False):
        """:func:`~.reported.reported_parts` of ``recon`` in this session (with ``close``,
        cut by :meth:`_cut_refuted` where its holes cannot be closed)."""
        cut = functools.partial(self._cut_refuted, contacts=contacts) if close else None
        return reported_parts(recon, self.state.refuted, contacts,
                              self.p.contact_spacing, self.p.eps, close=close, cut=cut)

    def _cut_refuted(self, recon, contacts):
        """``recon`` extracted again as it was, with balls of ``contact_spacing`` about
        the refuted points cut out of its fit's solid beyond ``eps`` of every contact
        (:func:`~..shape.gpis_prior.free_space_cut`): the vertices
        :func:`~.reported.refuted_vertices` marks, gone from a surface that stays closed. A
        20 cm fork's last surface at 2 mm noise kept a part 17-48 mm from every contact
        and 43 mm off the fork (25% of its size), its holes not closed where the refuted
        faces were dropped."""
        p = self.p
        balls = free_space_cut(self.state.refuted, contacts, p.contact_spacing,
                               keep_within=p.eps)
        if balls is None or recon.bounds is None:
            return recon
        fit = replace(recon.fit, cut=joined_cut(recon.fit.cut, balls))
        cut = self._surface(fit, recon.bounds, recon.resolution, spacing=recon.spacing)[0]
        return recon if cut.empty else cut

    def best_supported(self, final, contacts, prior):
        """``final`` if the contacts cover it (every vertex within ``eps`` of a contact),
        else the newest reconstruction they cover, else the best supported one (the least
        :func:`support`): the GPIS fitted to every observation with the MAP prior of this
        step and of each of the last ``final_candidates`` steps, then (``gpis_agnostic``)
        with each superquadric fitted to the contacts, each without and then with the
        carve's cut of the estimate (beyond the paper). A novel object's MAP prior
        switches from step to step, and a switch at the last step can leave surface far
        from every contact (under noise, where the prior switches most, at the step cap
        too); a candidate's support bounds how far its surface can lie from the object.

        Each candidate is first extracted at ``final_screen_resolution`` cells (its
        support there lies within about a cell of the finer one's); only those whose
        support could still be within ``eps`` or beat the best so far by that cell, at
        most ``FINE_CANDIDATES`` of the latter, are extracted at ``final_resolution`` and
        judged there: fifteen candidates at 64 cells took 2.4 s of a capped 8 cm cup's
        last step. Returns the surface and the superquadric its prior mean was (None: a
        MAP prior's)."""
        p = self.p
        tree = cKDTree(contacts)
        best_support = self._support(final.vertices, tree)
        if best_support <= p.eps:
            return final, self.state.gpis.shape
        screen = p.final_screen_resolution or p.final_resolution
        best, screened = None, []
        for candidate, box, shape in self._final_candidates(final, contacts, prior):
            if screen != p.final_resolution:
                slack = float(np.ptp(np.asarray(box), axis=0).max()) / screen
                coarse_support = self._level(candidate, box, screen, tree)[1]
                if coarse_support > p.eps + slack:
                    # Only the few best are kept: each fit holds a factor of 4 rows a contact.
                    screened.append((coarse_support - slack, candidate, box, shape))
                    screened.sort(key=lambda item: item[0])
                    del screened[FINE_CANDIDATES:]
                    continue
            level, candidate_support = self._level(candidate, box, p.final_resolution, tree)
            if candidate_support <= p.eps:
                return self._surface(candidate, box, p.final_resolution, level=level)[0], shape
            if candidate_support < best_support:
                best_support, best = candidate_support, (candidate, box, shape, level)
        for least, candidate, box, shape in screened:
            if least >= best_support:
                break
            level, candidate_support = self._level(candidate, box, p.final_resolution, tree)
            if candidate_support < best_support:
                best_support, best = candidate_support, (candidate, box, shape, level)
        if best is None:
            return final, self.state.gpis.shape
        return self._surface(best[0], best[1], p.final_resolution, level=best[3])[0], best[2]

    def _own_box(self, final):
        """``final`` extracted again at its resolution in its own box (its vertices', with
        :data:`OWN_BOX_CELLS` cells of margin) where that box's longest side is at most
        :data:`OWN_BOX_SHARE` of the box it was extracted in (beyond the paper; off with
        ``final_wall_cells`` 0, as the thin walls). The box holds the MAP prior and the
        contacts: a 2 cm block's surface in a 29 cm knife prior's box had 4.6 mm cells,
        28 mm across and 16.7% of its size off."""
        if (self.p.final_wall_cells <= 0 or final.bounds is None or final.spacing is not None
                or final.empty):
            return final
        box = own_box(final.vertices, final.bounds, final.resolution)
        if box is None:
            return final
        tighter = self._surface(final.fit, box, final.resolution)[0]
        return final if tighter.empty else tighter

    def _thin_walls(self, final, contacts):
        """``final`` extracted again on finer cells where the contacts measure thin walls
        (:meth:`wall_resolution`); the surface was chosen at its own resolution."""
        if final.bounds is None or final.spacing is not None:
            return final
        resolution = self.wall_resolution(final.bounds, final.resolution, contacts,
                                          vertices=len(final.vertices))
        if resolution == final.resolution:
            return final
        finer = self._surface(final.fit, final.bounds, resolution)[0]
        return final if finer.empty else finer

    def wall_resolution(self, box, resolution, contacts, normals=None, vertices=None):
        """``resolution`` (cells along the longest side of ``box``), or more where the
        contacts measure walls touched on both sides: ``final_wall_cells`` cells across their
        median thickness (:func:`~..shape.metrics.wall_thickness` within ``eps``), at most
        :data:`WALL_MOST` times ``resolution``, no finer than the sensor's position noise
        and, for a surface of ``vertices`` at ``resolution``, about :data:`WALL_VERTICES`
        vertices (beyond the paper). At 64 cells a 20 cm fork's 4 mm tines were one cell
        across, and the learned fork's normals missed its own contacts' by 45 degrees
        (median): met again, it was judged novel."""
        cells = self.p.final_wall_cells
        if cells <= 0:
            return resolution
        if normals is None:
            normals = self.filter.contact_normals
        wall = wall_thickness(contacts, normals, self.p.eps)
        if wall is None:
            return resolution
        longest = float(np.max(np.asarray(box[1]) - np.asarray(box[0])))
        # Cells finer than the sensor's position noise would draw the noise.
        cell = max(wall / cells, self.sensor_noise[0], 1e-12)
        wanted = int(np.ceil(longest / cell))
        most = WALL_MOST * resolution
        if vertices:  # a surface's vertices, and its cost, grow as the cells' square
            most = min(most, resolution * np.sqrt(WALL_VERTICES / vertices))
        return int(min(max(resolution, wanted), max(resolution, int(most))))

    def _level(self, fit, box, resolution, contacts_tree):
        """``fit``'s zero level set ``(vertices, faces)`` on ``resolution`` cells of ``box``
        and its :func:`support` (``inf`` without a surface)."""
        level = zero_level_surface(fit, box, resolution, fill_voids=self.p.gpis_fill_voids)
        return level, self._support(level[0], contacts_tree) if len(level[1]) else np.inf

    def _support(self, vertices, contacts_tree):
        """:func:`support` over the vertices the stop counts (``final_support_open``): not
        near a given-up target or a missed probe's path (the planner's reachable mask). A
        session stopped with its estimate covered there had every surface weighed again
        for vertices no probe could reach: a 20 cm fork's last step at 2 mm noise took
        2.1 s, 1.8 of them candidate surfaces (0.8 s without)."""
        if self.p.final_support_open:
            vertices = vertices[open_vertices(vertices, self.state, self.p.contact_spacing)]
        return support(vertices, contacts_tree)

    def _final_candidates(self, final, contacts, prior):
        """The fits :meth:`best_supported` weighs, newest first, as ``(fit, (low, high),
        superquadric or None)``."""
        f, p = self.filter, self.p
        free = np.vstack([f.noncontact_positions, self.state.free_space])
        observed = self.noncontact_points()
        cut = functools.partial(cut_free_space, free_points=free, contacts=contacts,
                                radius=p.gpis_carve_radius, keep_within=p.eps)
        step_prior = None
        for index, (class_name, rotation, translation) in enumerate(
                self._recent_priors(p.final_candidates, prior)):
            model = f.models[f.class_names.index(class_name)]
            shape = self.state.gpis.shape if index == 0 else None
            low, high, kernel = self.gpis_box(
                transform_points(model.mesh.vertices, rotation, translation), contacts, shape)
            if index == 0:
                step_prior = model, rotation, translation
                # This step's own: its uncut fit is final's, in its box.
                yield cut(final.fit), (low, high), shape
                continue
            prior_mean = self.gpis_prior(model, rotation, translation, contacts,
                                          f.noncontact_positions, self.state.free_space,
                                          f.contact_normals)
            fit = self._fit(kernel, contacts, f.contact_normals, observed, prior_mean,
                            self.state.gpis.scale, newton=False)
            yield fit, (low, high), None
            yield cut(fit), (low, high), None
        if not p.gpis_agnostic or step_prior is None:
            return
        model, rotation, translation = step_prior
        own = getattr(self.state.gpis.shape, "roundness", None)
        for shape in fit_superquadrics(contacts, f.contact_normals,
                                       self._least_radius(contacts)):
            if shape.roundness == own:
                continue  # the step's own
            low, high, kernel = self.gpis_box(None, contacts, shape)
            prior_mean = self.gpis_prior(model, rotation, translation, contacts,
                                          f.noncontact_positions, self.state.free_space,
                                          f.contact_normals, shape=shape)
            fit = self._fit(kernel, contacts, f.contact_normals, observed, prior_mean,
                            self.state.gpis.scale, newton=False)
            yield fit, (low, high), shape
            yield cut(fit), (low, high), shape

    def _recent_priors(self, count, current):
        """The distinct MAP priors ``(class, rotation, translation)`` of ``current`` and the
        last ``count`` novel steps, newest first (``current`` first)."""
        priors = []
        recent = [(snapshot.map_class, snapshot.map_rotation, snapshot.map_translation)
                  for snapshot in reversed(self.snapshots[-count:]) if snapshot.novel]
        for prior in [current] + recent:
            prior = (prior[0], np.asarray(prior[1]), np.asarray(prior[2]))
            if not any(
                    prior[0] == other[0] and np.array_equal(prior[1], other[1])
                    and np.array_equal(prior[2], other[2]) for other in priors):
                priors.append(prior)
        return priors

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

    def _fit(self, kernel, contacts, normals, noncontacts, prior, scale, newton=True):
        """A full fit, then refitted while it puts a non-contact farther than ``eps`` from
        every contact inside (beyond the paper: ``gpis_refute_rounds``, at the scale the
        first fit took)."""
        options = self._observation_options(noncontacts)
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
        # The sensor's position noise adds to the GPIS's observation noise (variances).
        return {"noise_variance": p.gpis_noise + self.sensor_noise[0] ** 2,
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
        return carved_prior(prior, free, contacts, p.gpis_carve_radius,
                            inside_only=not p.gpis_carve_outside)

    def cut_estimate(self, fit, contacts, noncontacts, free_space):
        """``fit`` with the carve's balls cut out of its mean too (``gpis_carve_estimate``)
        where no contact is within ``eps`` (where the surface is not covered)."""
        when = self.p.gpis_carve_estimate
        if when == "never" or (when == "noisy" and not any(self.sensor_noise)):
            return fit
        return cut_free_space(fit, np.vstack([noncontacts, free_space]), contacts,
                              self.p.gpis_carve_radius, keep_within=self.p.eps)

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


def support(vertices, contacts_tree):
    """How far the surface's farthest vertex lies from every contact (the DHD of all its
    vertices, scene units; ``inf`` without vertices).

    Parameters
    ----------
    vertices : (v, 3) float
    contacts_tree : scipy.spatial.cKDTree
        Of the contacts, world frame.
    """
    if len(vertices) == 0:
        return np.inf
    return float(contacts_tree.query(vertices)[0].max())


def own_box(vertices, bounds, resolution):
    """The box ``(low, high)`` of a surface's ``vertices`` (v, 3) with :data:`OWN_BOX_CELLS`
    cells of margin, within ``bounds`` (the box it was extracted in on ``resolution``
    cells along its longest side), if it is at most :data:`OWN_BOX_SHARE` of ``bounds``
    across; else None."""
    low, high = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    if len(vertices) == 0:
        return None
    cell = float(np.max(high - low)) / resolution
    own_low = np.maximum(np.min(vertices, axis=0) - OWN_BOX_CELLS * cell, low)
    own_high = np.minimum(np.max(vertices, axis=0) + OWN_BOX_CELLS * cell, high)
    if np.max(own_high - own_low) > OWN_BOX_SHARE * np.max(high - low):
        return None
    return own_low, own_high


def _extent(points):
    """The longest side of the axis-aligned box of ``points`` (n, 3) (0 without any)."""
    return float(np.ptp(points, axis=0).max()) if len(points) else 0.0
