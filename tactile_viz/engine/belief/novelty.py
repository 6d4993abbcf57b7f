"""The paper's novelty test on the contacts, as a plain function (paper, Section III-D:
known iff the MAP's evidence reaches ``known_fraction`` of its maximum per contact)."""

import numpy as np

from .likelihood import log_contact_likelihood, log_normaliser

NOISE_OFFSETS = np.array([0.0, -1.0, 1.0, -2.0, 2.0])  # position-noise stds along a normal
# A noise offset counts where the nearest face's normal turns by more than 60 degrees
# within it: a fold of the distance field (a thin wall's middle, the inside of a sharp
# edge), not a curvature, which turns the normal by a few degrees over the offset.
FOLD_COSINE = 0.5


def contact_test(exact, local, normals, params, noise=0.0, turn=0.0):
    """``(the MAP's log-likelihood of the contacts, its threshold)``, each contact at its
    best offset within the position ``noise`` where that offset crosses a fold of the
    distance field (a thin wall's middle), without the worst ``ceil(eps n)`` contacts
    (``eps = outlier_probability``: one wrong contact cannot make a known object novel),
    the threshold lowered by what a normal ``turn`` costs each contact.

    Distances and normals are the MAP mesh's own (exact distance, nearest face's normal),
    not its grid's: a tine or a rod one or two voxels across has grid normals that point
    anywhere a few millimetres inside it, where noisy readings lie (a fork at 2 mm flipped
    between known and novel). A learned MAP's ``turn`` is its own normal error: the most a
    contact on a reconstruction can reach is what its learning contacts reach, not a
    perfect fit.

    Parameters
    ----------
    exact : ExactDistance
        The MAP's mesh, object frame.
    local, normals : (n, 3) float, object frame
        Contact positions (scene units) and measured unit normals.
    params : FilterParams
        ``sigma_d``, ``sigma_n``, ``outlier_probability`` and ``known_fraction``.
    noise : float, scene units
        The position noise granted (the sensor's, a learned shape's own error).
    turn : float
        The normal error granted beyond ``sigma_n`` (a length of the normals' difference).

    Returns
    -------
    total, threshold : float, nats
    """
    offsets = noise * NOISE_OFFSETS[1:] if noise else ()
    # One look-up for the readings and their offsets; the likelihood needs no sign.
    distance, faces = exact.nearest_face(
        np.vstack([local, *(local + offset * normals for offset in offsets)]))
    distance, faces = distance[:len(local)], faces.reshape(-1, len(local))
    own = exact.face_normal(faces[0])
    terms = log_contact_likelihood(distance, own, normals, params.sigma_d, params.sigma_n,
                                   params.outlier_probability)
    for offset, at_offset in zip(offsets, faces[1:]):
        # The normal a reading ``offset`` off along its normal would meet, where the offset
        # crosses a fold of the distance field (FOLD_COSINE) and nowhere else: a
        # best-of-five normal elsewhere grants every contact on a near twin's curves slack
        # that no noise explains (sofa_2 passed as sofa_1). The distance stays the
        # reading's own, so a shape that merely lies near the contacts gains nothing; the
        # offset costs as a distance does, with the same sigma_d.
        shifted_normal = exact.face_normal(at_offset)
        fold = np.einsum("ij,ij->i", shifted_normal, own) < FOLD_COSINE
        shifted = log_contact_likelihood(distance, shifted_normal, normals, params.sigma_d,
                                         params.sigma_n, params.outlier_probability)
        prior = -0.5 * (offset / params.sigma_d) ** 2
        terms = np.where(fold, np.maximum(terms, shifted + prior), terms)
    total, kept = trimmed_sum(terms, params.outlier_probability)
    return total, kept * (np.log(params.known_fraction)
                          - log_normaliser(params.sigma_d, params.sigma_n)
                          - 0.5 * (turn / params.sigma_n) ** 2)


def trimmed_sum(terms, fraction):
    """The sum of ``terms`` without their ``ceil(fraction * n)`` smallest, and how many
    remain."""
    drop = int(np.ceil(fraction * len(terms)))
    kept = np.sort(terms)[drop:]
    return float(kept.sum()), len(kept)
