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
``count`` contacts does. Its lead, if it misfits there, is refitted alone on every
contact and all the free space and tested there: the test of all the contacts decides,
and a lead that passes it (or fits on the spread) is searched again on all, as without a
spread. The spread only finds the lead: fewer contacts hold a pose less tightly, and their
test is stricter for a misfit held by a few of them (a learned cup's rim met again).
"""

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
    and normals); its bank, models, particles and non-contacts are the filter's own. The
    filter itself is not changed."""
    view = object.__new__(type(pf))
    view.__dict__.update(pf.__dict__)
    view.contact_positions = pf.contact_positions[index]
    view.contact_normals = pf.contact_normals[index]
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
