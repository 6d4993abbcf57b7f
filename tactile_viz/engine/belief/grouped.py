"""A hypothesis's residuals weighed by place (beyond the paper): a look-alike misfits in
patches, noise does not.

The chi-squared test of :mod:`.fit_test` sums every contact's squared residual. A shape
that misfits by a few percent of the size everywhere adds its misfit to each of ``n``
noisy residuals and needs hundreds of contacts to stand out: a 10 cm mug against its copy
4% larger at 2 mm / 2 degrees left 2.25 mm RMS where the noise leaves 2.0, a p-value of
0.002 at 190 contacts. The sensor's noise is independent from contact to contact; a wrong
shape's misfit is shared by the contacts of one place. Averaged over groups of about
:data:`GROUP_SIZE` contacts that lie near each other and face alike, the noise shrinks by
the group's size and the misfit does not. For a right hypothesis each group's mean
residual ``m_j`` over its ``n_j`` contacts is Gaussian with variance ``s^2 / n_j + b^2``,
so::

    T = sum_j m_j^2 / (s^2 / n_j + b^2)  ~  chi^2(groups)

with ``s`` each residual's noise scale (the sensor's and the contact's localisation, in
quadrature) and ``b`` what the contacts of one place may share without a misfit: the
localisation (a probe that stops a little short stops short everywhere) and a learned
shape's own error (a reconstruction errs by place). The pose fitted to the same contacts
takes up to six of the degrees of freedom, so the test is conservative.
"""

import numpy as np
from scipy.special import chdtrc

from .mesh_fit import mesh_fit
from .pose_refinement import POSE_PARAMETERS
from .stretch import contact_frame, stretch_p

GROUP_SIZE = 10  # contacts a group holds on average: its mean's noise is ~1/3 of one's


def contact_groups(points, normals, weight, size=GROUP_SIZE):
    """Groups of contacts that lie near each other and face alike, ``(n,) int`` labels.

    The seeds are the contacts farthest from each other (farthest-point sampling from the
    first) in position and normal together, ``[x, weight * n]``; each contact joins the
    nearest seed. Opposite faces of a thin wall lie ``2 weight`` apart: their contacts
    fall into different groups, whose residuals a misfit pushes opposite ways.

    Parameters
    ----------
    points : (n, 3) float
        Contacts, any frame, scene units.
    normals : (n, 3) float, unit
        Their measured outward normals, the same frame.
    weight : float
        Scene units per unit of normal difference.
    size : int
        Contacts per group on average (``n // size`` groups, at least one).

    Returns
    -------
    (n,) int
        Group labels ``0 .. groups - 1``; an empty array without contacts.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    features = np.hstack([points, float(weight) * np.asarray(normals, float).reshape(-1, 3)])
    count = max(1, len(points) // max(int(size), 1))
    seeds = [0]
    nearest = np.linalg.norm(features - features[0], axis=1)
    for _ in range(count - 1):
        seeds.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, np.linalg.norm(features - features[seeds[-1]], axis=1))
    distance = np.linalg.norm(features[:, None, :] - features[seeds][None], axis=2)
    return np.argmin(distance, axis=1).astype(np.int64)


def grouped_p(residuals, groups, noise2, shared2=0.0, trim=0.0):
    """The p-value of a hypothesis's group means (see the module): how unlikely a right
    hypothesis leaves them.

    Parameters
    ----------
    residuals : (n,) float
        Signed residuals of the contacts, scene units.
    groups : (n,) int
        :func:`contact_groups`' labels.
    noise2 : float
        Each residual's noise variance ``s^2``, squared scene units.
    shared2 : float
        What a group may share, ``b^2``, squared scene units.
    trim : float
        Share of the contacts, the farthest off, left out (the pose fits' outliers).

    Returns
    -------
    float
        1 with at most ``POSE_PARAMETERS`` contacts or a non-finite residual; 0 for a
        right hypothesis's variance of 0 with a mean off 0.
    """
    residuals = np.asarray(residuals, dtype=float).reshape(-1)
    groups = np.asarray(groups, dtype=np.int64).reshape(-1)
    if len(residuals) <= POSE_PARAMETERS or not np.all(np.isfinite(residuals)):
        return 1.0
    kept = np.ones(len(residuals), bool)
    drop = int(np.ceil(trim * len(residuals)))
    if drop:
        kept[np.argsort(-np.abs(residuals), kind="stable")[:drop]] = False
    counts = np.bincount(groups[kept], minlength=groups.max() + 1)
    sums = np.bincount(groups[kept], weights=residuals[kept], minlength=groups.max() + 1)
    held = counts > 0
    means = sums[held] / counts[held]
    variance = float(noise2) / counts[held] + float(shared2)
    if not np.all(variance > 0):
        return 0.0 if np.any(means != 0) else 1.0
    return float(chdtrc(int(held.sum()), float(np.sum(means**2 / variance))))


def contact_residuals(pf, class_index, local, facing, oriented, exact=False):
    """The filter's contacts' signed residuals to a class, the contacts ``local`` and
    their measured normals ``facing`` in its posed frame (:func:`~.stretch.contact_frame`,
    (n, 3) each), on its grid (the filter's bank) or, ``exact``, on its mesh; where the
    surface found is turned away from the contact's measured normal (a noisy touch
    through a thin wall), the distance to the nearest surface facing its way
    (``oriented``, :class:`~.oriented.OrientedEvaluator`), as the pose fits measure them.
    Returns (n,) float, scene units."""
    if exact:
        mesh = pf.exact_distance(class_index)
        distance, _, face = mesh.query_near(local)
        gradients = mesh.face_normal(face)
    else:
        values, gradients = pf.bank.evaluate(np.array([class_index]), local[None])
        distance, gradients = np.array(values[0], dtype=float), gradients[0]
    turned = np.flatnonzero(np.einsum("ij,ij->i", gradients, facing) < 0)
    if len(turned):
        distance[turned] = oriented(np.full(len(turned), class_index), local[turned],
                                    facing[turned])[0]
    return distance


def grouped_test(pf, class_index, rotation, translation, oriented, floor, localisation=0.0,
                 exact=False, groups=None):
    """The look-alike tests of a class posed at ``rotation``, ``translation`` on the
    filter's contacts (:func:`contact_residuals`, ``exact`` or on the grid): the smaller
    of :func:`grouped_p` and :func:`~.stretch.stretch_p`, each residual's noise ``floor``
    (the sensor's and the localisation's, scene units), a place's share the
    ``localisation`` and the class's own error (``shape_error``, a learned shape's) in
    quadrature; ``groups`` the contacts' :func:`contact_groups` (None: grouped with the
    normals weighed at the class's size unit). A look-alike of another size misfits as a
    stretch of the whole shape more plainly than by place (:mod:`.stretch`)."""
    model = pf.models[class_index]
    if len(pf.contact_positions) <= POSE_PARAMETERS:
        return 1.0
    points, normals = contact_frame(pf, rotation, translation)
    residuals = contact_residuals(pf, class_index, points, normals, oriented, exact)
    if groups is None:
        groups = contact_groups(pf.contact_positions, pf.contact_normals, model.size_unit)
    shared2, trim = localisation**2 + model.shape_error**2, pf.params.outlier_probability
    stretched, _ = stretch_p(residuals, points, normals, floor**2, shared2, trim)
    return min(grouped_p(residuals, groups, floor**2, shared2, trim), stretched)


def lead_grouped_p(pf, lead, oriented, floor, localisation, confidence, outside,
                   tolerance=0.0):
    """:func:`grouped_test` of a decision's ``lead`` (a :class:`~.decision.Hypothesis`),
    asked as the chi-squared test asks (:func:`~.fit_test.fit_test`): on its grid at its
    pose, without the grid's own error; below ``1 - confidence`` there, on its mesh
    (exact distance); below it again, on its mesh refined from the pose
    (:func:`~.mesh_fit.mesh_fit`, with ``outside`` (q, 3) and ``tolerance``), the better
    of the two. The grid errs by place (in thin parts), and a pose refined on it is off
    by that error."""
    index, rotation, translation = int(lead.class_index), lead.rotation, lead.translation
    if len(pf.contact_positions) <= POSE_PARAMETERS:
        return 1.0
    groups = contact_groups(pf.contact_positions, pf.contact_normals,
                            pf.models[index].size_unit)  # the same for every pose asked
    p = grouped_test(pf, index, rotation, translation, oriented, floor, localisation,
                     groups=groups)
    if p >= 1 - confidence:
        return p
    p = grouped_test(pf, index, rotation, translation, oriented, floor, localisation,
                     exact=True, groups=groups)
    if p >= 1 - confidence:
        return p
    _, rotation, translation = mesh_fit(pf, index, rotation, translation, outside, oriented,
                                        tolerance=tolerance)
    return max(p, grouped_test(pf, index, rotation, translation, oriented, floor,
                               localisation, exact=True, groups=groups))
