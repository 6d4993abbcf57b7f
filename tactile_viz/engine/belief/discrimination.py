"""Telling near twins apart: the filter step beyond the paper for large libraries.

Between priors a few percent apart (a stretched variant, a rescaled copy, a learned shape
beside its source) the particle weights follow the luck of the sampling, not the fit: a
twin's surface lies well inside ``sigma_d`` of the truth, so resampling keeps whichever
class it happened to draw more of, and once its fit passes the sampling gate nothing brings
the other back. The evidence cannot tell them apart either: at ``sigma_d`` of 8% of the
size their distance terms differ by a fraction of a nat, less than what the broad normal
and non-contact terms vary. Their best fits still differ (on the bench's variants the true
class's refined RMS distance to the contacts was about 0.01 size units, its twins'
0.02-0.13), so each step:

1. the contenders are the MAP particle and the heaviest particle of each of the
   ``contenders`` heaviest classes holding at least ``contender_mass`` of the posterior;
2. the lookalikes are the ``contenders`` other classes whose surfaces pass closest to the
   contacts at the MAP's pose, if within ``sigma_d`` RMS (twins in a shared frame:
   variants, canonically aligned data sets);
3. all their poses are refined to the least squared distance to the contacts (plus the
   depth of non-contacts inside; with ``outlier_probability`` the farthest such fraction
   of the contacts left out), :func:`.pose_refinement.refine_poses`;
4. a lookalike that then fits better than every contender joins the belief at its refined
   pose, with the paper's relative weight against the MAP;
5. the MAP is the candidate whose refined pose has the least squared distance: a
   contender's own particle, or the lookalike that joined. Under the sensor's position
   noise (``position_noise``) the contacts are measured to the face turned their way and
   their normals weigh in (:mod:`.oriented`): the least ``RSS / (2 noise^2)`` plus the
   normals' cost. A knife's blade fitted noisy touches of a pencil better than the pencil,
   and with a blade the MAP the novelty test judged the pencil novel.

The contenders' particles are left as they are: moving the heaviest particle of a class to
its refined pose (and its weight by the gain) made that pose's mode win over the class's
other modes, a mug's handle on the wrong side among them. With one class holding the belief
and no lookalike close enough nothing changes.
"""

import numpy as np

from . import kernels
from .likelihood import normalise_log_weights
from .oriented import MIN_NORMAL_NOISE_DEG, oriented_evaluator, turned_cost
from .particles import Particles
from .pose_refinement import refine_poses, refine_warm, warm_starts


def contenders(particles, count, min_mass):
    """Indices of the heaviest particle of each of the ``count`` heaviest classes that hold
    at least ``min_mass`` of the posterior, heaviest class first: (k,) int."""
    mass = np.bincount(particles.classes, np.exp(particles.log_weights))
    classes = np.flatnonzero(mass >= min_mass)
    classes = classes[np.argsort(-mass[classes], kind="stable")][:count]
    # The heaviest particle of each class: the last of its class in weight order.
    order = np.lexsort((particles.log_weights, particles.classes))
    sorted_classes = particles.classes[order]
    last = order[np.r_[sorted_classes[1:] != sorted_classes[:-1], True]]
    return last[np.searchsorted(particles.classes[last], classes)]


def lookalikes(bank, rotation, translation, contacts, exclude, count, within):
    """Up to ``count`` classes (other than ``exclude``) whose surfaces pass closest to the
    contacts ``(m, 3)`` at one pose, those with an RMS signed distance under ``within``:
    (k,) int, best first."""
    n = len(bank.offsets)
    values = kernels.distances(*bank.grids, np.arange(n, dtype=np.int64),
                               np.repeat(rotation[None], n, axis=0),
                               np.repeat(translation[None], n, axis=0),
                               np.ascontiguousarray(contacts, dtype=float))
    misfit = np.square(values).mean(axis=1)
    misfit[np.asarray(exclude, dtype=int)] = np.inf
    best = np.argsort(misfit, kind="stable")[:count]
    return best[misfit[best] < within**2]


def discriminate(pf, particles, warm=None):
    """One discrimination step (see the module docstring).

    Parameters
    ----------
    pf : ParticleFilter
        Its parameters, bank, observations and :meth:`log_evidence_of` are used.
    particles : Particles
    warm : dict, optional
        The last step's ``refined`` (under noise the refinement starts from it).

    Returns
    -------
    particles : Particles
        The belief, with refined contenders and any lookalike that joined.
    chosen : int or None
        Index of the MAP in it, or None when no class contends (the heaviest stays MAP).
    refined : dict
        This step's refined poses, for the next step's ``warm``.
    """
    params = pf.params
    if not params.contenders or len(pf.contact_positions) < 3:
        return particles, None, {}
    heaviest = int(np.argmax(particles.log_weights))
    held = contenders(particles, params.contenders, params.contender_mass)
    held = np.r_[heaviest, held[held != heaviest]]
    rotation, translation = particles.rotations[heaviest], particles.translations[heaviest]
    others = lookalikes(pf.bank, rotation, translation, pf.contact_positions,
                        particles.classes[held], params.contenders, params.sigma_d)
    n = len(held)
    if n < 2 and not len(others):
        return particles, None, {}
    candidates = Particles.concatenate([
        particles.take(held),
        Particles(others, np.repeat(rotation[None], len(others), axis=0),
                  np.repeat(translation[None], len(others), axis=0), np.zeros(len(others)))])
    oriented = _oriented(pf)
    try:
        rotations, translations, misfit, refined = _refined(pf, candidates, oriented,
                                                            warm or {})
    except np.linalg.LinAlgError:
        return particles, None, {}
    misfit = np.where(np.isfinite(misfit), misfit, np.inf)
    if oriented is not None:
        # In nats: the normals weigh in (a knife's blade fits a noisy pencil's positions).
        misfit = misfit / (2 * params.position_noise**2) + turned_cost(
            oriented, candidates.classes, rotations, translations, pf.contact_positions,
            pf.contact_normals, MIN_NORMAL_NOISE_DEG)
    joining = n + np.flatnonzero(misfit[n:] < misfit[:n].min())
    if n < 2 and not len(joining):
        return particles, None, refined
    positions = np.r_[held, len(particles) + np.arange(len(joining))]
    if len(joining):
        # Lookalikes: the paper's new-particle weight, relative to the MAP.
        evidence = pf.log_evidence_of(Particles.concatenate([
            particles.take([heaviest]),
            Particles(candidates.classes[joining], rotations[joining], translations[joining],
                      np.zeros(len(joining)))]))
        joined = Particles(candidates.classes[joining], rotations[joining], translations[joining],
                           particles.log_weights[heaviest] + evidence[1:] - evidence[0])
        belief = Particles.concatenate([particles, joined])
        particles = Particles(belief.classes, belief.rotations, belief.translations,
                              normalise_log_weights(belief.log_weights))
    chosen = int(positions[int(np.argmin(misfit[np.r_[np.arange(n), joining]]))])
    return particles, chosen, refined


def _refined(pf, candidates, oriented, warm):
    """The candidates' poses refined (:func:`.pose_refinement.refine_poses`), their
    misfits, and the poses by candidate (class and unrefined pose) for the next step.

    Under noise a candidate the last step refined (the same class at the same pose: a
    particle that survived resampling, or a lookalike at an unchanged MAP) starts from
    that refined pose and takes ``refine_warm_iterations`` steps: one new contact moves
    its optimum little, and the oriented look-ups of ten steps from the particle's pose
    were most of a noisy step. Without noise the refinement starts afresh (as measured)."""
    params = pf.params
    if oriented is None or not params.refine_warm_iterations:
        return (*refine_poses(
            pf.bank.evaluate, candidates.classes, candidates.rotations, candidates.translations,
            pf.contact_positions, pf.noncontact_positions, params.refine_iterations,
            trim=params.outlier_probability, normals=pf.contact_normals, oriented=oriented,
            clearance=pf.scene.tip_radius, below=pf.bank.below), {})
    keys, rotations, translations, started = warm_starts(
        candidates.classes, candidates.rotations, candidates.translations, warm)
    rotations, translations, misfit = refine_warm(
        pf.bank.evaluate, candidates.classes, rotations, translations, started,
        params.refine_iterations, params.refine_warm_iterations, pf.contact_positions,
        pf.noncontact_positions, trim=params.outlier_probability, normals=pf.contact_normals,
        oriented=oriented, clearance=pf.scene.tip_radius,
        below=pf.bank.below)
    refined = {key: (rotations[index], translations[index]) for index, key in enumerate(keys)}
    return rotations, translations, misfit, refined


def _oriented(pf):
    """Under position noise, contacts measured to the surface facing their way
    (:mod:`.oriented`): a grid's distance folds the noise at a thin wall, and a twin with
    a wall where the object has none fits better than the object. None without noise
    (the noiseless path is left as it was measured)."""
    noise = pf.params.position_noise
    if noise <= 0:
        return None
    # The filter is not told the normal noise: the samples' own roughness bounds it.
    return oriented_evaluator(pf.bank, pf.models, noise, MIN_NORMAL_NOISE_DEG)
