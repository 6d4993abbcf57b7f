"""The customised particle filter over object class and 6-DOF pose (paper, Algorithm 1).

Particles are static hypotheses ``z = (class, object_to_world)``. Each step:

1. weight update: ``log w_j += log p(D_t | z_j)`` and normalise;
2. stochastic universal resampling, merging duplicates;
3. the MAP particle ``z*`` and its evidence ``log p(D_1:t | z*)``;
4. if the evidence is poor (gate ``lambda``), new particles from point-pair features of the
   new contact paired with ``n_s`` earlier contacts, weighted by the paper's relative-weight
   approximation;
5. optionally a local refinement of the MAP pose and of each learned prior's heaviest
   particles, in place;
6. optionally, particles whose poses lie within a merge tolerance of each other merged;
7. beyond the paper, near twins told apart: when several classes hold a share of the
   posterior, or another class fits the contacts at the MAP's pose, their poses are refined
   and the MAP is the one that then fits best (a better-fitting lookalike joins);
8. the known/novel decision from the MAP evidence.
"""

import numpy as np

from ..errors import ParameterError
from ..explore.observations import observation_arrays
from ..params import FilterParams
from ..scene import FREE
from ..shape.resting import hull_points, lowest_heights, seeds_on_table, stable_rotations
from ..shape.sdf import ExactDistance
from . import kernels
from .discrimination import discriminate
from .likelihood import (
    OUTLIER_NATS,
    log_noncontact_likelihood,
    log_normaliser,
    normalise_log_weights,
)
from .novelty import contact_test
from .particles import FilterState, Particles
from .pose_refinement import least_squares_pose, refine_poses
from .ppf import is_degenerate, local_frames, pair_features, rotation_about_x
from .prior_bank import PriorBank, bank_for, kept_recent, release_freed_memory
from .resampling import merge_close_poses, stochastic_universal_resampling  # noqa: F401

EXACT_KEPT = 8  # classes whose exact distance (libigl trees, ~8 MB each) the filter keeps
SCREEN_POINTS = 4  # earlier contacts that screen the candidates beyond max_candidates
SEED_NORMAL_TOLERANCE = 0.25  # resting seeds: vertical parts of the normals this close
_CHUNK = 400_000  # particle-point evaluations per batch, bounds memory


class ParticleFilter:
    """Joint class and pose belief over the priors of a library.

    Parameters
    ----------
    library : PriorLibrary
        The priors; their SDF grids, features and pair tables are built on first use.
    params : FilterParams, optional
    rng : int, numpy.random.Generator or None
    """

    def __init__(self, library, params=None, rng=None, scene=None):
        self.params = params or FilterParams()
        self.scene = FREE if scene is None else scene
        if len(library) == 0:
            raise ParameterError("the prior library is empty")
        wanted = {"sdf_resolution": self.params.sdf_resolution,
                  "sdf_max_resolution": self.params.sdf_max_resolution,
                  "sdf_exact_band": self.params.sdf_exact_band,
                  "n_features": self.params.n_features}
        self.models = [model.with_params(**wanted)
                       if any(getattr(model.params, key) != value for key, value in wanted.items())
                       else model for model in library]
        self.class_names = [model.name for model in self.models]
        self.rng = np.random.default_rng(rng)
        self.contact_positions = np.zeros((0, 3))
        self.contact_normals = np.zeros((0, 3))
        self.noncontact_positions = np.zeros((0, 3))
        self.particles = None
        self.step_count = 0
        self.state = None
        self.refined = {}  # the discrimination's last refined poses (its warm starts)
        self._bank = None

    @property
    def bank(self) -> PriorBank:
        """The priors' grids, features and one point-pair table (built on first use)."""
        if self._bank is None:
            self._bank = bank_for(self.models, self.params.distance_step,
                                  self.params.angle_step_deg)
        return self._bank

    def __getstate__(self):
        # The bank is rebuilt from the models' disk cache rather than pickled.
        return {**self.__dict__, "_bank": None}

    _STATE = ("particles", "contact_positions", "contact_normals", "noncontact_positions",
              "step_count", "state", "refined")

    def checkpoint(self):
        """What :meth:`restore` needs to undo later updates.

        An update replaces the filter's arrays rather than writing into them, so references
        (and the generator's state) are enough.
        """
        return {name: getattr(self, name) for name in self._STATE}, self.rng.bit_generator.state

    def restore(self, saved):
        """Return to a :meth:`checkpoint`."""
        state, generator = saved
        for name, value in state.items():
            setattr(self, name, value)
        self.rng.bit_generator.state = generator

    # ----------------------------------------------------------------- likelihood
    def log_likelihood(self, particles, contacts=None, normals=None, noncontacts=None):
        """Log-likelihood of observations under each particle.

        Parameters
        ----------
        particles : Particles
        contacts, normals : (m, 3) float, world frame
        noncontacts : (q, 3) float, world frame

        Returns
        -------
        (N,) float
        """
        contacts = np.zeros((0, 3)) if contacts is None else contacts
        normals = np.zeros((0, 3)) if normals is None else normals
        noncontacts = np.zeros((0, 3)) if noncontacts is None else noncontacts
        total = np.zeros(len(particles))
        if len(contacts) + len(noncontacts) == 0 or len(particles) == 0:
            return total
        params, grids = self.params, self.bank.grids
        classes = particles.classes.astype(np.int64, copy=False)
        if len(contacts):
            log_z = log_normaliser(params.sigma_d, params.sigma_n)
            total += kernels.contact_log_likelihoods(
                *grids, classes, particles.rotations, particles.translations,
                np.ascontiguousarray(contacts, dtype=float),
                np.ascontiguousarray(normals, dtype=float), params.sigma_d, params.sigma_n,
                log_z, params.outlier_probability, -OUTLIER_NATS - log_z)
        if len(noncontacts):
            chunk = max(1, _CHUNK // len(noncontacts))
            for start in range(0, len(particles), chunk):
                part = slice(start, start + chunk)
                values = kernels.distances(*grids, classes[part], particles.rotations[part],
                                           particles.translations[part],
                                           np.ascontiguousarray(noncontacts, dtype=float))
                if self.scene.tip_radius:  # a tip of radius r missed: its centre was
                    values = values - self.scene.tip_radius  # at least r off the surface
                total[part] += log_noncontact_likelihood(values, params.sigma_d).sum(axis=1)
        return total

    def log_evidence_of(self, particles):
        """``log p(D_1:t | z)`` of particles over every observation so far, with the
        table's pose prior (:meth:`log_support`)."""
        evidence = self.log_likelihood(particles, self.contact_positions,
                                       self.contact_normals, self.noncontact_positions)
        return evidence + self.log_support(particles) if self.scene.has_table else evidence

    def log_support(self, particles):
        """The table's pose prior (beyond the paper; 0 without a table): ``-(d / s)^2 / 2``
        for a hypothesis whose lowest point lies ``d`` off the plane, ``s`` the
        ``support_sigma`` in quadrature with twice the position noise. (N,) float."""
        scene = self.scene
        out = np.zeros(len(particles))
        if not scene.has_table or len(particles) == 0:
            return out
        sigma = float(np.hypot(self.params.support_sigma, 2 * self.params.position_noise))
        for c in np.unique(particles.classes):
            members = np.flatnonzero(particles.classes == c)
            gap = lowest_heights(hull_points(self.models[int(c)]), particles.rotations[members],
                                 particles.translations[members], scene.up, scene.table_point)
            out[members] = -0.5 * (gap / sigma) ** 2
        return out

    # ----------------------------------------------------------------- the step
    def update(self, observations):
        """Take one step's observations (contacts and/or non-contacts) and return the state.

        Parameters
        ----------
        observations : Contact, NonContact or a sequence of them

        Returns
        -------
        FilterState

        Raises
        ------
        ObservationError
            For anything that is not a valid observation; the filter is left unchanged.
        """
        contacts, normals, noncontacts = observation_arrays(observations)
        self.step_count += 1
        new_contacts, new_normals = contacts, normals
        self.contact_positions = np.vstack([self.contact_positions, contacts])
        self.contact_normals = np.vstack([self.contact_normals, normals])
        self.noncontact_positions = np.vstack([self.noncontact_positions, noncontacts])
        sampled = 0
        if self.particles is None:
            if len(contacts) == 0:
                return self._record(sampled)
            self.particles = self._initial_particles(contacts[0], normals[0])
            contacts, normals = contacts[1:], normals[1:]
            new_contacts, new_normals = new_contacts[1:], new_normals[1:]
        log_w = self.particles.log_weights + self.log_likelihood(
            self.particles, contacts, normals, noncontacts)
        self.particles = self._resample(_with_log_weights(self.particles, log_w))
        map_index, map_evidence = self._map()
        if len(new_contacts) and self._needs_sampling(map_evidence):
            for position, normal in zip(new_contacts, new_normals):
                new = self._sample_from_pairs(position, normal, map_index, map_evidence)
                if new is not None:
                    sampled += len(new)
                    self.particles = self._merged(new)
                    map_index, map_evidence = self._map()
            map_index = self._bounded(map_index)
        if len(self.contact_positions) >= 3:
            for index in self._to_refine(map_index):
                self._refine(index)
        if self.params.merge_distance > 0:
            self.particles = merge_close_poses(self.particles, self.params.merge_distance,
                                               np.radians(self.params.merge_angle_deg))
        chosen = None
        if self.params.contenders:  # beyond the paper: near twins refined and weighed
            self.particles, chosen, self.refined = discriminate(self, self.particles,
                                                                self.refined)
        if self.bank.large:
            release_freed_memory()
        return self._record(sampled, chosen)

    # ----------------------------------------------------------------- pieces
    def _initial_particles(self, position, normal):
        """Every feature point of every class put onto the first contact (Algorithm 1), or
        beyond ``max_particles`` hypotheses a random subset of them: one contact tells the
        hypotheses nothing apart, so a large library need not spawn them all."""
        k = self.params.init_rotations
        offset = self.rng.uniform(0, 2 * np.pi)
        angles = offset + 2 * np.pi * np.arange(k) / k
        bank = self.bank
        classes, features = bank.points.shape[:2]
        # Hypothesis i: class i // (F k), feature point (i // k) % F, angle i % k.
        chosen = np.arange(classes * features * k)
        if len(chosen) > self.params.max_particles:
            chosen = np.sort(self.rng.choice(len(chosen), self.params.max_particles,
                                             replace=False))
        c, f, a = chosen // (features * k), (chosen // k) % features, chosen % k
        points, rm = bank.points[c, f], bank.frames[c, f]
        rs, _, _ = local_frames(position[None], normal[None], position[None])
        # object_to_world = T_g(s)^-1 R_x(angle) T_g(m): the feature point onto the contact.
        rotations = rs[0].T @ rotation_about_x(angles)[a] @ rm
        translations = position - np.einsum("kij,kj->ki", rotations, points)
        particles = Particles(c, rotations, translations, np.full(len(c), -np.log(len(c))))
        if not self.scene.has_table:
            return particles
        if self.params.seed_stable_poses:
            particles = Particles.concatenate([particles, self._resting_seeds(position, normal)])
        return _with_log_weights(particles, self.log_support(particles))

    def _resting_seeds(self, position, normal):
        """The first touch's hypotheses that rest on the table in a stable pose of their
        prior, turned about the vertical (:func:`~..shape.resting.seeds_on_table`)."""
        bank, scene, params = self.bank, self.scene, self.params
        sigma = float(np.hypot(params.support_sigma, 2 * params.position_noise))
        classes, rotations, translations = [], [], []
        for c, model in enumerate(self.models):
            stable, _ = stable_rotations(model)
            r, t = seeds_on_table(bank.points[c], bank.normals[c], hull_points(model), stable,
                                  position, normal, scene.up, scene.table_point,
                                  SEED_NORMAL_TOLERANCE, 3 * sigma, params.init_rotations)
            classes.append(np.full(len(r), c))
            rotations.append(r)
            translations.append(t)
        return Particles(np.concatenate(classes), np.concatenate(rotations),
                         np.concatenate(translations), np.zeros(sum(map(len, classes))))

    def _resample(self, particles):
        weights = np.exp(particles.log_weights)
        count = min(len(particles), self.params.max_particles)
        copies = stochastic_universal_resampling(weights, count, self.rng)
        keep = np.flatnonzero(copies)
        return Particles(particles.classes[keep], particles.rotations[keep],
                         particles.translations[keep], np.log(copies[keep] / count))

    def _map(self):
        index = int(np.argmax(self.particles.log_weights))
        return index, float(self.log_evidence_of(self.particles.take([index]))[0])

    def _max_log_evidence(self):
        return -len(self.contact_positions) * log_normaliser(self.params.sigma_d,
                                                             self.params.sigma_n)

    def _needs_sampling(self, map_evidence):
        """Gate: the per-observation geometric mean of p(D|z*) / p_max is below lambda."""
        n = len(self.contact_positions) + len(self.noncontact_positions)
        return (map_evidence - self._max_log_evidence()) / max(n, 1) < np.log(self.params.lam)

    def _subset(self, position):
        """Indices of the n_s earlier contacts: one per equal segment of the distance order."""
        earlier = len(self.contact_positions) - 1
        order = np.argsort(np.linalg.norm(self.contact_positions[:earlier] - position, axis=1))
        segments = np.array_split(order, min(self.params.n_s, earlier))
        return np.array([segment[0] for segment in segments if len(segment)], dtype=int)

    def _sample_from_pairs(self, position, normal, map_index, map_evidence):
        """New particles from point pairs (new contact, earlier contact), both orders."""
        if len(self.contact_positions) < 2:
            return None
        subset = self._subset(position)
        old_p, old_n = self.contact_positions[subset], self.contact_normals[subset]
        new_p, new_n = np.broadcast_to(position, old_p.shape), np.broadcast_to(normal, old_n.shape)
        p1, n1 = np.vstack([new_p, old_p]), np.vstack([new_n, old_n])
        p2, n2 = np.vstack([old_p, new_p]), np.vstack([old_n, new_n])
        usable = ~is_degenerate(p1, n1, p2, n2)
        if not usable.any():
            return None
        p1, n1, p2, n2 = p1[usable], n1[usable], p2[usable], n2[usable]
        features = pair_features(p1, n1, p2, n2)
        subset_p = np.vstack([old_p, position[None]])
        subset_n = np.vstack([old_n, normal[None]])
        bank = self.bank
        query, classes, first, second = self._capped(
            *bank.lookup(features, self.params.neighbour_bins))
        if len(query) == 0:
            return None
        rotations, translations = kernels.align(bank.frames, bank.points, classes, first,
                                                second, *local_frames(p1, n1, p2), query)
        candidates = self._screened(
            Particles(classes, rotations, translations, np.zeros(len(query))), old_p)
        classes, rotations, translations = (candidates.classes, candidates.rotations,
                                             candidates.translations)
        log_subset = self.log_likelihood(candidates, subset_p, subset_n)
        if self.scene.has_table:
            log_subset = log_subset + self.log_support(candidates)
        # Each class's best candidate (the first of equals), and its evidence over all data.
        order = np.lexsort((-log_subset, classes))
        best = order[np.flatnonzero(np.r_[True, np.diff(classes[order]) != 0])]
        group = np.searchsorted(classes[best], classes)
        best_evidence = self.log_evidence_of(candidates.take(best))
        # Paper eq. new_weights: relative to the class's best candidate, which is placed
        # relative to the MAP particle by their likelihoods over all data.
        log_w = (log_subset - log_subset[best][group] + best_evidence[group] - map_evidence
                 + self.particles.log_weights[map_index])
        new = Particles(classes, rotations, translations, log_w)
        budget = self.params.max_new_particles
        if budget and len(new) > budget:
            new = new.take(np.sort(np.argpartition(-new.log_weights, budget - 1)[:budget]))
        return new

    def _capped(self, query, classes, first, second):
        """Look-up matches sorted by class (stable), each class's cut to a random
        ``max_new_per_class`` of them."""
        order = np.argsort(classes, kind="stable")
        query, classes, first, second = query[order], classes[order], first[order], second[order]
        _, starts, counts = np.unique(classes, return_index=True, return_counts=True)
        cap = self.params.max_new_per_class
        if counts.max(initial=0) <= cap:
            return query, classes, first, second
        # Over the cap, a random subset in the order drawn.
        index = np.concatenate([
            np.arange(start, start + count) if count <= cap
            else start + self.rng.choice(count, cap, replace=False)
            for start, count in zip(starts, counts)])
        return query[index], classes[index], first[index], second[index]

    def _screened(self, candidates, positions):
        """At most ``max_candidates`` candidates: beyond it, those whose surfaces pass
        closest to four of the earlier contacts ``(n, 3)`` (spread along their distance
        order; the distance term of the likelihood), in their order."""
        budget = self.params.max_candidates
        if not budget or len(candidates) <= budget:
            return candidates
        screen = np.unique(np.linspace(0, len(positions) - 1, SCREEN_POINTS).round().astype(int))
        values = kernels.distances(*self.bank.grids, candidates.classes.astype(np.int64),
                                   candidates.rotations, candidates.translations,
                                   np.ascontiguousarray(positions[screen]))
        score = -np.square(values).sum(axis=1)
        return candidates.take(np.sort(np.argpartition(-score, budget - 1)[:budget]))

    def _bounded(self, map_index):
        """At most ``max_particles`` particles after sampling, the heaviest (those
        resampling would keep anyway; the MAP is the heaviest): a step's new particles
        cannot carry the belief past the cap. Returns the MAP's index in the kept set."""
        cap = self.params.max_particles
        if len(self.particles) <= cap:
            return map_index
        keep = np.sort(np.argpartition(-self.particles.log_weights, cap - 1)[:cap])
        self.particles = _with_log_weights(self.particles.take(keep),
                                           self.particles.log_weights[keep])
        return int(np.argmax(self.particles.log_weights))

    def _merged(self, new):
        combined = Particles.concatenate([self.particles, new])
        return _with_log_weights(combined, normalise_log_weights(combined.log_weights))

    def _to_refine(self, map_index):
        """Particles whose pose is refined this step: the MAP (``refine_map``) and the
        ``refine_learned`` heaviest of each learned prior, so that a learned shape's coarse
        point-pair poses can still overtake a given mesh's."""
        chosen = [map_index] if self.params.refine_map else []
        count = self.params.refine_learned
        for c in np.flatnonzero(self.bank.learned) if count else ():
            members = np.flatnonzero(self.particles.classes == c)
            heaviest = members[np.argsort(-self.particles.log_weights[members])[:count]]
            chosen += [int(index) for index in heaviest]
        return list(dict.fromkeys(chosen))

    def _refine(self, index):
        """Move particle ``index`` to its pose after a few least-squares steps on all
        observations, its weight multiplied by the gain in evidence (kept as it is if there
        is none). The particle is replaced, not copied: a copy would count its weight twice."""
        particle = self.particles.take([index])
        evidence_before = self.log_evidence_of(particle)[0]
        try:
            rotation, translation = least_squares_pose(
                self.bank.evaluate, int(particle.classes[0]), particle.rotations[0],
                particle.translations[0], self.contact_positions, self.contact_normals,
                self.noncontact_positions, self.params.sigma_d, self.params.sigma_n,
                self.scene.tip_radius, self.params.refine_iterations * 7)
        except (ValueError, np.linalg.LinAlgError):
            return
        refined = Particles(particle.classes, rotation[None], translation[None], np.zeros(1))
        evidence = self.log_evidence_of(refined)[0]
        if not evidence > evidence_before:
            return
        rotations = self.particles.rotations.copy()
        translations = self.particles.translations.copy()
        log_weights = self.particles.log_weights.copy()
        rotations[index], translations[index] = rotation, translation
        log_weights[index] += evidence - evidence_before
        self.particles = Particles(self.particles.classes, rotations, translations,
                                   normalise_log_weights(log_weights))

    def _refined_map(self, best):
        """The MAP particle's pose fitted to the observations
        (:func:`~.pose_refinement.refine_poses`); the particle is left as it is."""
        try:
            rotations, translations, _ = refine_poses(
                self.bank.evaluate, best.classes[:1].astype(np.int64), best.rotations[:1],
                best.translations[:1], self.contact_positions, self.noncontact_positions,
                self.params.refine_iterations, trim=self.params.outlier_probability,
                clearance=self.scene.tip_radius, below=self.bank.below)
        except np.linalg.LinAlgError:
            return best.rotations[0], best.translations[0]
        return rotations[0], translations[0]

    def _tested_pose(self, best):
        """The pose the novelty test takes for the MAP particle ``best``: its refined pose
        (:meth:`_refined_map`) with a noisy sensor or on a table and three contacts or more,
        else its own. Under noise the particle is off by more than the noise, and thin
        walls need it closer to tell a noisy touch from a wrong shape; on a table, touched
        from one side, it is off by more than the touches allow (a 30 cm dragon's sat 7%
        off, every touch fitting its refined pose, and it was judged novel)."""
        if (self.allowed_noise(int(best.classes[0])) > 0 or self.scene.has_table) and len(
                self.contact_positions) >= 3:
            return self._refined_map(best)
        return best.rotations[0], best.translations[0]

    def _noncontact_test(self, best, pose):
        """The novelty test's non-contact part: the MAP's log-likelihood of the
        non-contacts, on a table at its tested ``pose`` (the tip comes down a radius beside
        the object, where the particle's pose error alone puts the surface inside the
        tip), else at the particle's own."""
        if self.scene.has_table:
            best = Particles(best.classes, pose[0][None], pose[1][None], np.zeros(1))
        return self.log_likelihood(best, noncontacts=self.noncontact_positions)[0]

    def _contact_test(self, best, pose=None):
        """The novelty test's contact part (:func:`~.novelty.contact_test`) at the MAP's
        refined pose with a noisy sensor, the noise the class is granted
        (:meth:`allowed_noise`) and a learned MAP's own normal error (:meth:`own_turn`):
        ``(the MAP's log-likelihood of the contacts, its threshold)``."""
        rotation, translation = self._tested_pose(best) if pose is None else pose
        mine = int(best.classes[0])
        return contact_test(self.exact_distance(mine),
                            (self.contact_positions - translation) @ rotation,
                            self.contact_normals @ rotation, self.params,
                            self.allowed_noise(mine), self.own_turn(mine))

    def allowed_noise(self, class_index):
        """The position noise the novelty test grants a class's contacts, scene units: the
        sensor's and a learned shape's own error (``shape_error``), in quadrature. A
        learned fork is a blob where its tines were: met again, a touch on a tine's side
        met the blob's other side (normals 130-170 degrees apart) and the fork was judged
        novel at touch 26. Only the sensor's without ``learned_noise``."""
        own = self.models[class_index].shape_error if self.params.learned_noise else 0.0
        return float(np.hypot(self.params.position_noise, own))

    def own_turn(self, class_index):
        """The normal error the novelty test grants a class's contacts beyond ``sigma_n``:
        a learned shape's own ``normal_error`` (0 for a given mesh, and for every class
        without ``learned_noise``). A learned fork's tines are blobs whose normals lie
        20-30 degrees (median) off its learning contacts' and its contacts' met again at
        the true pose, within a millimetre of it: every contact cost that turn and the
        fork met again was judged novel at nine touches in ten."""
        return self.models[class_index].normal_error if self.params.learned_noise else 0.0

    def exact_distance(self, class_index):
        """The exact distance of a class's mesh (:class:`~..shape.sdf.ExactDistance`),
        kept on the bank for the last :data:`EXACT_KEPT` classes asked for."""
        model = self.models[class_index]
        return kept_recent(self.bank.__dict__.setdefault("_exact", {}), class_index,
                           lambda: model.__dict__.get("exact")
                           or ExactDistance(model.mesh.vertices, model.mesh.faces), EXACT_KEPT)

    def _record(self, sampled, chosen=None):
        params = self.params
        n_pos, n_neg = len(self.contact_positions), len(self.noncontact_positions)
        contact_threshold = n_pos * (np.log(params.known_fraction)
                                     - log_normaliser(params.sigma_d, params.sigma_n))
        noncontact_threshold = n_neg * np.log(params.noncontact_fraction)
        threshold = contact_threshold + noncontact_threshold
        if self.particles is None:
            state = FilterState(self.step_count, None, self.class_names, {}, None, None, None,
                                -np.inf, threshold, False, 0, n_pos, n_neg)
        else:
            index = int(np.argmax(self.particles.log_weights)) if chosen is None else chosen
            best = self.particles.take([index])
            on_contacts = self.log_likelihood(best, self.contact_positions,
                                              self.contact_normals)[0]
            pose = self._tested_pose(best)  # refined once for both parts
            on_noncontacts = self._noncontact_test(best, pose)
            tested, tested_threshold = on_contacts, contact_threshold
            mine = int(best.classes[0])
            if (params.outlier_probability > 0 or self.allowed_noise(mine) > 0
                    or self.own_turn(mine) > 0 or self.scene.has_table) and n_pos:
                tested, tested_threshold = self._contact_test(best, pose)
            # Each kind must pass on its own: non-contacts far outside the MAP shape (likelihood
            # ~1 > 0.5) must not buy slack for contacts that miss its surface.
            novel = bool(tested < tested_threshold or on_noncontacts < noncontact_threshold)
            summed = np.bincount(self.particles.classes, np.exp(self.particles.log_weights),
                                 minlength=len(self.class_names))
            posterior = dict(zip(self.class_names, summed.tolist()))
            state = FilterState(
                self.step_count, self.particles, self.class_names, posterior,
                self.class_names[self.particles.classes[index]],
                self.particles.rotations[index].copy(), self.particles.translations[index].copy(),
                float(on_contacts + on_noncontacts), threshold, novel, sampled, n_pos, n_neg, index)
        self.state = state
        return state


def _with_log_weights(particles, log_weights):
    return Particles(particles.classes, particles.rotations, particles.translations,
                     normalise_log_weights(log_weights))
