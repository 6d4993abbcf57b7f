"""Learning a shape: a novel object's reconstruction as a new prior (paper, shape transfer
learning)."""

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..errors import SessionError
from ..shape.gpis import ThinPlateKernel, held_out_errors
from ..shape.gpis_variance import lattice_low
from ..shape.level_set import zero_level_surface
from ..shape.objects import ObjectModel
from ..shape.sdf import ExactDistance
from .final import own_box

SPREAD_POINTS = 2000  # surface vertices a learned shape's spread is measured at


def learned_model(estimator, snapshot, name, resolution, library):
    """The reconstructed surface of a novel snapshot as a new :class:`ObjectModel`.

    The snapshot's GPIS posterior mean (its contacts, MAP prior and kernel scale) is
    extracted at ``resolution`` (``params.learned_resolution`` as a session asks), finer
    where the contacts measure thin walls (:meth:`~.estimate.Estimator.wall_resolution`)
    and in its own box where it is small in the prior's (:func:`~.final.own_box`);
    a stopped session's last surface, asked at ``params.final_resolution``, is learned as
    reported (the final surface, finer where walls are thin); the largest connected
    piece of the zero level set is kept, and the model is checked and normalised like any
    loaded mesh. Its own errors are its contacts' (:func:`own_errors`): the fit's
    held-out errors there (:func:`~..shape.gpis.held_out_errors`, how far a touch the fit
    has not seen may miss it) with the mesh's own distance to them beyond the sensor's
    noise (``position_noise``), and its normals'.

    Parameters
    ----------
    estimator : Estimator
        Built with the lengths of the snapshot's MAP prior.
    snapshot : Snapshot
        Novel, with a surface.
    name : str
    resolution : int
    library : PriorLibrary
        The MAP prior's parameters are the learned model's.
    """
    if snapshot is None or snapshot.gpis_faces is None or len(snapshot.gpis_faces) == 0:
        raise SessionError("no reconstructed surface to learn from: the object was not "
                           "judged novel in this step")
    if snapshot.terminated and resolution == estimator.p.final_resolution:
        resolution = snapshot.gpis_resolution  # the last surface, learned as reported
    else:
        low, high, _ = estimator.gpis_box(snapshot.map_vertices, snapshot.contacts,
                                          snapshot.gpis_shape)
        at = len(snapshot.gpis_vertices) * (resolution / snapshot.gpis_resolution) ** 2
        resolution = estimator.wall_resolution((low, high), resolution, snapshot.contacts,
                                               snapshot.normals, vertices=at)
    fit, box = snapshot_fit(estimator, snapshot, resolution)
    vertices, faces = snapshot.gpis_vertices, snapshot.gpis_faces
    if resolution != snapshot.gpis_resolution:
        vertices, faces = level_set(fit, box, resolution, estimator.p.gpis_fill_voids)
        tighter = (None if box[2] is not None or estimator.p.final_wall_cells <= 0
                   else own_box(vertices, box[:2], resolution))
        if tighter is not None:  # a small object's surface in its prior's box
            vertices, faces = level_set(fit, (*tighter, None), resolution,
                                        estimator.p.gpis_fill_voids)
    return learned_model_from_surface(
        vertices, faces, name, params=library[snapshot.map_class].params
        if snapshot.map_class in library else None, contacts=snapshot.contacts,
        normals=snapshot.normals, reach=estimator.p.eps, held_out=held_out_errors(fit),
        noise=estimator.filter.params.position_noise, surface=surface_spread(fit, vertices))


def surface_spread(fit, vertices, count=SPREAD_POINTS):
    """The RMS posterior standard deviation of a GPIS fit's value on a surface (scene
    units): its variance's mean at up to ``count`` of the surface's ``vertices`` (n, 3),
    evenly strided. How far a touch anywhere on a learned surface may miss it, where its
    held-out errors say so only at its contacts: a learned 20 cm fork's were 0.6 mm RMS,
    its surface's spread 0.85 mm, and met again its touches lay 0.83-1.0 mm off it (a
    misfit by the decision's test at 1.3e-5 to 3e-9: never decided)."""
    vertices = np.reshape(vertices, (-1, 3))
    if len(vertices) == 0:
        return 0.0
    step = max(len(vertices) // count, 1)
    return float(np.sqrt(np.mean(fit.variance(vertices[::step]))))


def snapshot_fit(estimator, snapshot, resolution):
    """The snapshot's GPIS fit again, with the snapshot's MAP prior (a stopped session may
    report the surface of a recent prior instead, ``final_candidates``; it is learned as
    reported at ``final_resolution``, the default ``learned_resolution``), and the box
    ``(low, high, spacing)`` of its surface at ``resolution``. Changes no state."""
    filter_ = estimator.filter
    model = filter_.models[filter_.class_names.index(snapshot.map_class)]
    prior = estimator.gpis_prior(model, snapshot.map_rotation, snapshot.map_translation,
                                 snapshot.contacts, snapshot.noncontacts, snapshot.free_space,
                                 snapshot.normals, shape=snapshot.gpis_shape)
    low, high, kernel = estimator.gpis_box(snapshot.map_vertices, snapshot.contacts,
                                           snapshot.gpis_shape)
    if isinstance(kernel, ThinPlateKernel) and snapshot.gpis_radius is not None:
        kernel = ThinPlateKernel(snapshot.gpis_radius)  # the step's, maybe kept
    spacing = snapshot.gpis_spacing if resolution == snapshot.gpis_resolution else None
    if spacing is not None:
        low = lattice_low(low, spacing)
    fit = estimator.refit(kernel, snapshot.contacts, snapshot.normals,
                          estimator.noncontact_points(snapshot.noncontacts,
                                                      snapshot.free_space),
                          prior, snapshot.gpis_scale)
    fit = estimator.cut_estimate(fit, snapshot.contacts, snapshot.normals,
                                 snapshot.noncontacts, snapshot.free_space)
    return fit, (low, high, spacing)


def surface_at(estimator, snapshot, resolution):
    """The snapshot's GPIS zero level set on a grid of ``resolution`` cells."""
    return level_set(*snapshot_fit(estimator, snapshot, resolution), resolution,
                     estimator.p.gpis_fill_voids)


def level_set(fit, box, resolution, fill_voids=False):
    """The zero level set of a snapshot's fit (:func:`snapshot_fit`) on a grid of
    ``resolution`` cells (``box``: its low and high corners and cell)."""
    low, high, spacing = box
    vertices, faces = zero_level_surface(fit, (low, high), resolution, spacing=spacing,
                                         fill_voids=fill_voids)
    if len(faces) == 0:
        raise SessionError("the reconstruction has no surface at the learned resolution")
    return vertices, faces


def learned_model_from_surface(vertices, faces, name, params=None, contacts=None, reach=0.0,
                               normals=None, held_out=(), noise=0.0, surface=0.0):
    """An :class:`ObjectModel` from a reconstructed surface: its largest connected piece and
    every other piece with a vertex within ``reach`` of one of ``contacts`` (world frame,
    scene units), with its :func:`own_errors` at the contacts (given their ``normals``).

    A GPIS parts a thin leg from a chair's seat, and the leg's piece carries its contacts;
    a piece no contact supports is a blob nothing touched. (The largest piece alone made a
    learned chair of TWD 0.594 from a surface of 0.375.)

    The surface keeps its measured size: it is in the same world units as the object it was
    learned from, whereas scaling its (pose-dependent) bounding box to the bundled objects'
    size would change its size and spoil every later match.
    """
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    pieces = mesh.split(only_watertight=False)
    contacts = np.reshape([] if contacts is None else contacts, (-1, 3))
    if len(pieces):
        largest = max(range(len(pieces)), key=lambda index: abs(pieces[index].area))
        tree = cKDTree(contacts) if len(contacts) else None
        kept = [piece for index, piece in enumerate(pieces) if index == largest or (
            tree is not None and tree.query(piece.vertices)[0].min() <= reach)]
        mesh = trimesh.util.concatenate(kept)
    shape_error, normal_error = own_errors(mesh.vertices, mesh.faces, contacts, normals,
                                           held_out, noise, surface)
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, name, params=params,
                                   longest_side=None, learned=True, shape_error=shape_error,
                                   normal_error=normal_error)


def own_errors(vertices, faces, contacts, normals=None, held_out=(), noise=0.0, surface=0.0):
    """How far a touch may lie off a learned surface, ``(shape_error, normal_error)``.

    ``shape_error`` (scene units): the RMS of the fit's ``held_out`` errors, of the
    contacts' distances to the surface beyond the sensor's ``noise`` and the fit's
    ``surface`` spread (:func:`surface_spread`), in quadrature (the
    grid a surface is extracted on blurs a fork's tines into blobs a millimetre off
    contacts its fit passes through: met again, touches missed it by 1.4 mm RMS where
    the held-out errors alone granted 0.6). ``normal_error``: the RMS length of the
    difference between each contact's unit normal and the outward normal of the
    surface's nearest face (0 to 2; 0 without ``normals``).

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    contacts : (k, 3) float, the surface's frame
    normals : (k, 3) float, unit, optional
    held_out : (j,) float, scene units
    noise : float, scene units
        The sensor's position noise (std).
    surface : float, scene units
        The fit's RMS posterior standard deviation on the surface.
    """
    contacts = np.reshape(contacts, (-1, 3))
    held_out = np.asarray(held_out, dtype=float)
    squares = (float(np.mean(held_out**2)) if len(held_out) else 0.0) + surface**2
    if len(contacts) == 0 or len(faces) == 0:
        return float(np.sqrt(squares)), 0.0
    exact = ExactDistance(vertices, faces)
    distance, nearest = exact.nearest_face(contacts)
    squares += max(float(np.mean(distance**2)) - noise**2, 0.0)
    if normals is None:
        return float(np.sqrt(squares)), 0.0
    difference = exact.face_normal(nearest) - np.reshape(normals, (-1, 3))
    return float(np.sqrt(squares)), float(np.sqrt(np.mean(np.sum(difference**2, axis=1))))
