"""Deciding a known object, and where to touch to decide it (beyond the paper).

The paper stops when the MAP surface is covered, which says nothing about whether another
class or another pose would explain the contacts as well: two screwdrivers that share a
handle are both covered before the tip is touched. Here a step's belief is *decided* when

1. the object is judged known,
2. the classes weighed below hold at least ``decision_confidence`` of the filter's class
   posterior (its broad likelihood cannot tell near twins apart, but it does say which
   classes matter),
3. among the distinct hypotheses that could explain the contacts, the lead (the MAP, a
   pose of its class the positions prefer, :func:`~.lead.particle_lead`, or with ``any_class`` a
   hypothesis of another class, :func:`~.lead.class_lead`) holds at least
   ``decision_confidence`` of their fit posterior,
4. the lead fits within the noise: its refined residuals pass a chi-squared test at
   ``decision_confidence`` with the noise scale ``s`` below and ``n - 6`` degrees of freedom
   (a rival the particles never held cannot be weighed, but a MAP in a wrong mode leaves
   residuals beyond the noise); when its grid's residuals fail, those on its mesh are
   tested without the grid's error; with ``decision_normals_p`` its contacts' normals
   too (:func:`~.fit_test.turn_p`: a spatula fits a fork's touches within a millimetre,
   their normals not), and
5. no other pose mode of its class fits within the noise as well while lying farther from
   it than the pose tolerance (:func:`_open_modes`; such a mode is aimed at however
   improbable: a can whose ends differ by a few mm of rim was decided 178 degrees off).

The hypotheses are the MAP particle, the heaviest particles of other pose modes and other
classes, the classes whose surfaces pass close to the contacts at the MAP's pose, and the
MAP's pose turned half about each principal axis of its shape
(:func:`~.round_turns.flips`: a mug upside down fits touches of its outside as well, and
the particles may never have held it; with ``any_class`` the flips of the last touch's
most probable hypothesis too, when it is of another class), and
the plausible hypotheses of the step before (a mode the particles lost under noise is
weighed until it no longer fits). Each
is refined to its best pose (:func:`~.pose_refinement.refine_poses`), and one whose shape
is round about an axis turned about it to where its normals fit best
(:func:`~.round_turns.turn_round_hypotheses`); two hypotheses of one
class whose posed surfaces agree (a symmetry of the shape, or two particles of one mode)
are one. Their fit posterior is Gaussian in the refined residuals with one noise scale,
``s^2 = max(RSS_best / (n - 6), floor^2 + e^2)``: the residual scatter of the best fit (six
pose parameters spent), at least the sensor's position noise and ``decision_floor`` in
quadrature (``floor``) with the MAP grid's own error at its surface (``e``,
:func:`~.fit_test.grid_error`)::

    log p_k = -(RSS_k - RSS_best) / (2 s^2) - N_k   (normalised over the hypotheses)

with ``N_k`` what the contacts' measured normals cost hypothesis ``k``
(:func:`~.oriented.turned_cost`): positions alone let a knife's 4 mm blade fit a dozen
noisy touches of a 7 mm pencil better than the pencil, whose normals turn all the way round.

While hypotheses other than the MAP stay plausible, :func:`~.telling.disagreement_target` picks the
point that tells them apart best: the point of one hypothesis's surface where a touch is
expected to take the most posterior mass from the others.
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import ndtri

from ..shape.symmetry import symmetry_group
from ..transforms import transform_points
from .discrimination import contenders, lookalikes
from .fit_test import fit_limit, fit_test, model_floor2, model_turn_deg, normals_fit
from .grouped import lead_grouped_p
from .incremental import MODE_ANGLE_DEG, NOTHING, Refined, full_search_due, remembered, starts
from .lead import class_lead, fit_leader, particle_lead
from .mesh_fit import NO_FITS, weighed_on_meshes
from .modes import distinct, mode_tolerance, pose_disagreements, surface_disagreement
from .oriented import oriented_evaluator, turned_cost
from .pose_refinement import POSE_PARAMETERS, refine_poses, surface_uncertainty
from .posed import posed_by_normals
from .round_turns import flips, turn_near_spheres, turn_round_hypotheses
from .spread import FREE_PER_CONTACT, seen_through, spread_contacts, thinned
from .support import table_support

TOP_PARTICLES = 64  # the heaviest particles searched for other pose modes
OTHER_CLASSES = 4  # classes besides the MAP's whose heaviest particle is a rival
HELD_CLASSES = 8  # up to this many, those the filter holds at least PLAUSIBLE of
OTHER_MODES = 3  # pose modes of the MAP's class besides its own
PLAUSIBLE = 1e-3  # fit posterior above which a rival is aimed at
MAX_RIVALS = 8  # the most plausible rivals aimed at and carried to the next step
REFINE_TOLERANCE = 1e-4  # a hypothesis's fit ends once a step gains less than this share


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One distinct explanation of the contacts.

    Attributes
    ----------
    class_index : int
    rotation : (3, 3) float
        Refined ``object_to_world`` rotation.
    translation : (3,) float, scene units
    misfit : float, squared scene units
        Sum of squared signed distances of the contacts (and of non-contacts inside).
    probability : float
        Fit posterior among the hypotheses.
    turned : float
        What the contacts' measured normals cost it, nats (:func:`~.oriented.turned_cost`).
    """

    class_index: int
    rotation: np.ndarray
    translation: np.ndarray
    misfit: float
    probability: float
    turned: float = 0.0


@dataclass(frozen=True, eq=False)
class Decision:
    """Whether a step's belief is decided (see the module).

    Attributes
    ----------
    decided : bool
    confidence : float
        The smaller of the weighed classes' share of the class posterior and the MAP's fit
        posterior (0 when not assessed: novel, fewer than three contacts).
    hypotheses : tuple of Hypothesis
        The MAP first, then the rivals by fit; empty when not assessed.
    fits : bool
        Whether the MAP's residuals pass the chi-squared test (rivals are worth telling
        apart only then: otherwise the object is none of them).
    loosest : ((3,) float, (3,) float) or None
        While the MAP is the one hypothesis but its pose is not yet known well enough: the
        point of its surface (world frame) whose place is least certain, and its outward
        normal; a touch there pins the pose most.
    scale : float, scene units
        The fit posterior's noise scale ``s`` (0 when not assessed).
    modes : tuple of Hypothesis
        Other pose modes of the MAP's class that fit within the noise as well, farther
        from it than the pose tolerance: the pose is not decided while one is left, and
        they are aimed at as rivals however improbable.
    fit_p : float
        The chi-squared test's p-value of the MAP's residuals, the better of its grid's
        and its mesh's (1 when it fits at the confidence, or when not assessed): how
        unlikely a right hypothesis leaves them.
    group_p : float
        The p-value of the MAP's residuals averaged by place (:mod:`.grouped`), or as its
        shape stretched (:mod:`.stretch`), the smaller (1 when not asked for or not
        assessed): a look-alike's misfit, shared by the contacts of a place or all of
        them, stands out of the noise there long before it does in ``fit_p``.
    refined : Refined
        What it refined, for the next touch's starts (:mod:`.incremental`).
    lead : Hypothesis or None
        The hypothesis the fit test and the decision are about (None: not assessed).
    """

    decided: bool
    confidence: float
    hypotheses: tuple = ()
    fits: bool = False
    loosest: object = None
    scale: float = 0.0
    modes: tuple = ()
    fit_p: float = 1.0
    group_p: float = 1.0
    refined: Refined = field(default=NOTHING, repr=False)
    lead: object = field(default=None, repr=False)

    @property
    def rivals(self):
        """The hypotheses besides the MAP that are still plausible, the ``MAX_RIVALS``
        most plausible: contacts on one flat face fit every flat face of a library about
        as well, and carried from step to step the rivals grew past a hundred, each
        weighed against each other for every telling target."""
        plausible = [h for h in self.hypotheses[1:] if h.probability >= PLAUSIBLE]
        plausible += [h for h in self.modes if h not in plausible]
        return tuple(sorted(plausible, key=lambda h: -h.probability)[:MAX_RIVALS])

    @property
    def carried(self):
        """The MAP and its rivals: weighed again at the next step (``carried``)."""
        return self.hypotheses[:1] + self.rivals


UNDECIDED = Decision(False, 0.0)


def decide(pf, belief, confidence=0.99, floor=0.0, same_mode=0.0, carried=(), free_space=None,
           pose_tolerance=np.inf, normal_noise_deg=0.0, refined=NOTHING, refresh=1,
           budget=np.inf, normals=False, any_class=False, spread=0, localisation=None,
           least_turn_p=0.0):
    """The :class:`Decision` of a filter's belief.

    Parameters
    ----------
    pf : ParticleFilter
        Its bank, parameters and observations are read (nothing is changed).
    belief : FilterState
    confidence : float
        ``decision_confidence``.
    floor : float, scene units
        Least noise scale of the fit posterior besides the grid's own error and a learned
        MAP's ``shape_error``: the sensor's position noise and the contact's localisation,
        in quadrature.
    same_mode : float, scene units
        Hypotheses of one class whose posed surfaces agree within this distance
        (:func:`~.modes.surface_disagreement`) are one.
    carried : sequence of Hypothesis
        The plausible hypotheses of the step before: weighed again, so that a mode the
        particles lost (resampling under noise) is not forgotten while it still fits.
    free_space : (k, 3) float, world frame, optional
        Points of the paths missed probes passed through: like a non-contact, each costs
        a hypothesis its depth inside (a probe's end can lie beyond a thin blade or a
        handle it passed through, and a pose turned a little avoids one point).
    pose_tolerance : float
        How far the MAP's surface may be off, as a share of its longest side: decided only
        once its surface's uncertainty along the normals
        (:func:`~.pose_refinement.surface_uncertainty`), times the two-sided normal
        quantile of ``confidence``, is within it (a 2 cm block under 2 mm noise is known
        long before it is posed within 10% of its size).
    normal_noise_deg : float
        The sensor's normal noise (std, degrees): with ``floor`` it weighs a contact's
        normal against its position when it is matched to a hypothesis's surface
        (:mod:`.oriented`).
    refined : Refined
        The last touch's ``Decision.refined``: candidates start from its poses, and
        between full searches those in its modes are left out (:mod:`.incremental`).
    refresh : int
        Contacts between full searches (``decision_refresh``). Only a full search decides:
        an incremental touch that would is searched in full; every fit stops once it
        converges (``REFINE_TOLERANCE``). 1: every touch searches afresh from the
        filter's poses, every fit takes ``refine_iterations``, as before
        :mod:`.incremental`.
    budget : int
        Between full searches, the candidates besides the MAP's that a touch refines
        from the filter's poses at most (``decision_budget``).
    normals : bool
        ``decision_normals``: the lead is refitted with the contacts' measured normals
        beside their positions (:func:`posed_by_normals`), the pose whose uncertainty
        decides and that is reported, and a pose mode whose normals cost it more than
        ``log(1 / (1 - confidence))`` nats over the lead's is not open.
    any_class : bool
        ``decision_any_class``: a hypothesis of another class than the filter's MAP, the
        class of the last touch's most probable hypothesis (whose flips are weighed), may
        lead (:func:`~.lead.class_lead`); decided, it comes first in ``hypotheses``.
    spread : int
        With more contacts, searched first on this many of them spread over the object
        and a thinned free space, and again on all unless the lead misfits there
        (:mod:`.spread`; 0: on all; the planner asks it while the MAP keeps misfitting).
    localisation : float or None, scene units
        What the contacts of one place may share off a right hypothesis (the contact's
        localisation): with it the lead's residuals are also tested by place
        (``Decision.group_p``, :func:`~.grouped.lead_grouped_p`); None: not tested.
    least_turn_p : float
        ``decision_normals_p``: a lead whose contacts' normals cost it more than the noise
        leaves at this p-value (:func:`~.fit_test.turn_p`, at its own normal error) is not
        decided (0: not tested).

    Returns
    -------
    Decision
    """
    options = dict(confidence=confidence, floor=floor, same_mode=same_mode, carried=carried,
                   free_space=free_space, pose_tolerance=pose_tolerance,
                   normal_noise_deg=normal_noise_deg, refined=refined, budget=budget,
                   normals=normals, any_class=any_class, localisation=localisation,
                   least_turn_p=least_turn_p)
    count = len(pf.contact_positions)
    incremental = refresh > 1  # else as before: afresh at each touch
    full = not incremental or full_search_due(refined, count, refresh)
    index = spread_contacts(pf.contact_positions, spread)
    view = seen_through(pf, index) if len(index) < count else None
    decision = None
    if view is not None:
        decision = _weigh(view, belief, full=full, incremental=incremental, count=count,
                          **{**options, "free_space": thinned(free_space,
                                                              FREE_PER_CONTACT * spread)})
        fits, fit_p, group_p = True, 1.0, 1.0  # a lead that fits, or none: searched on all
        if decision.lead is not None and not decision.fits:  # its misfit, tested on all
            fits, fit_p, group_p = _tested_on_all(pf, decision.lead, floor, confidence,
                                                  free_space, normal_noise_deg, normals,
                                                  incremental, localisation)
        decision = None if fits else replace(decision, fit_p=fit_p, group_p=group_p)
    if decision is None:
        decision = _weigh(pf, belief, full=full, incremental=incremental, count=count,
                          **options)
    if decision.decided and not full:  # only a full search decides
        decision = _weigh(pf, belief, full=True, incremental=True, count=count, **options)
    return decision


def _outside(pf, free_space):
    """The points a fit keeps its shape off: the non-contacts and the ``free_space``."""
    if free_space is None:
        return pf.noncontact_positions
    return np.vstack([pf.noncontact_positions, np.reshape(free_space, (-1, 3))])


def _refined(pf, classes, rotations, translations, outside, oriented, tolerance):
    """The poses refined on the filter's contacts and ``outside``
    (:func:`~.pose_refinement.refine_poses`): rotations, translations, misfits."""
    return refine_poses(
        pf.bank.evaluate, classes, rotations, translations, pf.contact_positions, outside,
        pf.params.refine_iterations, trim=pf.params.outlier_probability,
        normals=pf.contact_normals, oriented=oriented, clearance=pf.scene.tip_radius,
        support=table_support(pf), below=pf.bank.below, tolerance=tolerance)


def _tested_on_all(pf, lead, floor, confidence, free_space, normal_noise_deg, normals,
                   incremental, localisation=None):
    """``(fits, fit_p, group_p)`` of a lead found on a spread of the contacts
    (:mod:`.spread`), its pose refined on every contact and all the free space first:
    :func:`fit_test`'s and, when it misfits, its look-alike tests' p-value there
    (:func:`~.grouped.lead_grouped_p`; 1 without ``localisation``). On the spread
    alone, 64 of a mug's 150 contacts at 2 mm, its 4% larger copy's stretch passed at
    1e-3 where all of them refuted it at 1e-8, every other step: the misfit count never
    reached five."""
    outside = _outside(pf, free_space)
    oriented = oriented_evaluator(pf.bank, pf.models, max(floor, 1e-12), normal_noise_deg,
                                  normals)
    tolerance = REFINE_TOLERANCE if incremental else 0.0
    try:
        rotations, translations, misfit = _refined(
            pf, [lead.class_index], lead.rotation[None], lead.translation[None], outside,
            oriented, tolerance)
    except np.linalg.LinAlgError:
        return True, 1.0, 1.0  # untested: searched on all
    refit = replace(lead, rotation=rotations[0], translation=translations[0],
                    misfit=float(misfit[0]) if np.isfinite(misfit[0]) else np.inf)
    fits, fit_p = fit_test(pf, refit, floor, confidence, outside, oriented, tolerance)[:2]
    group_p = 1.0 if localisation is None or fits else lead_grouped_p(
        pf, refit, oriented, floor, localisation, confidence, outside, tolerance)
    return fits, fit_p, group_p


def _weigh(pf, belief, confidence, floor, same_mode, carried, free_space, pose_tolerance,
           normal_noise_deg, refined, budget, full, incremental, normals, any_class, count,
           localisation=None, least_turn_p=0.0):
    """:func:`decide`, a full search or not, with what the last touch refined or
    afresh (not ``incremental``: the decision as it was before :mod:`.incremental`);
    ``count`` the filter's contacts (``pf`` may see a spread of them)."""
    contacts = pf.contact_positions
    if belief.particles is None or len(contacts) < 3:
        return UNDECIDED
    particles = belief.particles
    chosen = int(np.argmax(particles.log_weights)) if belief.map_index is None else belief.map_index
    candidates = _candidates(pf, particles, chosen, same_mode)
    classes = particles.classes[candidates]
    map_class = particles.classes[chosen]
    # Every class that fits at the MAP's pose is weighed there, even one whose heaviest
    # particle is weighed elsewhere (in another mode): a scaled twin fits best there.
    others = lookalikes(pf.bank, particles.rotations[chosen], particles.translations[chosen],
                        contacts, [map_class], OTHER_CLASSES, pf.params.sigma_d)
    leader = fit_leader([h for h in carried if h.class_index < len(pf.models)],
                        map_class) if any_class else None
    flipped_classes, flipped_rotations, flipped_translations = _flipped(
        pf, [(map_class, particles.rotations[chosen], particles.translations[chosen]), leader])
    classes = np.r_[classes, others, flipped_classes].astype(np.int64)
    rotations = np.concatenate([particles.rotations[candidates],
                                np.repeat(particles.rotations[chosen][None], len(others), 0),
                                flipped_rotations])
    translations = np.concatenate([particles.translations[candidates],
                                   np.repeat(particles.translations[chosen][None],
                                             len(others), 0), flipped_translations])
    begun = rotations, translations
    memory = refined if incremental else NOTHING
    tolerance = REFINE_TOLERANCE if incremental else 0.0
    rotations, translations, source, fresh = starts(classes, rotations, translations, memory,
                                                    same_mode, full, budget)
    left_out = classes[~fresh & (source >= 0)]  # weighed at an earlier touch
    classes, rotations, translations = classes[fresh], rotations[fresh], translations[fresh]
    # A carried hypothesis a fresh one starts from is weighed once.
    kept = [h for h in carried if h.class_index < len(pf.models) and not (
        incremental and _starts_at(h, classes, rotations, translations))]
    classes = np.r_[classes, [h.class_index for h in kept]].astype(np.int64)
    rotations = np.concatenate([rotations, np.reshape([h.rotation for h in kept], (-1, 3, 3))])
    translations = np.concatenate([translations,
                                   np.reshape([h.translation for h in kept], (-1, 3))])
    outside = _outside(pf, free_space)
    oriented = oriented_evaluator(pf.bank, pf.models, max(floor, 1e-12), normal_noise_deg,
                                  normals)
    try:
        rotations, translations, misfit = _refined(pf, classes, rotations, translations,
                                                   outside, oriented, tolerance)
    except np.linalg.LinAlgError:
        return UNDECIDED
    memory = remembered(memory, source, fresh, begun, classes,
                        (rotations.copy(), translations.copy()),
                        count if full else memory.searched)
    misfit = np.where(np.isfinite(misfit), misfit, np.inf)
    best = float(misfit.min())
    floor2 = model_floor2(pf, classes[0], floor)  # the MAP's model, a learned one's error too
    scale2 = max(best / max(len(contacts) - POSE_PARAMETERS, 1), floor2, 1e-300)
    turn_deg = model_turn_deg(pf, classes[0], normal_noise_deg)  # a learned MAP's own too
    turned = np.full(len(classes), np.inf)
    finite = np.flatnonzero(np.isfinite(misfit))
    if len(finite):
        turned[finite] = turned_cost(oriented, classes[finite], rotations[finite],
                                     translations[finite], contacts, pf.contact_normals,
                                     turn_deg)
    # Each mode is kept as its most probable pose, the normals weighed in: a cross
    # screwdriver turned 60 degrees about its shaft fitted noisy touches' positions better
    # than turned right, and, kept for the mode, lost to the flat one by its tip's normals.
    keep = distinct(pf.bank, classes, rotations, translations, misfit / (2 * scale2) + turned,
                    [mode_tolerance(model, same_mode) for model in pf.models], same_mode)
    for turn in (turn_round_hypotheses, turn_near_spheres):
        rotations, translations, misfit, turned = turn(
            pf, oriented, classes, rotations, translations, misfit, turned, scale2, outside,
            turn_deg, among=keep)
    occam = 0.5 * np.log(len(contacts)) * np.array(
        [used_pose_parameters(pf.models[c], scale2) for c in classes[keep]])
    log_p = -(misfit[keep] - best) / (2 * scale2) - turned[keep] - occam  # the fit posterior
    if full:  # between full searches the grid's posterior only aims and carries rivals
        log_p, meshes = weighed_on_meshes(
            pf, classes[keep], rotations[keep], translations[keep], log_p, turned[keep] + occam,
            outside, oriented, floor, (refined.meshes or NO_FITS) if incremental else NO_FITS,
            same_mode, tolerance)
        memory = replace(memory, meshes=meshes)
    probability = np.exp(log_p - np.logaddexp.reduce(log_p))
    order = np.argsort(-probability, kind="stable")
    order = np.r_[0, order[order != 0]]  # the MAP candidate leads
    hypotheses = tuple(Hypothesis(int(classes[keep[k]]), rotations[keep[k]],
                                  translations[keep[k]], float(misfit[keep[k]]),
                                  float(probability[k]), float(turned[keep[k]]))
                       for k in order)
    # The filter's broad likelihood cannot tell near twins apart, but it does say which
    # classes matter: those weighed here must hold the confidence between them.
    # Summed in name order: a set's order follows the string hash, which changes from one
    # process to the next, and so would the sum's last bit.
    weighed = sorted({belief.class_names[c] for c in np.r_[classes[keep], left_out]})
    weighed_share = sum(belief.class_posterior.get(name, 0.0) for name in weighed)
    dof = len(contacts) - POSE_PARAMETERS
    lead = particle_lead(hypotheses, scale2, confidence)
    if leader is not None:  # only the class whose flips were weighed, as rival modes
        lead = class_lead([h for h in hypotheses if h.class_index == leader[0]], lead, scale2,
                          confidence, belief.class_posterior, belief.class_names,
                          lambda c: fit_limit(pf, c, floor, confidence, dof))
    level = min(weighed_share, lead.probability)
    fits, fit_p, limit = fit_test(pf, lead, floor, confidence, outside, oriented, tolerance)
    group_p = 1.0 if localisation is None else lead_grouped_p(
        pf, lead, oriented, floor, localisation, confidence, outside, tolerance)
    loosest, modes, posed = None, (), lead
    if fits and level >= confidence:
        modes = _open_modes(pf.bank, hypotheses, lead, limit,
                            pose_tolerance * pf.models[lead.class_index].length,
                            np.log(1 / (1 - confidence)) if normals else np.inf)
        posed = posed_by_normals(pf, lead, outside, oriented, tolerance)
        loosest = _loosest(pf, posed, scale2, confidence, pose_tolerance, oriented.fit_noise)
    decided = (not belief.novel and fits and level >= confidence and loosest is None
               and not modes and normals_fit(pf, lead, oriented, normal_noise_deg,
                                             least_turn_p, turn_deg))
    if decided:  # the decided pose is the one reported and aimed from
        hypotheses = (posed,) + tuple(h for h in hypotheses if h is not lead)
        memory = replace(memory, decided=True)
    return Decision(bool(decided), float(level), hypotheses, bool(fits), loosest,
                    float(np.sqrt(scale2)), modes, fit_p, group_p, memory, lead)


def _flipped(pf, poses):
    """:func:`~.round_turns.flips` of each ``(class, rotation, translation)`` (None
    skipped): classes (k,), rotations (k, 3, 3), translations (k, 3)."""
    turned = [(c, *flips(pf, c, rotation, translation))
              for c, rotation, translation in (p for p in poses if p is not None)]
    return (np.concatenate([np.full(len(r), c) for c, r, _ in turned]),
            np.concatenate([r for _, r, _ in turned]), np.concatenate([t for _, _, t in turned]))


def _starts_at(hypothesis, classes, rotations, translations):
    """Whether a hypothesis's pose is one of ``rotations``, ``translations`` of its class,
    to the bit."""
    mine = np.flatnonzero(classes == hypothesis.class_index)
    return bool(np.any(np.all(rotations[mine] == hypothesis.rotation, axis=(1, 2))
                       & np.all(translations[mine] == hypothesis.translation, axis=1)))


def _open_modes(bank, hypotheses, lead, limit, tolerance, turned=np.inf):
    """The other pose modes of the lead's class that fit within the noise too (squared
    residuals within ``limit``, and normals that cost at most ``turned`` nats more than
    the lead's) and whose surfaces lie farther from the lead's than the pose
    ``tolerance`` forgives (scene units): while one is left the pose is not decided,
    however the fit posterior leans (a can whose ends differ by a few mm of rim was
    decided 178 degrees off). A 2 cm block's poses a few degrees off a symmetry fit its
    noisy positions within 10% RMS at any count of contacts, but their normals cost
    them 100 nats more."""
    if not np.isfinite(tolerance):
        return ()
    modes = [h for h in hypotheses if h is not lead and h.class_index == lead.class_index
             and h.misfit <= limit and h.turned - lead.turned <= turned]
    if not modes:
        return ()
    apart = pose_disagreements(bank, lead.class_index, lead.rotation, lead.translation,
                               np.array([h.rotation for h in modes]),
                               np.array([h.translation for h in modes])) > tolerance
    return tuple(h for h, far in zip(modes, apart) if far)


def _loosest(pf, hypothesis, scale2, confidence, tolerance, normal_noise=None):
    """None when the MAP's pose is known within ``tolerance`` of its longest side at
    ``confidence`` (see :func:`decide`), else its surface point whose place is least
    certain and its normal, world frame. With ``normal_noise`` the contacts' normals
    pin the turn too, as they did in the fit."""
    if not np.isfinite(tolerance):
        return None
    c = hypothesis.class_index
    group = symmetry_group(pf.models[c])
    axes = np.eye(3) if group.is_sphere else np.reshape(
        [] if group.axis is None else group.axis, (-1, 3))
    # A round shape's own turns move its surface by its detail (roughness) at most.
    spread = np.hypot(group.roughness, surface_uncertainty(
        pf.bank.evaluate, c, hypothesis.rotation, hypothesis.translation,
        pf.contact_positions, pf.bank.points[c], pf.bank.normals[c], scale2,
        free_turns=axes @ hypothesis.rotation.T, support=table_support(pf),
        pivot=transform_points(group.centre[None], hypothesis.rotation,
                               hypothesis.translation)[0],
        measured=pf.contact_normals, normal_noise=normal_noise))
    worst = int(np.argmax(spread))
    if ndtri(0.5 + confidence / 2) * spread[worst] <= pose_limit(pf, c, tolerance):
        return None
    return (transform_points(pf.bank.points[c][worst:worst + 1], hypothesis.rotation,
                             hypothesis.translation)[0],
            pf.bank.normals[c][worst] @ hypothesis.rotation.T)


def pose_limit(pf, class_index, tolerance):
    """How far a decided pose's surface may be off at the decision's confidence, scene
    units: ``tolerance`` of the class's longest side, or for a learned shape (with
    ``learned_noise``) as far as its own error puts two copies of it apart
    (:func:`~.modes.mode_tolerance`), if that is farther: poses that differ by less are one
    mode, and a 2 cm block learned 1.8 mm off (RMS) and met again at 2 mm noise was not
    posed within 1 mm in 86 touches."""
    model = pf.models[class_index]
    own = mode_tolerance(model, 0.0) if pf.params.learned_noise else 0.0
    return max(tolerance * model.length, own)


def used_pose_parameters(model, scale2):
    """How many of the six pose parameters a class's fit uses (an Occam charge of
    ``log(n) / 2`` each, the Bayesian information criterion's).

    A turn about an exactly round axis moves nothing, so it is not fitted: a smooth ball
    uses three (its position), a cylinder five. Detail that breaks the roundness (a bumpy
    ball's bumps, RMS ``r``) makes the turn count by ``r^2 / (r^2 + s^2)`` (the share of a
    parameter the data determine, MacKay's effective number): under noise ``s`` far above
    the bumps a bumpy ball is charged as a smooth one, and its turns cannot fit the noise
    for free.
    """
    group = symmetry_group(model)
    free = 3 if group.is_sphere else (1 if group.axis is not None else 0)
    r2 = group.roughness**2
    return POSE_PARAMETERS - free * (1.0 - r2 / (r2 + scale2))


def _candidates(pf, particles, chosen, same_mode):
    """Indices of the MAP particle, the heaviest particle of each of the other classes held
    (up to ``HELD_CLASSES`` holding ``PLAUSIBLE`` of the posterior, at least
    ``OTHER_CLASSES``; heaviest class first: a pencil's posterior spread over six thin
    classes, and weighing four of them the decision could not reach its confidence)
    and the heaviest particles of up to
    ``OTHER_MODES`` other pose modes of the MAP's class (poses apart by more than
    ``MODE_ANGLE_DEG`` or ``same_mode``, whose surfaces differ: a symmetry is not a mode)."""
    kept = [chosen]
    held = contenders(particles, HELD_CLASSES + 1, 0.0)
    mass = np.bincount(particles.classes, np.exp(particles.log_weights))
    held = [int(i) for i in held if particles.classes[i] != particles.classes[chosen]]
    kept += [i for n, i in enumerate(held)
             if n < OTHER_CLASSES or mass[particles.classes[i]] >= PLAUSIBLE][:HELD_CLASSES]
    order = np.argsort(-particles.log_weights, kind="stable")[:TOP_PARTICLES]
    mine = [int(i) for i in order if particles.classes[i] == particles.classes[chosen]]
    modes = [chosen]
    for index in mine:
        if len(modes) > OTHER_MODES:
            break
        if all(_poses_apart(particles, index, k, same_mode) for k in modes) and all(
                _apart(pf.bank, particles, index, k, same_mode) for k in modes):
            modes.append(index)
    return np.array(kept + modes[1:], dtype=np.int64)


def _poses_apart(particles, a, b, distance):
    """Whether two particles' poses differ by more than ``MODE_ANGLE_DEG`` or ``distance``."""
    turn = particles.rotations[a] @ particles.rotations[b].T
    angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1.0, 1.0)))
    gap = np.linalg.norm(particles.translations[a] - particles.translations[b])
    return bool(angle > MODE_ANGLE_DEG or gap > distance)


def _apart(bank, particles, a, b, tolerance):
    """Whether particles ``a`` and ``b`` are distinct hypotheses: other classes, or their
    posed surfaces further apart than ``tolerance`` (:func:`~.modes.surface_disagreement`)."""
    if particles.classes[a] != particles.classes[b]:
        return True
    return surface_disagreement(bank, particles.classes[a], particles.rotations[[a, b]],
                                particles.translations[[a, b]]) > tolerance

