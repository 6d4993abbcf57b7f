import numpy as np
import pytest

from tactile_viz.engine.shape.gpis_prior import (
    DISK_NEIGHBOURS,
    carved_prior,
    disk_distances,
    disk_radii,
    free_space_cut,
)


def _reference(points, contacts, normals, disk):
    """Every point to every contact's disc, by the disc's nearest point."""
    best = np.full(len(points), np.inf)
    for contact, normal in zip(contacts, normals):
        offset = points - contact
        along = offset @ normal
        across = np.linalg.norm(offset - along[:, None] * normal, axis=1)
        best = np.minimum(best, np.hypot(along, np.maximum(across - disk, 0.0)))
    return best


@pytest.mark.parametrize("disk", [0.0, 0.05, 0.4, 3.0])
def test_disk_distances_are_the_distances_to_the_nearest_disc(disk):
    rng = np.random.default_rng(3)
    contacts = rng.uniform(-1, 1, size=(DISK_NEIGHBOURS, 3))
    normals = rng.normal(size=contacts.shape)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points = rng.uniform(-2, 2, size=(500, 3))
    found = disk_distances(points, contacts, normals, disk)
    np.testing.assert_allclose(found, _reference(points, contacts, normals, disk), atol=1e-12)
    # A disc lies no farther than its centre; a zero disc is its centre.
    nearest = np.min(np.linalg.norm(points[:, None] - contacts[None], axis=2), axis=1)
    assert np.all(found <= nearest + 1e-12)
    if disk == 0.0:
        np.testing.assert_allclose(found, nearest, atol=1e-12)


def test_disk_distances_beyond_the_reach_are_infinite():
    contacts, normals = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    points = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 5.0]])
    found = disk_distances(points, contacts, normals, 0.1, reach=1.0)
    np.testing.assert_allclose(found[0], 0.5)
    assert found[1] == np.inf


def _wall(thickness=0.06, spacing=0.6, gap=0.25):
    """A plate z in [-thickness, 0] (its signed distance, exact across it), contacts on
    its top face every ``spacing`` with their normals +z, and free points ``gap`` above
    the face midway between contacts, where a probe passed."""
    def plate(points):
        z = points[:, 2]
        values = np.maximum(z, -thickness - z)
        gradients = np.zeros_like(points)
        gradients[:, 2] = np.where(z > -thickness / 2, 1.0, -1.0)
        return values, gradients

    grid = np.arange(-3, 4) * spacing
    contacts = np.array([[x, y, 0.0] for x in grid for y in grid])
    normals = np.tile([0.0, 0.0, 1.0], (len(contacts), 1))
    middle = grid[:-1] + spacing / 2
    free = np.array([[x, y, gap] for x in middle for y in middle])
    inside_wall = free - [0.0, 0.0, gap + thickness / 2]
    return plate, contacts, normals, free, inside_wall


def test_a_thin_wall_between_contacts_survives_the_carve_with_discs():
    # A ball about a free point 0.25 above a thin plate, bounded only by the distance to
    # the nearest contact (0.49 away), cuts through the plate between the contacts; bounded
    # by the contacts' discs (the plate's tangent plane about each) wide enough to meet
    # (0.45: half the diagonal of the contacts' squares, 0.42), it stops at the face.
    plate, contacts, normals, free, inside_wall = _wall()
    holed = carved_prior(plate, free, contacts, radius=0.6)
    assert np.all(holed(inside_wall)[0] > 0)
    kept = carved_prior(plate, free, contacts, radius=0.6, normals=normals, disk=0.45)
    np.testing.assert_allclose(kept(inside_wall)[0], plate(inside_wall)[0])
    # The balls still cut the free space above the face, as far as the face.
    cut = free_space_cut(free, contacts, 0.6, normals=normals, disk=0.45)
    np.testing.assert_allclose(cut.radii, 0.25)


def test_no_disc_keeps_the_carve_as_it_was():
    plate, contacts, normals, free, inside_wall = _wall()
    plain = free_space_cut(free, contacts, 0.6)
    same = free_space_cut(free, contacts, 0.6, normals=normals, disk=0.0)
    np.testing.assert_array_equal(plain.radii, same.radii)
    np.testing.assert_array_equal(plain.free_points, same.free_points)


def test_a_disc_ends_at_a_free_point_beside_its_contact():
    # A probe passed 0.2 beside the first contact, in its tangent plane (between a fork's
    # tines): the surface ends there, and so does that contact's disc. Points above a
    # contact (its approach) and beyond the disc leave it whole.
    contacts = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (2, 1))
    free = np.array([[0.2, 0.0, 0.05], [5.0, 0.0, 0.1], [5.0, 0.0, 0.3], [5.9, 0.0, 0.0]])
    radii = disk_radii(contacts, normals, free, 0.5)
    np.testing.assert_allclose(radii, [0.2, 0.5])
    np.testing.assert_array_equal(disk_radii(contacts, normals, free[:0], 0.5), [0.5, 0.5])
    # A ball about a point beyond the shortened disc is bounded by what is left of it.
    beyond = np.array([[0.5, 0.0, 0.1]])
    np.testing.assert_allclose(disk_distances(beyond, contacts, normals, radii),
                               np.hypot(0.1, 0.3))
