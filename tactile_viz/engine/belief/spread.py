"""A decision searched on a spread of the contacts while its MAP misfits (beyond the
paper).

A full decision search refines some 25 hypotheses on every contact, and on their meshes
the plausible ones again: its time grows with the contacts and the missed probes' free
space (1.2 s with 225 contacts and 3,700 free-space points on 2 cores). An object the
filter keeps judging known while no fit holds (a novel look-alike, judged novel by its
misfit) was searched afresh every few touches for hundreds of touches. While the MAP
keeps misfitting, a search first fits a spread of ``count`` of the contacts, each the
farthest from those before it, and ``FREE_PER_CONTACT`` times as many points of the free
space (every k-th: each path keeps a share of its points), and costs what one with
``count`` contacts does. Its lead's squares there are a lower bound of theirs on every
observation (the spread's are the least at its own best pose, a free-space point only
adds cost, and as many contacts are left out as all would leave), so squares beyond the
test's limit for every contact's degrees of freedom fail it on all too; a lead that
passes that limit on the spread is searched again on all (a spread holds a pose less
tightly, and the test of fewer contacts is stricter for a misfit held by a few of them).
"""

from dataclasses import replace

import numpy as np

from .features import farthest_point_order

# Free-space points a search on a spread of ``count`` contacts weighs, per contact: the
# probes' paths are sampled densely (a cup at 2 mm had 3,700 points by touch 200, and its
# mesh fits asked 1,250 of them each at their start).
FREE_PER_CONTACT = 8


def spread_contacts(positions, count):
    """Indices of at most ``count`` of ``positions (m, 3)``, chosen farthest first from
    the first contact, in the contacts' order: ``(min(count, m),)`` int (all when
    ``count`` is 0 or at least ``m``)."""
    if count <= 0 or len(positions) <= count:
        return np.arange(len(positions))
    return np.sort(farthest_point_order(np.asarray(positions, float), count))


def seen_through(pf, index):
    """A view of a particle filter whose contacts are those at ``index`` (their positions
    and normals); its bank, models, particles and non-contacts are the filter's own, and
    its fits leave out as many contacts as the filter's would (``outlier_probability``:
    a subset's squares less its ``D`` largest are at most the whole set's less its ``D``
    largest). None when that is half of them or more. The filter is not changed."""
    index = np.asarray(index)
    drop = int(np.ceil(pf.params.outlier_probability * len(pf.contact_positions)))
    if drop and 2 * drop >= len(index):
        return None
    view = object.__new__(type(pf))
    view.__dict__.update(pf.__dict__)
    view.contact_positions = pf.contact_positions[index]
    view.contact_normals = pf.contact_normals[index]
    if drop:  # refine_poses leaves out ceil(share * contacts)
        view.params = replace(pf.params, outlier_probability=(drop - 0.5) / len(index))
    return view


def thinned(points, count):
    """At most ``count`` of ``points (q, 3)``, every k-th in their order (all when
    ``count`` is 0 or at least ``q``; None stays None)."""
    if points is None:
        return None
    points = np.reshape(points, (-1, 3))
    if count <= 0 or len(points) <= count:
        return points
    return points[::int(np.ceil(len(points) / count))]
