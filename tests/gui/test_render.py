"""Off-screen rendering of the viewport layers (no Qt): colours where expected."""

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from tactile_viz.engine import PriorLibrary, load_bundled  # noqa: E402
from tactile_viz.engine.session import Session, make_truth  # noqa: E402
from tactile_viz.gui.layers import ViewportLayers  # noqa: E402

pytestmark = pytest.mark.usefixtures("off_screen")


@pytest.fixture(scope="module")
def snapshot():
    library = PriorLibrary(load_bundled(name) for name in ["mug_1", "vase_1", "bottle_1"])
    session = Session.simulated(make_truth(load_bundled("vase_1"), rng=2), library, seed=2)
    session.run(max_steps=12)
    return session


def _render(session, hidden=()):
    plotter = pv.Plotter(off_screen=True, window_size=(480, 480))
    plotter.set_background("white")
    layers = ViewportLayers(plotter)
    layers.show_truth(session.truth)
    layers.show_snapshot(session.latest)
    for name in hidden:
        layers.set_visible(name, False)
    plotter.camera_position = [(14, -14, 10), tuple(session.truth.translation), (0, 0, 1)]
    image = plotter.screenshot(return_img=True)
    plotter.close()
    return image[..., :3].astype(int)


def _fraction(image, rgb, tolerance=60):
    return float((np.abs(image - np.array(rgb)).sum(axis=-1) < tolerance).mean())


def test_scene_is_not_blank_and_shows_layer_colours(snapshot):
    image = _render(snapshot)
    assert (np.abs(image - 255).sum(axis=-1) > 30).mean() > 0.05
    red = _fraction(image, (255, 0, 0), 150)
    # Contacts: 12 spheres of radius 0.07 are about 0.1% of the image when all face the
    # camera; some lie behind the object, and how many depends on the trajectory down to
    # rounding, so ask for about two visible (0.02%) and let the hidden render prove they
    # are the contacts.
    assert red > 0.0002
    hidden = _render(snapshot, hidden=("contacts", "noncontacts", "map", "target", "path"))
    assert _fraction(hidden, (255, 0, 0), 150) < red / 3
    salmon = _fraction(image, (250, 128, 114), 90)
    assert salmon > _fraction(hidden, (250, 128, 114), 90)


def _with_surface(snapshot, variance_scale):
    from dataclasses import replace

    sphere = pv.Sphere(radius=1.0, center=tuple(snapshot.contacts[0]))
    faces = sphere.faces.reshape(-1, 4)[:, 1:]
    variance = variance_scale * (1.0 + np.asarray(sphere.points)[:, 2] - sphere.points[:, 2].min())
    return replace(snapshot, gpis_vertices=np.asarray(sphere.points), gpis_faces=faces,
                   gpis_variance=variance)


def test_colour_bar_range_follows_the_current_surface(snapshot):
    plotter = pv.Plotter(off_screen=True, window_size=(480, 480))
    layers = ViewportLayers(plotter)
    layers.show_truth(snapshot.truth)
    for scale in (1e-3, 5e-2):
        step = _with_surface(snapshot.latest, scale)
        layers.show_snapshot(step)
        bar = plotter.scalar_bars["variance"]
        low, high = bar.GetLookupTable().GetRange()
        assert (low, high) == pytest.approx((step.gpis_variance.min(), step.gpis_variance.max()))
        assert bar.GetPositionCoordinate().GetValue()[0] + bar.GetWidth() <= 1.0
    layers.set_visible("gpis", False)
    assert not plotter.scalar_bars["variance"].GetVisibility()  # hidden, kept for the next
    plotter.close()


def _legend_pixels(plotter, layers, image):
    """The legend box of ``image``, a pixel short of its edges."""
    height, width = image.shape[:2]
    left, bottom = layers.legend.GetPosition()
    box_w, box_h = layers.legend.GetPosition2()
    return image[round((1 - bottom - box_h) * height) + 2:round((1 - bottom) * height) - 2,
                 round(left * width) + 2:round((left + box_w) * width) - 2]


def test_nothing_drawn_shows_through_the_legend(snapshot):
    # The same legend over the scene filling the view and over an empty view.
    plotter = pv.Plotter(off_screen=True, window_size=(480, 480))
    plotter.set_background("white")
    layers = ViewportLayers(plotter)
    layers.show_truth(snapshot.truth)
    layers.show_snapshot(snapshot.latest)
    centre = np.asarray(snapshot.truth.translation, dtype=float)
    views = {"filled": (centre + (3, -3, 2), centre), "empty": (centre + (0, 0, 40),
                                                               centre + (0, 0, 80))}
    images = {}
    for key, (position, focus) in views.items():
        plotter.camera_position = [tuple(position), tuple(focus), (0, 1, 0)]
        images[key] = plotter.screenshot(return_img=True)[..., :3].astype(int)
    plotter.close()
    behind = _legend_pixels(plotter, layers, images["filled"])
    assert (np.abs(behind - 255).sum(axis=-1) > 30).mean() > 0.2  # mostly the legend's text
    whole = images["filled"]
    assert (np.abs(whole - 255).sum(axis=-1) > 30).mean() > 0.5  # the scene fills the view
    np.testing.assert_array_equal(behind, _legend_pixels(plotter, layers, images["empty"]))


def test_the_target_is_drawn_over_the_surfaces(snapshot):
    from dataclasses import replace

    from tactile_viz.gui.layers import LAYERS

    # A target behind the truth and the MAP shape (seen from the camera), as a target on the
    # far side of a known object is: those translucent surfaces all but hid it.
    centre = np.asarray(snapshot.truth.translation, dtype=float)
    camera = np.array([14.0, -14.0, 10.0])
    behind = centre + 2.0 * (centre - camera) / np.linalg.norm(centre - camera)
    inside = replace(snapshot.latest, target=behind)
    gold = pv.Color(LAYERS["target"][1]).int_rgb
    fractions = []
    for shown in (True, False):
        plotter = pv.Plotter(off_screen=True, window_size=(480, 480))
        layers = ViewportLayers(plotter)
        layers.show_truth(snapshot.truth)
        layers.show_snapshot(inside)
        layers.set_visible("target", shown)
        layers.legend.SetVisibility(False)  # its gold marker is not the target
        plotter.camera_position = [tuple(camera), tuple(centre), (0, 0, 1)]
        image = plotter.screenshot(return_img=True)[..., :3].astype(int)
        fractions.append(_fraction(image, gold, 80))
        plotter.close()
    assert fractions[0] > 0.0001 and fractions[0] > 5 * fractions[1], fractions


def test_nothing_is_drawn_over_the_colour_bar_title(snapshot):
    # The target is drawn over the layers; placed right under the colour bar's title it cut
    # letters out of it ("ariance"). The title's dark pixels stay dark with it there (the
    # bar's box hides it).
    from dataclasses import replace

    centre = np.asarray(snapshot.truth.translation, dtype=float)
    plotter = pv.Plotter(off_screen=True, window_size=(480, 480))
    plotter.set_background("white")
    layers = ViewportLayers(plotter, snapshot.library.reference_size)
    layers.show_truth(snapshot.truth)
    step = _with_surface(snapshot.latest, 1e-3)
    layers.show_snapshot(step)
    plotter.camera_position = [(14, -14, 10), tuple(centre), (0, 0, 1)]
    layers.set_visible("target", False)
    layers.legend.SetVisibility(False)
    image = plotter.screenshot(return_img=True)[..., :3].astype(int)
    bar = plotter.scalar_bars["variance"]
    # The title is at the top of the bar's box, above the colours and the top label.
    left = round(bar.GetPositionCoordinate().GetValue()[0] * 480) - 40
    top = round((1 - bar.GetPositionCoordinate().GetValue()[1] - bar.GetHeight()) * 480)
    band = slice(top - 6, top + 16), slice(left, None)
    title = np.zeros(image.shape[:2], dtype=bool)
    title[band] = image[band].sum(axis=-1) < 300
    rows, columns = np.nonzero(title)
    assert title.sum() > 20  # the word is there
    renderer = plotter.renderer
    renderer.SetWorldPoint(*centre, 1.0)
    renderer.WorldToDisplay()
    depth = renderer.GetDisplayPoint()[2]
    renderer.SetDisplayPoint(columns.mean(), 480 - rows.mean(), depth)
    renderer.DisplayToWorld()
    world = np.asarray(renderer.GetWorldPoint())
    layers.show_snapshot(replace(step, target=world[:3] / world[3]))
    layers.set_visible("target", True)
    gold = pv.Color("gold").int_rgb
    layers.colour_bar.set_visible(False)  # the target is there, behind the bar's box
    plotter.render()
    behind = plotter.screenshot(return_img=True)[..., :3].astype(int)
    assert _fraction(behind[band], gold, 80) > 0.005
    layers.colour_bar.set_visible(True)
    plotter.render()
    covered = plotter.screenshot(return_img=True)[..., :3].astype(int)
    assert (covered[title].sum(axis=-1) < 300).mean() > 0.95
    plotter.close()
