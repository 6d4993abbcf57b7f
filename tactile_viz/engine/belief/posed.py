"""The decided pose refitted with the contacts' normals beside their positions (beyond
the paper; ``decision_normals``).

A small object's turn is pinned by its flat faces' normals long before their positions pin
it (a 2 cm block under 2 mm noise); :func:`~.pose_refinement.refine_poses` weighs each
normal by how flat the surface is about its contact. Only the lead is refitted so: the
hypotheses are weighed and tested on positions (:mod:`.decision`).
"""

from dataclasses import replace

import numpy as np

from .pose_refinement import refine_poses
from .support import table_support


def posed_by_normals(pf, lead, outside, oriented, tolerance=0.0):
    """The lead refitted with its contacts' normals beside their positions (the
    evaluator's ``fit_noise``; the lead itself without it), its misfit the positions' there.

    The hypotheses are weighed and tested on positions alone: a mug's contacts at 2 mm
    lay 2.5 mm RMS off its grid at its true pose on one trajectory, and a joint fit's
    slightly larger misfit of the positions failed the fit test for 200 touches. Only the
    pose that is reported, and whose uncertainty decides, is the joint fit's."""
    if oriented.fit_noise is None:
        return lead
    try:
        rotations, translations, misfit = refine_poses(
            pf.bank.evaluate, np.array([lead.class_index]), lead.rotation[None],
            lead.translation[None], pf.contact_positions, outside,
            pf.params.refine_iterations, trim=pf.params.outlier_probability,
            normals=pf.contact_normals, oriented=oriented, clearance=pf.scene.tip_radius,
            support=table_support(pf), below=pf.bank.below, tolerance=tolerance,
            normal_noise=oriented.fit_noise)
    except np.linalg.LinAlgError:
        return lead
    return replace(lead, rotation=rotations[0], translation=translations[0],
                   misfit=float(misfit[0]))
