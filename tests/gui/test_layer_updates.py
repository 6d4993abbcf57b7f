"""The viewport's layers keep up with novel objects: actors updated in place, unchanged
layers left alone, a GPIS surface finer than the viewport drawn decimated (off-screen, no Qt)."""

from dataclasses import replace

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from tactile_viz.engine import PriorLibrary, load_bundled  # noqa: E402
from tactile_viz.engine.session import Session, make_truth  # noqa: E402
from tactile_viz.gui.display_mesh import decimation, face_budget  # noqa: E402
from tactile_viz.gui.layers import ViewportLayers  # noqa: E402

pytestmark = pytest.mark.usefixtures("off_screen")


SIZE = 480


@pytest.fixture(scope="module")
def session():
    library = PriorLibrary(load_bundled(name) for name in ["mug_1", "vase_1", "bottle_1"])
    session = Session.simulated(make_truth(load_bundled("vase_2"), rng=2), library, seed=2)
    session.run(max_steps=6)
    return session


@pytest.fixture
def layers(session):
    plotter = pv.Plotter(off_screen=True, window_size=(SIZE, SIZE))
    plotter.set_background("white")
    layers = ViewportLayers(plotter, session.library.reference_size)
    layers.show_truth(session.truth)
    yield layers
    plotter.close()


def _sphere_surface(snapshot, resolution, radius=1.0):
    """``snapshot`` with a GPIS surface: a sphere of ``resolution`` by ``resolution`` at its
    first contact, its variance growing with height."""
    sphere = pv.Sphere(radius=radius, center=tuple(snapshot.contacts[0]),
                       theta_resolution=resolution, phi_resolution=resolution)
    points = np.asarray(sphere.points)
    variance = 1e-3 * (1.0 + points[:, 2] - points[:, 2].min())
    return replace(snapshot, gpis_vertices=points, gpis_faces=sphere.faces.reshape(-1, 4)[:, 1:],
                   gpis_variance=variance)


def _drawn(layers, name):
    return pv.wrap(layers.actors[name].GetMapper().GetInput())


def test_budget_grows_with_the_viewport():
    assert face_budget(716, 825) == 716 * 825 // 50
    assert face_budget(1432, 1650) > 3.9 * face_budget(716, 825)
    assert face_budget(100, 100) >= 4000  # a tiny view still shows a shape


def test_decimation_keeps_a_subset_of_the_vertices():
    sphere = pv.Sphere(theta_resolution=80, phi_resolution=80)
    vertices, faces = np.asarray(sphere.points), sphere.faces.reshape(-1, 4)[:, 1:]
    kept, reduced = decimation(vertices, faces, 2000)
    assert 1000 < len(reduced) <= 2100 < len(faces)
    assert reduced.min() == 0 and reduced.max() == len(kept) - 1
    assert np.all(np.diff(kept) > 0) and kept.max() < len(vertices)
    # Every face of the decimated surface is a real triangle of kept vertices.
    assert np.all((reduced[:, 0] != reduced[:, 1]) & (reduced[:, 1] != reduced[:, 2]))
    whole, same = decimation(vertices, faces, len(faces))
    np.testing.assert_array_equal(same, faces)
    np.testing.assert_array_equal(whole, np.arange(len(vertices)))


def test_novel_steps_update_the_same_gpis_actor(layers, session):
    first = _sphere_surface(session.latest, 12)
    layers.show_snapshot(first)
    actor, bar = layers.actors["gpis"], layers.plotter.scalar_bars["variance"]
    for resolution, radius in ((16, 0.8), (10, 1.2), (20, 0.6)):
        step = _sphere_surface(session.latest, resolution, radius)
        layers.show_snapshot(step)
        assert layers.actors["gpis"] is actor
        drawn = _drawn(layers, "gpis")
        assert drawn.n_cells == len(step.gpis_faces)
        np.testing.assert_allclose(drawn.points, step.gpis_vertices)
        np.testing.assert_allclose(drawn.point_data["variance"], step.gpis_variance)
        assert bar.GetLookupTable().GetRange() == pytest.approx(
            (step.gpis_variance.min(), step.gpis_variance.max()))
    # A step without a surface hides the colour bar; it comes back as it was.
    layers.show_snapshot(replace(step, gpis_vertices=None, gpis_faces=None, gpis_variance=None))
    assert not actor.GetVisibility() and not bar.GetVisibility()
    layers.show_snapshot(first)
    assert layers.plotter.scalar_bars["variance"] is bar and bar.GetVisibility()
    assert layers.actors["gpis"] is actor and actor.GetVisibility()


def test_a_surface_finer_than_the_view_is_drawn_decimated_and_coloured(layers, session):
    fine = _sphere_surface(session.latest, 110, radius=1.5)
    budget = layers.budget
    assert budget == face_budget(SIZE, SIZE) and len(fine.gpis_faces) > 2 * budget
    layers.show_snapshot(fine)
    drawn = _drawn(layers, "gpis")
    assert budget / 2 < drawn.n_cells <= 1.05 * budget
    variance = np.asarray(drawn.point_data["variance"])
    assert len(variance) == drawn.n_points and np.all(np.isfinite(variance))
    # The colours cover the decimated surface, from the whole surface's variance.
    assert fine.gpis_variance.min() <= variance.min() and variance.max() <= fine.gpis_variance.max()
    low, high = layers.actors["gpis"].mapper.scalar_range
    assert (low, high) == pytest.approx((fine.gpis_variance.min(), fine.gpis_variance.max()))
    np.testing.assert_allclose(drawn.bounds, pv.PolyData(fine.gpis_vertices).bounds, atol=0.05)
    for name in ("truth", "map", "contacts", "noncontacts", "target", "path"):
        layers.set_visible(name, False)
    layers.legend.SetVisibility(False)
    layers.plotter.scalar_bars["variance"].SetVisibility(False)
    layers.plotter.camera_position = [tuple(np.asarray(fine.contacts[0]) + (0, -8, 0)),
                                      tuple(fine.contacts[0]), (0, 0, 1)]
    image = layers.plotter.screenshot(return_img=True)[..., :3].astype(int)
    coloured = (np.abs(image - 255).sum(axis=-1) > 60).mean()
    assert coloured > 0.05  # the surface is drawn, in colour (not the white background)
    # A coarser surface next: drawn whole, in the same actor.
    coarse = _sphere_surface(session.latest, 14)
    layers.show_snapshot(coarse)
    assert _drawn(layers, "gpis").n_cells == len(coarse.gpis_faces)


def test_a_layer_whose_data_did_not_change_is_not_uploaded_again(layers, session):
    step = session.latest
    layers.show_snapshot(step)
    stamps = {name: _drawn(layers, name).GetMTime() for name in ("map", "contacts")}
    # The next step: the same MAP shape (equal arrays, not the same objects), one contact more.
    contacts = np.vstack([step.contacts, step.contacts[-1] + 0.01])
    layers.show_snapshot(replace(step, map_vertices=np.array(step.map_vertices),
                                 map_faces=np.array(step.map_faces), contacts=contacts))
    assert _drawn(layers, "map").GetMTime() == stamps["map"]
    assert _drawn(layers, "contacts").GetMTime() > stamps["contacts"]
    assert _drawn(layers, "contacts").n_points > 0
    moved = np.asarray(step.map_vertices) + 0.5
    layers.show_snapshot(replace(step, map_vertices=moved))
    np.testing.assert_allclose(_drawn(layers, "map").points, moved)
    # Sizes follow the scene's length even when the contacts are the same.
    before = _drawn(layers, "contacts").length
    layers.set_scene_length(2 * layers.scene_length)
    assert _drawn(layers, "contacts").length > before
