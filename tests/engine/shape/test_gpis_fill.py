"""The solid behind the contacts and the filled voids of a GPIS estimate (beyond the paper):
a prior with a cavity where the object is solid."""

import functools

import numpy as np
import pytest

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.shape.gpis_prior import contact_balls, filled_prior
from tactile_viz.engine.shape.level_set import filled_voids


def _sphere_contacts(count, radius=1.0, rng=0):
    directions = np.random.default_rng(rng).normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return radius * directions, directions


def _empty(points, far=5.0):  # a prior with nothing in it: everything outside
    points = np.atleast_2d(points)
    return np.full(len(points), far), np.tile([0.0, 0.0, 1.0], (len(points), 1))


@pytest.mark.parametrize("radius", [1e-3, 1.0, 1e3])
def test_the_balls_behind_a_spheres_contacts_fill_it_at_every_scale(radius):
    contacts, normals = _sphere_contacts(60, radius)
    fill = contact_balls(contacts, normals, np.zeros((0, 3)), 10 * radius, 1e-6 * radius)
    np.testing.assert_allclose(fill.radii, radius, rtol=1e-4)  # no contact inside any ball
    empty = functools.partial(_empty, far=5 * radius)
    values, gradients = filled_prior(empty, fill)(np.array([[0.0, 0.0, 0.0],
                                                            [0.0, 0.0, 0.5 * radius]]))
    assert (values < 0).all()  # the centre and a point inside are solid
    np.testing.assert_allclose(np.linalg.norm(gradients, axis=1), 1.0)
    outside = filled_prior(empty, fill)(np.array([[0.0, 0.0, 2.0 * radius]]))[0]
    np.testing.assert_allclose(outside, radius, rtol=1e-4)  # the union's distance, outside


def test_a_free_point_or_a_contact_bounds_its_ball():
    contacts = np.array([[0.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0]])
    free = np.array([[0.0, 0.0, -1.0]])  # one unit behind the tangent plane, on the axis
    fill = contact_balls(contacts, normals, free, 10.0)
    np.testing.assert_allclose(fill.radii, 0.5)  # |p - c|^2 / (2 d) = 1 / 2
    beside = contact_balls(np.vstack([contacts, [[1.0, 0.0, -0.1]]]),
                           np.vstack([normals, normals]), np.zeros((0, 3)), 10.0)
    assert beside.radii[0] == pytest.approx(1.01 / 0.2)
    within_noise = contact_balls(np.vstack([contacts, [[1.0, 0.0, -0.1]]]),
                                 np.vstack([normals, normals]), np.zeros((0, 3)), 10.0, 0.2)
    np.testing.assert_allclose(within_noise.radii, 10.0)  # 0.1 deep is within the noise


def test_no_contact_or_no_radius_adds_nothing():
    assert contact_balls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), 1.0) is None
    contacts, normals = _sphere_contacts(5)
    assert contact_balls(contacts, normals, np.zeros((0, 3)), 0.0) is None
    assert filled_prior(_empty, None) is _empty


def test_an_enclosed_void_is_filled_and_an_open_cavity_kept():
    axes = np.linspace(-2, 2, 41)
    x, y, z = np.meshgrid(axes, axes, axes, indexing="ij")
    r = np.sqrt(x**2 + y**2 + z**2)
    shell = np.maximum(r - 1.5, 0.8 - r)  # a hollow ball: a void inside
    filled = filled_voids(shell)
    assert (filled[r < 0.7] < 0).all() and (filled[r > 1.6] > 0).all()
    drilled = np.maximum(shell, np.minimum(0.4 - np.hypot(y, z), x))  # a hole out along +x
    kept = filled_voids(drilled)
    np.testing.assert_array_equal(kept, drilled)  # open to the outside: nothing filled
    assert (kept[r < 0.7] > 0).all()
    np.testing.assert_array_equal(filled_voids(shell + 10), shell + 10)  # no inside at all


def test_the_presets_keep_the_prior_as_it_is():
    for name in ("paper", "recommended"):  # both measured worse on the protocol
        params = session_preset(name)
        assert params.gpis_fill_radius == 0 and not params.gpis_fill_voids


def test_held_out_errors_are_the_fits_without_each_contact():
    from tactile_viz.engine.shape.gpis import ThinPlateKernel, fit_gpis, held_out_errors

    contacts, normals = _sphere_contacts(25, 1.0, rng=3)
    contacts = contacts * np.array([1.0, 1.0, 1.3])  # an ellipsoid the sphere prior misfits

    def ball(points):
        points = np.atleast_2d(points)
        length = np.linalg.norm(points, axis=1)
        return length - 1.0, points / length[:, None]

    kernel = ThinPlateKernel(4.0)
    fit = fit_gpis(contacts, normals, ball, kernel, scale=0.5, newton=False)
    errors = held_out_errors(fit)
    for j in (0, 7, 19):
        rest = np.delete(np.arange(len(contacts)), j)
        without = fit_gpis(contacts[rest], normals[rest], ball, kernel, scale=0.5, newton=False)
        np.testing.assert_allclose(errors[j], abs(without.mean_value(contacts[j:j + 1])[0]),
                                   rtol=1e-5, atol=1e-9)
    assert errors.max() > 1e-3  # the ellipsoid's ends are not where the others predict
    with_misses = fit_gpis(contacts, normals, ball, kernel, scale=0.5, newton=False,
                           noncontacts=np.array([[0.0, 0.0, 0.5]]))
    assert held_out_errors(with_misses).shape == (len(contacts),)  # a miss has no block
