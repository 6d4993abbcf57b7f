"""Whether a hypothesis fits its contacts within the noise (beyond the paper): the
chi-squared test the decision asks of its lead, and the noise a right hypothesis leaves
(the sensor's, the contact's localisation, the grid's own error and a learned shape's own
error, in quadrature).
"""

import numpy as np
from scipy.special import chdtrc, gammaincinv

from .mesh_fit import mesh_misfit
from .oriented import MIN_NORMAL_NOISE_DEG, contact_turns
from .pose_refinement import POSE_PARAMETERS

GRID_ERROR_PERCENTILE = 95


def fit_test(pf, lead, floor, confidence, outside, oriented, tolerance=0.0):
    """Whether the lead fits within the noise, ``(fits, fit_p, limit)``: its squares on
    the grid within the chi-squared quantile of ``confidence`` without the grid's own
    error, else on its mesh (:func:`~.mesh_fit.mesh_misfit`) within the same; ``fit_p``
    the p-value of the mesh's fit when it fails, or the grid's when that is the better and
    the grid fails within :func:`fit_limit` too (1 when it fits); ``limit`` the grid's
    (its own error granted, :func:`fit_limit`), which the decision's modes are held to.

    A rival never sampled cannot be weighed, but a MAP in a wrong mode leaves residuals
    beyond the noise. A round shape's detail is not granted (a smooth ball fitted a bumpy
    one within it; its turns are searched all round, round_turns). The grid errs most in
    thin parts, where noisy readings lie: where it does not fit within the noise alone,
    the mesh is asked. Its own error is no grant for a shape's: noiseless, a 20 cm fork
    fitted a 25 cm knife's grid within the blade's grid error (1.8 mm) while lying 1.8 mm
    RMS off its mesh, and was taken for the knife."""
    dof = len(pf.contact_positions) - POSE_PARAMETERS
    limit = fit_limit(pf, lead.class_index, floor, confidence, dof)
    if dof <= 0:
        return False, 1.0, limit
    quantile = chi2_quantile(confidence, dof)
    mesh2 = max(floor**2 + pf.models[lead.class_index].shape_error ** 2, 1e-300)
    if lead.misfit <= quantile * mesh2:
        return True, 1.0, limit
    on_mesh = mesh_misfit(pf, lead.class_index, lead.rotation, lead.translation, outside,
                          oriented, tolerance)
    if on_mesh <= quantile * mesh2:
        return True, 1.0, limit
    p_mesh = float(chdtrc(dof, on_mesh / mesh2))
    if lead.misfit <= limit:  # the grid fits only by its own error, which the mesh has not
        return False, p_mesh, limit
    grid2 = limit / max(quantile, 1e-300)
    return False, max(float(chdtrc(dof, lead.misfit / grid2)), p_mesh), limit


def normals_fit(pf, lead, oriented, normal_noise_deg, least_turn_p, weighed_deg=None):
    """Whether the contacts' normals fit the ``lead`` (a :class:`~.decision.Hypothesis`)
    within the noise: their cost at its own normal error (:func:`model_turn_deg`), without
    the worst ``ceil(eps n)`` contacts (``eps = outlier_probability``: a wrong reading's
    normal points anywhere), has a p-value of at least ``least_turn_p`` (:func:`turn_p`;
    0: not tested). ``lead.turned`` is that cost when nothing is left out and it was
    weighed at ``weighed_deg``, its own (the decision weighs every hypothesis at the MAP
    candidate's); else the lead is costed afresh."""
    if least_turn_p <= 0:
        return True
    own = model_turn_deg(pf, lead.class_index, normal_noise_deg)
    count = len(pf.contact_positions)
    drop = int(np.ceil(pf.params.outlier_probability * count))
    if not drop and weighed_deg is not None and own == weighed_deg:
        return turn_p(lead.turned, count) >= least_turn_p
    turns = contact_turns(oriented, [lead.class_index], lead.rotation[None],
                          lead.translation[None], pf.contact_positions, pf.contact_normals,
                          own)[0]
    kept = np.sort(turns)[:count - drop] if drop else turns
    return turn_p(float(kept.sum()), len(kept)) >= least_turn_p


def turn_p(turned, count):
    """The chi-squared p-value of what ``count`` contacts' measured normals cost a
    hypothesis, ``turned`` nats (:func:`~.oriented.turned_cost`): a normal's tilt has two
    degrees of freedom, and ``2 turned`` is their sum of squares in noise stds (1 without
    contacts). A 25 cm spatula fitted a 20 cm fork's 44 touches, tines and handle, within
    0.5 mm while their normals cost it 82 nats (p 2e-6), and was decided; right leads'
    normals on 23 objects cost them 0.01-1.2 nats a contact (p at least 0.09 at a
    decision)."""
    if count <= 0:
        return 1.0
    return float(chdtrc(2 * count, 2 * max(float(turned), 0.0)))


def chi2_quantile(q, dof):
    """``scipy.stats.chi2.ppf(q, dof)`` to the bit, from :mod:`scipy.special` (as
    ``chdtrc`` is its ``sf`` and ``ndtri`` the normal's ``ppf``): importing
    :mod:`scipy.stats` was a third of the engine's import."""
    return 2.0 * gammaincinv(dof / 2, q)


def model_floor2(pf, class_index, floor):
    """The squared noise scale a right hypothesis of a class leaves at least (squared
    scene units): the sensor's ``floor``, the grid's own error and a learned shape's
    ``shape_error``, in quadrature."""
    return (floor**2 + grid_error(pf.bank, class_index) ** 2
            + pf.models[class_index].shape_error ** 2)


def model_turn_deg(pf, class_index, noise_deg):
    """The normal noise a right hypothesis of a class leaves at least, degrees: the
    sensor's (at least ``MIN_NORMAL_NOISE_DEG``) and a learned shape's own normal error
    (``ParticleFilter.own_turn``, a chord), in quadrature. A learned mug's normals lay 17
    degrees (RMS) off its own learning contacts; weighed at 10, its pose upside down cost
    7.5 nats less than its right pose, which the decision then did not hold open."""
    own = pf.own_turn(class_index)
    if not own:
        return float(noise_deg)  # a given mesh's, to the bit
    return float(np.degrees(np.hypot(np.radians(max(float(noise_deg), MIN_NORMAL_NOISE_DEG)),
                                     own)))


def fit_limit(pf, class_index, floor, confidence, dof):
    """The largest sum of squared residuals a right hypothesis of a class passes at
    ``confidence`` (chi-squared with ``dof`` degrees of freedom; 0 without any): its
    :func:`model_floor2`."""
    if dof <= 0:
        return 0.0
    return chi2_quantile(confidence, dof) * max(model_floor2(pf, class_index, floor), 1e-300)


def grid_error(bank, class_index):
    """How far a perfect touch can seem off a class's surface, scene units: the 95th
    percentile of its grid's signed distance at its own feature points, which lie on the
    surface (largest for a thin blade in coarse cells; touches gather where the grid errs
    most, on edges and thin parts, so an RMS understates it)."""
    values, _ = bank.evaluate(np.array([class_index]), bank.points[class_index][None])
    return float(np.percentile(np.abs(values), GRID_ERROR_PERCENTILE))
