"""The surface a session reports and ends with (beyond the paper): the fit at
``final_resolution``, the best supported of the recent priors' fits, in its own box and
finer across thin walls, without what misses refute; a part of the
:class:`~.estimate.Estimator`.
"""

import functools
import time
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from ..belief.modes import pose_disagreements
from ..shape.gpis_evidence import fit_superquadrics
from ..shape.gpis_prior import free_space_cut, joined_cut
from ..shape.level_set import box_closure, zero_level_surface
from ..shape.metrics import wall_thickness
from ..transforms import transform_points
from .refuted import open_estimate
from .reported import reported_parts, support_reach

FINE_CANDIDATES = 3  # the best supported on the screen's surfaces, judged finer too
WALL_MOST = 4  # a thin wall's final surface takes at most this many times the resolution
# and about this many vertices: its extraction's time grows faster than its vertices (a 20
# cm fork has 800 at 64 cells; an 8 cm cup 3,300, whose two-sided walls are not refined)
WALL_VERTICES = 3000
# A final surface at most this share of its box across is extracted again in its own box,
# with this many of the first grid's cells of margin (the level set lies within a cell).
OWN_BOX_SHARE = 0.5
OWN_BOX_CELLS = 2


class FinalSurface:
    """The :class:`~.estimate.Estimator`'s final and reported surfaces (its ``p``,
    ``state``, ``filter`` and fits)."""

    def final_surface(self, recon, map_vertices, contacts, timings, prior):
        """The reconstruction a stopping session reports: the same fit at
        ``final_resolution`` (thin parts between the exploration grid's samples appear;
        in the surface's own box where it is small in the prior's, :meth:`_own_box`),
        or, where part of it lies farther than ``eps`` from every contact, the newest
        reconstruction of a recent MAP prior that the contacts cover, else the best
        supported (:meth:`best_supported`; ``prior`` is the step's ``(class, rotation,
        translation)``); of that, without what misses refute (the holes this leaves
        closed), the parts some contact comes within reach of (:meth:`_supported`): a
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
        within reach of (:meth:`_supported`); the planner keeps the whole estimate. A
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
        """:func:`~.reported.reported_parts` of ``recon`` in this session, within
        :meth:`support_reach` of a contact (with ``close``, cut by :meth:`_cut_refuted`
        where its holes cannot be closed)."""
        cut = functools.partial(self._cut_refuted, contacts=contacts) if close else None
        return reported_parts(recon, self.state.refuted, contacts,
                              self.p.contact_spacing, self.support_reach(), close=close,
                              cut=cut, cap_reach=self.p.gpis_carve_radius,
                              normals=self.filter.contact_normals)

    def support_reach(self):
        """:func:`~.reported.support_reach` of this session."""
        return support_reach(self.p, self.sensor_noise[0])

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
                               keep_within=self.support_reach())
        if balls is None or recon.bounds is None:
            return recon
        fit = replace(recon.fit, cut=joined_cut(recon.fit.cut, balls))
        cut = self._surface(fit, recon.bounds, recon.resolution, spacing=recon.spacing)[0]
        return recon if cut.empty else cut

    def best_supported(self, final, contacts, prior):
        """``final`` if the contacts cover it (every vertex within ``eps`` and a cell of
        its grid of a contact), else the newest reconstruction they cover, else the best
        supported one (the least :func:`support`): the GPIS fitted to every observation
        with the MAP prior of this step and of each of the last ``final_candidates``
        steps, then (``gpis_agnostic``) with each superquadric fitted to the contacts, each
        without and then with the carve's cut of the estimate (beyond the paper). A novel
        object's MAP prior switches from step to step, and a switch at the last step can
        leave surface far from every contact (under noise, where the prior switches most,
        at the step cap too); a candidate's support bounds how far its surface can lie from
        the object.

        Each candidate is first extracted at ``final_screen_resolution`` cells (its
        support there lies within about a cell of the finer one's); only those whose
        support could still be within ``eps`` or beat the best so far by that cell, at
        most ``FINE_CANDIDATES`` of the latter, are extracted at ``final_resolution`` and
        judged there: fifteen candidates at 64 cells took 2.4 s of a capped 8 cm cup's
        last step. Returns the surface and the superquadric its prior mean was (None: a
        MAP prior's)."""
        p = self.p
        tree = cKDTree(contacts)
        best_support = self._support(final.vertices, tree, final.closure)
        # The stop judged the same fit on the exploration's coarser cells, and a finer grid
        # moves a surface by up to about a cell: a 10 cm mug's reached 0.04 mm beyond its
        # 11.8 mm eps, and seven candidates took 1.5 s to find one 0.03 mm nearer.
        if best_support <= p.eps + cell_of(final.bounds, final.resolution):
            return final, self.state.gpis.shape
        screen = p.final_screen_resolution or p.final_resolution
        best, screened = None, []
        for candidate, box, shape in self._final_candidates(final, contacts, prior):
            covered = p.eps + cell_of(box, p.final_resolution)
            if screen != p.final_resolution:
                slack = cell_of(box, screen)
                coarse_support = self._level(candidate, box, screen, tree)[1]
                if coarse_support > covered + slack:
                    # Only the few best are kept: each fit holds a factor of 4 rows a contact.
                    screened.append((coarse_support - slack, candidate, box, shape))
                    screened.sort(key=lambda item: item[0])
                    del screened[FINE_CANDIDATES:]
                    continue
            level, candidate_support = self._level(candidate, box, p.final_resolution, tree)
            if candidate_support <= covered:
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
        if not len(level[1]):
            return level, np.inf
        return level, self._support(level[0], contacts_tree,
                                    box_closure(level[0], box, resolution))

    def _support(self, vertices, contacts_tree, closure):
        """:func:`support` over the vertices the stop counts (``final_support_open``): not
        near a given-up target or a missed probe's path, nor where it closes at its box
        within the carve's reach of one (the planner's mask,
        :func:`~.refuted.open_estimate`). A session stopped with its estimate covered
        there had every surface weighed again for vertices no probe could reach: a 20 cm
        fork's last step at 2 mm noise took 2.1 s, 1.8 of them candidate surfaces (0.8 s
        without)."""
        if self.p.final_support_open:
            vertices = vertices[open_estimate(vertices, closure, self.state, self.p,
                                              contacts_tree.data)]
        return support(vertices, contacts_tree)

    def _final_candidates(self, final, contacts, prior):
        """The fits :meth:`best_supported` weighs, newest first, as ``(fit, (low, high),
        superquadric or None)``."""
        f, p = self.filter, self.p
        free = np.vstack([f.noncontact_positions, self.state.free_space])
        observed = self.noncontact_points()
        cut = functools.partial(self.carve_estimate, contacts=contacts,
                                normals=f.contact_normals, free=free)
        step_prior = None
        factors = {}  # the candidates' fits share their observations' covariance
        for index, (class_name, rotation, translation) in enumerate(
                self._recent_priors(p.final_candidates, prior,
                                    cell_of(final.bounds, p.final_resolution))):
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
                            self.state.gpis.scale, newton=False, factors=factors)
            yield fit, (low, high), None
            yield cut(fit), (low, high), None
        if not p.gpis_agnostic or step_prior is None:
            return
        model, rotation, translation = step_prior
        own = getattr(self.state.gpis.shape, "roundness", None)
        for shape in fit_superquadrics(contacts, f.contact_normals,
                                       self._least_radius(contacts),
                                       faces=self.sensor_noise[0] > 0):
            if shape.roundness == own:
                continue  # the step's own
            low, high, kernel = self.gpis_box(None, contacts, shape)
            prior_mean = self.gpis_prior(model, rotation, translation, contacts,
                                          f.noncontact_positions, self.state.free_space,
                                          f.contact_normals, shape=shape)
            fit = self._fit(kernel, contacts, f.contact_normals, observed, prior_mean,
                            self.state.gpis.scale, newton=False, factors=factors)
            yield fit, (low, high), shape
            yield cut(fit), (low, high), shape

    def _recent_priors(self, count, current, tolerance=0.0):
        """The distinct MAP priors ``(class, rotation, translation)`` of ``current`` and the
        last ``count`` novel steps, newest first (``current`` first): a prior whose posed
        surface agrees within ``tolerance`` (scene units,
        :func:`~..belief.modes.pose_disagreements`) with a newer one's of its class is
        that one (a capped 8 cm cup's last step fitted its nested copy turned about its
        axis six times, 0.1 s a fit and two surfaces each)."""
        priors = []
        recent = [(snapshot.map_class, snapshot.map_rotation, snapshot.map_translation)
                  for snapshot in reversed(self.snapshots[-count:]) if snapshot.novel]
        for prior in [current] + recent:
            prior = (prior[0], np.asarray(prior[1]), np.asarray(prior[2]))
            same = [other for other in priors if other[0] == prior[0]]
            if not same or self._apart(prior, same, tolerance):
                priors.append(prior)
        return priors

    def _apart(self, prior, others, tolerance):
        """Whether ``prior``'s posed surface lies farther than ``tolerance`` from each of
        ``others`` (of its class): exactly, when ``tolerance`` is 0."""
        if tolerance <= 0:
            return not any(np.array_equal(prior[1], other[1])
                           and np.array_equal(prior[2], other[2]) for other in others)
        f = self.filter
        apart = pose_disagreements(f.bank, f.class_names.index(prior[0]), prior[1], prior[2],
                                   np.array([other[1] for other in others]),
                                   np.array([other[2] for other in others]))
        return bool(np.all(apart > tolerance))


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
    cell = cell_of((low, high), resolution)
    own_low = np.maximum(np.min(vertices, axis=0) - OWN_BOX_CELLS * cell, low)
    own_high = np.minimum(np.max(vertices, axis=0) + OWN_BOX_CELLS * cell, high)
    if np.max(own_high - own_low) > OWN_BOX_SHARE * np.max(high - low):
        return None
    return own_low, own_high


def cell_of(box, resolution):
    """The cell of ``resolution`` cells along the longest side of ``box`` (``(low, high)``,
    scene units; 0 without a box)."""
    if box is None:
        return 0.0
    return float(np.ptp(np.asarray(box, dtype=float), axis=0).max()) / resolution
