"""A decision held from touch to touch (beyond the paper).

Once a known object is decided, a fresh :func:`~.decision.decide` at every further touch
searches the filter's modes, its classes' look-alikes, flips and round turns again, and was
most of what a known touch cost (issue 63: 129 ms of a 159-211 ms step on the bundled
armadillo). New contacts can only refute a decision by not fitting it, so the decided
hypothesis alone is refitted from its pose with every contact (one warm-started
Levenberg-Marquardt) and kept while it passes the decision's own fit test, the
chi-squared test of its residuals at ``confidence`` (and of its normals, with
``least_turn_p``), and the filter still puts the class at ``confidence``; otherwise the
decision is made afresh.
"""

import numpy as np

from .decision import Decision, Hypothesis
from .fit_test import fit_limit, model_floor2, normals_fit
from .grouped import lead_grouped_p
from .oriented import oriented_evaluator
from .pose_refinement import POSE_PARAMETERS, refine_poses
from .posed import posed_by_normals
from .support import table_support


def held_decision(pf, belief, lead, confidence=0.99, floor=0.0, free_space=None,
                  normal_noise_deg=0.0, normals=False, localisation=None, least_turn_p=0.0):
    """The decided ``lead`` refitted to every contact, as a :class:`~.decision.Decision`,
    or None when the decision must be made afresh.

    Parameters
    ----------
    pf : ParticleFilter
        Its bank, parameters and observations are read (nothing is changed).
    belief : FilterState
    lead : Hypothesis
        The decided hypothesis of an earlier touch.
    confidence, floor, free_space, normal_noise_deg, normals, localisation, least_turn_p
        As for :func:`~.decision.decide`.

    Returns
    -------
    Decision or None
        Decided, its one hypothesis the refitted lead; None when the object is judged
        novel, the filter's MAP class is another, its posterior below ``confidence``, or
        the contacts no longer fit the lead within the noise.
    """
    contacts = pf.contact_positions
    c = int(lead.class_index)
    dof = len(contacts) - POSE_PARAMETERS
    if (belief.novel or belief.particles is None or dof <= 0 or c >= len(pf.models)
            or belief.class_names[c] != belief.map_class):
        return None
    share = float(belief.class_posterior.get(belief.map_class, 0.0))
    if share < confidence:
        return None
    outside = np.vstack([pf.noncontact_positions, np.reshape(
        [] if free_space is None else free_space, (-1, 3))])
    oriented = oriented_evaluator(pf.bank, pf.models, max(floor, 1e-12), normal_noise_deg,
                                  normals)
    try:
        rotations, translations, misfit = refine_poses(
            pf.bank.evaluate, np.array([c]), lead.rotation[None], lead.translation[None],
            contacts, outside, pf.params.refine_iterations,
            trim=pf.params.outlier_probability, normals=pf.contact_normals,
            oriented=oriented, clearance=pf.scene.tip_radius, support=table_support(pf),
            below=pf.bank.below)
    except np.linalg.LinAlgError:
        return None
    misfit = float(misfit[0])
    if not misfit <= fit_limit(pf, c, floor, confidence, dof):
        return None  # a misfit (or NaN) reopens the decision
    # Tested on positions, reported posed by the normals too (as :func:`~.decision.decide`).
    refitted = Hypothesis(c, rotations[0], translations[0], misfit, 1.0)
    if not normals_fit(pf, refitted, oriented, normal_noise_deg, least_turn_p):
        return None  # so does a misfit of the normals
    kept = posed_by_normals(pf, refitted, outside, oriented)
    scale = float(np.sqrt(max(misfit / dof, model_floor2(pf, c, floor), 1e-300)))
    group_p = 1.0 if localisation is None else lead_grouped_p(
        pf, refitted, oriented, floor, localisation, confidence, outside)
    return Decision(True, share, (kept,), True, None, scale, (), group_p=group_p)
