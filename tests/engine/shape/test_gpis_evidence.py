"""The object-agnostic GPIS prior (an ellipsoid fitted to the contacts) and the evidence
that chooses between it and the MAP shape (beyond the paper)."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.session import Session, make_truth, session_preset
from tactile_viz.engine.shape.gpis import ThinPlateKernel, fit_gpis
from tactile_viz.engine.shape.gpis_evidence import (
    Superquadric,
    box_faces,
    contact_evidence,
    fit_superquadrics,
)

from ..conftest import surface_at


def _ellipsoid(points, normals, min_radius):
    shapes = fit_superquadrics(points, normals, min_radius, roundness=(1.0,))
    return shapes[0] if shapes else None


def _surface_samples(mesh, count, seed=1):
    points, faces = trimesh.sample.sample_surface(mesh, count, seed=seed)
    return points, mesh.face_normals[faces]


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_spheres_contacts_give_the_sphere_at_every_scale(scale):
    mesh = trimesh.creation.icosphere(4, radius=2.0 * scale)
    mesh.apply_translation(np.array([1.0, -2.0, 3.0]) * scale)
    points, normals = _surface_samples(mesh, 80)
    shape = _ellipsoid(points, normals, 0.01 * scale)
    np.testing.assert_allclose(shape.centre, np.array([1.0, -2.0, 3.0]) * scale,
                               atol=0.05 * scale)
    np.testing.assert_allclose(shape.radii, 2.0 * scale, rtol=0.03)
    values, gradients = shape(points)
    assert np.abs(values).max() < 0.05 * scale
    np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0)
    assert (np.einsum("ij,ij->i", gradients, normals) > 0.95).all()
    inside, _ = shape(np.vstack([shape.centre, shape.centre + 0.5 * scale]))
    assert (inside < 0).all() and np.isfinite(inside).all()  # the centre too


def test_a_long_box_gives_its_axes_and_few_contacts_give_none():
    mesh = trimesh.creation.box((1.0, 2.0, 6.0))
    points, normals = _surface_samples(mesh, 120)
    shape = _ellipsoid(points, normals, 0.05)
    order = np.argsort(shape.radii)
    assert np.abs(shape.axes[:, order[-1]] @ [0.0, 0.0, 1.0]) > 0.99  # the long side
    assert shape.radii[order[0]] < shape.radii[order[1]] < shape.radii[order[2]]
    assert (shape.radii <= 2 * np.array([1.0, 2.0, 6.0])[order.argsort()] + 0.05).all()
    np.testing.assert_allclose(shape.axes.T @ shape.axes, np.eye(3), atol=1e-9)
    assert np.linalg.det(shape.axes) == pytest.approx(1.0)
    assert _ellipsoid(points[:3], normals[:3], 0.05) is None
    flat = _ellipsoid(points[normals[:, 2] > 0.9], normals[normals[:, 2] > 0.9], 0.05)
    assert np.isfinite(flat.radii).all() and (flat.radii >= 0.05).all()  # one face only


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_spot_touched_again_and_again_gives_one_normal_line(scale):
    # A thin plate touched all over, then at one corner again and again with a tilted
    # normal (a fork's tip at each given-up target): the centre is the plate's.
    plate = trimesh.creation.box(np.array([0.2, 0.04, 2.0]) * scale)
    points, normals = _surface_samples(plate, 60)
    tip, tilted = np.array([0.0, 0.02, 1.0]) * scale, np.array([0.0, 0.6, 0.8])
    once = fit_superquadrics(np.vstack([points, tip]), np.vstack([normals, tilted]),
                             0.05 * scale)
    again = fit_superquadrics(np.vstack([points, np.repeat(tip[None], 40, axis=0)]),
                              np.vstack([normals, np.repeat(tilted[None], 40, axis=0)]),
                              0.05 * scale)
    for first, second in zip(once, again, strict=True):
        np.testing.assert_allclose(second.centre, first.centre, atol=1e-9 * scale)
        assert abs(second.centre[1]) < 0.05 * scale  # within the least radius of the plate


def test_a_boxs_contacts_fit_the_sharp_superquadric_best():
    mesh = trimesh.creation.box((2.0, 3.0, 4.0))
    points, normals = _surface_samples(mesh, 150)
    shapes = fit_superquadrics(points, normals, 0.05)
    assert [shape.roundness for shape in shapes] == [1.0, 0.5, 0.2]
    misfit = [np.abs(shape(points)[0]).mean() for shape in shapes]
    assert misfit[2] < misfit[1] < misfit[0]
    np.testing.assert_allclose(np.sort(shapes[2].radii), [1.0, 1.5, 2.0], rtol=0.1)
    corner, _ = shapes[2](np.array([[0.9, 1.35, 1.8]]))
    assert corner[0] < 0  # inside, where the ellipsoid leaves the corner out
    assert shapes[0](np.array([[0.9, 1.35, 1.8]]))[0][0] > 0


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_noisy_cube_gives_a_box_where_its_faces_contacts_lie(scale):
    # A 2-unit cube touched with noise a tenth of its size (a 2 cm die at 2 mm): the least
    # squares of the radii's powers are pulled outward; the faces' medians are not.
    rng = np.random.default_rng(4)
    mesh = trimesh.creation.box((2.0 * scale,) * 3)
    points, normals = _surface_samples(mesh, 150)
    points = points + rng.normal(0.0, 0.2 * scale, size=points.shape)
    shapes = fit_superquadrics(points, normals, 0.05 * scale, faces=True)
    np.testing.assert_allclose(shapes[2].radii, scale, rtol=0.05)
    np.testing.assert_allclose(shapes[2].centre, 0.0, atol=0.05 * scale)
    assert shapes[0].radii.min() > 1.1 * scale  # the ellipsoid keeps its least squares
    least_squares = fit_superquadrics(points, normals, 0.05 * scale)[2]
    assert least_squares.radii.min() > 1.1 * scale  # without faces, as a noiseless sensor
    # Inside a cup (normals toward its axis, as a box's would not be) no face is moved.
    inner = -normals[np.abs(normals[:, 2]) < 0.5]
    inside = box_faces(shapes[2], 0.5 * points[np.abs(normals[:, 2]) < 0.5], inner,
                       0.05 * scale, 10 * scale)
    np.testing.assert_array_equal(inside.radii, shapes[2].radii)
    np.testing.assert_array_equal(inside.centre, shapes[2].centre)


def _ball(points, radius=1.0):
    points = np.atleast_2d(points)
    length = np.linalg.norm(points, axis=1)
    return length - radius, points / length[:, None]


def test_the_evidence_is_the_fits_own_term_and_prefers_the_prior_that_fits():
    mesh = trimesh.creation.icosphere(3, radius=1.0)
    points, normals = _surface_samples(mesh, 40)
    fit = fit_gpis(points, normals, _ball, ThinPlateKernel(4.0), scale=0.5, newton=False)
    own = contact_evidence(fit, _ball, points, normals)
    np.testing.assert_allclose(own, -0.5 * fit.alpha[fit.kept] @ (
        np.column_stack([np.zeros(len(points)), normals])
        - np.column_stack(_ball(points))).ravel()[fit.kept], rtol=1e-8)
    shifted = Superquadric(np.array([0.3, 0.0, 0.0]), np.eye(3), np.ones(3))
    fitted = _ellipsoid(points, normals, 0.01)
    assert contact_evidence(fit, fitted, points, normals) > contact_evidence(
        fit, shifted, points, normals)
    with_misses = fit_gpis(points, normals, _ball, ThinPlateKernel(4.0), scale=0.5,
                           newton=False, noncontacts=np.array([[0.0, 0.0, 0.5]]))
    assert contact_evidence(with_misses, _ball, points, normals) == pytest.approx(own)
    assert contact_evidence(fit, _ball, np.zeros((0, 3)), np.zeros((0, 3))) == 0.0


@pytest.mark.slow
def test_a_ball_against_unlike_priors_takes_the_ellipsoid_and_learns_what_it_reports(
        bundled, sphere_model):
    library = PriorLibrary(bundled[name] for name in ("mug_1", "guitar_1", "office_chair"))
    params = session_preset("recommended", max_steps_novel=40, final_candidates=0)
    assert params.gpis_agnostic and not session_preset("paper").gpis_agnostic
    session = Session.simulated(make_truth(sphere_model, rng=2), library, "gpis-dhd", params,
                                seed=2)
    session.run()
    novel = [s for s in session.snapshots if s.gpis_faces is not None]
    assert novel and all(s.novel for s in novel)
    held = [s for s in novel if s.gpis_shape is not None]
    assert held, "a sphere's contacts favour the ellipsoid over every other prior"
    assert np.ptp(held[-1].gpis_shape.radii) < 0.5  # the sphere's, radius 3
    assert held[-1].record()["gpis_prior"] in ("ellipsoid", "rounded box", "box")
    assert {s.record()["gpis_prior"] for s in novel if s.gpis_shape is None} <= set(
        library.names)
    # Refitting from the snapshot (its ellipsoid prior included) gives the step's surface.
    last = held[-1]
    vertices, faces = surface_at(session, last, last.gpis_resolution)
    np.testing.assert_allclose(vertices, last.gpis_vertices, atol=1e-9)
    np.testing.assert_array_equal(faces, last.gpis_faces)
    off = Session.simulated(make_truth(sphere_model, rng=2), library, "gpis-dhd",
                  session_preset("recommended", max_steps_novel=5, gpis_agnostic=False), seed=2)
    off.run()
    assert all(s.gpis_shape is None for s in off.snapshots)
