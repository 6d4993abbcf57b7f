"""Viewport layers: one pyvista actor per kind of thing shown, each with a visibility toggle.

All methods touch VTK and must run on the GUI thread. Each layer's actor is created once and
then updated in place (the mapper draws the layer's own data set, into which each new mesh
is shallow-copied; a layer whose data did not change since it was drawn, compared with the
snapshot's read-only arrays it was drawn from, is left as it is: nothing is uploaded), nothing
renders while a step is being drawn and :meth:`ViewportLayers.show_snapshot` ends with a
single render. The camera is never moved by a step. The GPIS surface is drawn with no more
faces than the viewport can show (:mod:`tactile_viz.gui.display_mesh`); the colour bar spans
the whole surface's variance.

Everything drawn in world units (contact and target spheres) is a share of the scene's length
scale, :attr:`ViewportLayers.scene_length` (the window sets it to the priors' reference size,
:attr:`tactile_viz.app.scene.Scene.reference_size`), so a scene in metres, millimetres or
the paper's 6 units looks the same; the legend, the colour bar and line widths are in pixels.

The robot's scene (:mod:`tactile_viz.engine.scene`, given by :meth:`ViewportLayers.show_scene`)
adds two layers: its table, a translucent square on the support plane under the object
(:data:`TABLE_SIZE` times the object's longest side), drawn like the truth from the scene
rather than from a step; and the fingertip, a translucent sphere of the tip's radius at the
tip's centre of the latest contact (the contact plus the radius along its normal), drawn
only when the radius is above 0. The table is left out of the camera's framing.
"""

import numpy as np
import pyvista as pv
import vtk

from ..engine.params import PAPER_SIZE
from ..engine.transforms import transform_points
from .colour_bar import ColourBar
from .display_mesh import (  # noqa: F401
    decimation,
    face_budget,
    faces_to_polydata,
    polylines,
    spheres,
    vertex_normals,
)

# name -> (legend label, colour)
LAYERS = {
    "truth": ("ground truth", "lightsteelblue"),
    "table": ("table", "tan"),
    "map": ("MAP shape", "salmon"),
    "hypotheses": ("other hypotheses (opacity: weight)", "mediumpurple"),
    "gpis": ("GPIS (colour: variance)", "viridis"),
    "contacts": ("contacts", "red"),
    "noncontacts": ("non-contacts", "green"),
    "target": ("target", "gold"),
    "tip": ("fingertip (latest contact)", "darkorange"),
    "path": ("sensor path", "dimgray"),
}
# Sphere radii as shares of the scene's length scale: 0.07 and 0.154 on the paper's 6 units.
CONTACT_RADIUS = 0.07 / PAPER_SIZE
TARGET_RADIUS = 2.2 * CONTACT_RADIUS
LEGEND_ROW_PIXELS = 18  # height of one legend entry, whatever the viewport's size
LEGEND_WIDTH_PIXELS = 230
# The legend: dark labels on a light box, each beside a framed marker of its layer's colour
# (WCAG contrast of the labels against the box: about 17, where text needs 4.5).
LEGEND_BACKGROUND = (1.0, 1.0, 1.0)
LEGEND_BACKGROUND_OPACITY = 1.0  # opaque: a layer drawn behind it does not show through
LEGEND_TEXT = (0.1, 0.1, 0.1)
LEGEND_OUTLINE = (0.25, 0.25, 0.25)
LEGEND_MARKER_ASPECT = 2.0  # a marker's width over its height
LEGEND_RAMP_STRIPS = 8  # colours of the GPIS layer's viridis marker
SCALAR_BAR = "variance"
HIDDEN_AT_START = ("hypotheses",)
TRANSLUCENT_SURFACES = ("truth", "map", "hypotheses", "tip")
# Drawn from the scene (the object, the robot's table), not from a step: kept across steps
# and session resets.
SCENE_LAYERS = ("truth", "table")
UNFRAMED = ("table",)  # left out of the camera's framing (it reaches far beyond the object)
TABLE_SIZE = 3.0  # the table's side, times the object's longest side (else the scene's length)
TABLE_OPACITY = 0.3
# The table is drawn this share of its side below the plane: the object's face resting on
# the plane then does not fight it for depth.
TABLE_DROP = 1e-3
TIP_OPACITY = 0.4
TIP_RESOLUTION = 24  # of the fingertip's sphere (one sphere: smooth at any size)
# Drawn over every other layer: the target is a point of the MAP surface, often on its far
# side, where behind the translucent truth and MAP shape it did not show at all.
ON_TOP = ("target",)


def relative_luminance(rgb):
    """WCAG 2 relative luminance of an RGB colour with components in [0, 1]."""
    rgb = np.asarray(rgb, dtype=float)
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return float(linear @ [0.2126, 0.7152, 0.0722])


def contrast_ratio(first, second):
    """WCAG 2 contrast ratio of two RGB colours (1 to 21; text wants at least 4.5)."""
    light, dark = sorted((relative_luminance(first), relative_luminance(second)), reverse=True)
    return (light + 0.05) / (dark + 0.05)


def legend_fill(name):
    """The RGB colours (0-255) that fill a layer's legend marker, left to right: one for a
    plain colour, a viridis ramp for the GPIS layer (drawn in viridis)."""
    colour = LAYERS[name][1]
    if colour == "viridis":
        from matplotlib import colormaps

        ramp = colormaps["viridis"](np.linspace(0.0, 1.0, LEGEND_RAMP_STRIPS))[:, :3]
        return (ramp * 255).round().astype(np.uint8)
    return np.array([pv.Color(colour).int_rgb], dtype=np.uint8)


def legend_marker(fill, outline=LEGEND_OUTLINE):
    """A legend marker: a dark frame around a rectangle filled with the colours ``fill``
    ((k, 3) RGB, 0-255; k vertical strips, left to right), as a ``vtkPolyData`` whose cells
    carry their colours (the legend draws them as they are, whatever the entry's colour, which
    is then the label's).

    The frame keeps light colours (gold, light steel blue) visible on the legend's light
    background; the label beside the marker is dark.
    """
    fill = np.asarray(fill, dtype=np.uint8).reshape(-1, 3)
    width, height, frame = LEGEND_MARKER_ASPECT, 1.0, 0.14
    # The legend draws a symbol at half its column's width, from the column's middle (x = 0):
    # shifted left like this, it ends a few pixels before the label instead of touching it.
    left = -0.35 * width
    xs = np.linspace(left + frame, left + width - frame, len(fill) + 1)
    corners = [(left, 0), (left + width, 0), (left + width, height), (left, height)]
    points = [(x, y, 0.0) for x, y in corners]
    quads = [[0, 1, 2, 3]]  # the frame, drawn first, under the fill
    for x0, x1 in zip(xs[:-1], xs[1:]):
        start = len(points)
        points += [(x0, frame, 0.0), (x1, frame, 0.0), (x1, height - frame, 0.0),
                   (x0, height - frame, 0.0)]
        quads.append([start, start + 1, start + 2, start + 3])
    marker = pv.PolyData(np.array(points), faces=np.hstack([[4, *quad] for quad in quads]))
    outline = (np.asarray(pv.Color(outline).float_rgb) * 255).round().astype(np.uint8)
    marker.cell_data["colours"] = np.vstack([outline[None], fill])
    marker.cell_data.active_scalars_name = "colours"
    return marker


class ViewportLayers:
    """The actors of a plotter, by layer name.

    Parameters
    ----------
    plotter : pyvista.Plotter or pyvistaqt.QtInteractor
    scene_length : float
        The scene's length scale, scene units (see :meth:`set_scene_length`).
    """

    def __init__(self, plotter, scene_length=PAPER_SIZE):
        self.plotter = plotter
        self.scene_length = float(scene_length)
        self.visible = {name: name not in HIDDEN_AT_START for name in LAYERS}
        self.models = None  # class name -> ObjectModel, for the hypotheses' shapes
        self.present = {name: False for name in LAYERS}
        self.actors = {}
        self.latest = None
        self.robot_scene = None  # tactile_viz.engine.scene.Scene, from show_scene
        self._table_truth = None  # the truth the table was laid under
        self._legend_key = None
        self._variance_range = None
        self._overlay = None
        self.colour_bar = None  # a ColourBar once a GPIS surface is shown
        self._drawn = {}  # layer name -> the inputs it was last drawn from
        self.budget = face_budget(*self._viewport_pixels())

    # ------------------------------------------------------------------ public
    def set_visible(self, name, visible):
        self.visible[name] = bool(visible)
        if visible and self.latest is not None and name not in SCENE_LAYERS:
            self._update(name, self.latest)  # hidden layers are not kept up to date
        self._apply_visibility(name)
        self._sync_overlays()
        self.plotter.render()

    def set_scene_length(self, length, render=False):
        """Size what is drawn in world units as shares of ``length`` (scene units: the
        priors' reference size, 6 for the paper's objects); the current step is redrawn
        when it changes."""
        length = float(length)
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"the scene's length must be positive, got {length!r}")
        if length == self.scene_length:
            return
        self.scene_length = length
        if self.present["table"] and self._table_truth is None:  # sized by the scene's length
            self._draw_table()
        if self.latest is not None:
            for name in ("contacts", "noncontacts", "target"):
                if self.visible[name]:
                    self._update(name, self.latest)
        if render:
            self.plotter.render()

    def radius(self, name):
        """The radius of a contact, non-contact or target sphere, scene units."""
        return (TARGET_RADIUS if name == "target" else CONTACT_RADIUS) * self.scene_length

    def framed(self):
        """The layers the camera frames: the ground truth when it is shown, else what is
        shown but the table."""
        if self.shown("truth"):
            return ["truth"]
        return [name for name in LAYERS if self.shown(name) and name not in UNFRAMED]

    def bounds(self):
        """``(xmin, xmax, ymin, ymax, zmin, zmax)`` to frame, scene units: the ground truth's
        when it is shown, else what is shown (not the table), else a cube as long as the
        scene's length about the origin (a recording before its first step)."""
        names = self.framed()
        boxes = np.array([self.actors[n].GetBounds() for n in names if n in self.actors])
        if not len(boxes):
            half = self.scene_length / 2
            return (-half, half) * 3
        low, high = boxes[:, 0::2].min(axis=0), boxes[:, 1::2].max(axis=0)
        return tuple(float(v) for pair in zip(low, high) for v in pair)

    def fit_clipping_range(self):
        """Near and far planes around everything drawn (a step may draw beyond the framed
        bounds: a sensor path coming from afar)."""
        self.plotter.renderer.ResetCameraClippingRange()

    def shown(self, name):
        """True when the layer has something to show and is switched on."""
        return self.present[name] and self.visible[name]

    def show_truth(self, truth, render=True):
        """The ground truth at its pose, translucent (hidden when ``truth`` is None: a
        recording has no truth)."""
        if truth is None:
            self.present["truth"] = False
            self._apply_visibility("truth")
            self._sync_overlays()
            if render:
                self.plotter.render()
            return
        vertices = truth.to_world(truth.model.mesh.vertices)
        self._put("truth", faces_to_polydata(vertices, truth.model.mesh.faces, normals=True),
                  color=LAYERS["truth"][1], opacity=0.35, smooth=True)
        self._sync_overlays()
        if render:
            self.plotter.render()

    def show_scene(self, robot_scene, truth=None, render=True):
        """The robot's scene (:class:`tactile_viz.engine.scene.Scene`, None: free space):
        its table under ``truth`` (the ground truth, None for a recording: then under the
        table's point) and the tip's radius for the fingertip layer."""
        self.robot_scene = robot_scene
        self._table_truth = truth
        if robot_scene is not None and robot_scene.has_table:
            self._draw_table()
        else:
            self.present["table"] = False
            self._apply_visibility("table")
        if self.latest is not None and self.visible["tip"]:
            self._update("tip", self.latest)
        else:
            self._apply_visibility("tip")
        self._sync_overlays()
        if render:
            self.plotter.render()

    @property
    def tip_radius(self):
        """The robot scene's tip radius, scene units (0: a point sensor)."""
        return 0.0 if self.robot_scene is None else float(self.robot_scene.tip_radius)

    def table_mesh(self, robot_scene, truth=None):
        """The table as drawn: a square on the support plane, :data:`TABLE_SIZE` times the
        object's longest side (the scene's length without a truth), centred under the
        object's box (under the table's point without a truth), a hair below the plane."""
        up = np.asarray(robot_scene.up, dtype=float)
        if truth is not None:
            vertices = truth.to_world(truth.model.mesh.vertices)
            centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
            size = TABLE_SIZE * float(truth.model.length)
        else:
            centre = np.asarray(robot_scene.table_point, dtype=float)
            size = TABLE_SIZE * self.scene_length
        on_plane = centre - float(robot_scene.height(centre[None])[0]) * up
        return pv.Plane(center=on_plane - TABLE_DROP * size * up, direction=up, i_size=size,
                        j_size=size, i_resolution=1, j_resolution=1)

    def _draw_table(self):
        self._put("table", self.table_mesh(self.robot_scene, self._table_truth),
                  color=LAYERS["table"][1], opacity=TABLE_OPACITY)

    def show_snapshot(self, snapshot, render=True):
        """MAP shape, GPIS, contacts, non-contacts, target, fingertip and path of one step
        (one render)."""
        self.latest = snapshot
        for name in LAYERS:
            if name not in SCENE_LAYERS and self.visible[name]:
                self._update(name, snapshot)
            elif name not in SCENE_LAYERS:
                self.present[name] = self._has(name, snapshot)
                self._apply_visibility(name)
        self._sync_overlays()
        self.fit_clipping_range()
        if render:
            self.plotter.render()

    def clear_session(self, render=True):
        """Hide everything but the ground truth and the table."""
        self.latest = None
        for name in LAYERS:
            if name not in SCENE_LAYERS:
                self.present[name] = False
                self._apply_visibility(name)
        self._sync_overlays()
        if render:
            self.plotter.render()

    def relayout(self):
        """Size the legend and the GPIS surface's face budget for the current viewport
        (call on resize; the surface follows at the next step)."""
        self._legend_key = None
        self.budget = face_budget(*self._viewport_pixels())
        if self.colour_bar is not None:
            self.colour_bar.place(*self._viewport_pixels())
        self._sync_overlays()

    def gpis_surface(self, vertices, faces, variance):
        """The GPIS surface as drawn: decimated to :attr:`budget` faces (a new surface every
        step, so its decimation is not kept), with vertex normals and its variance at the
        vertices kept."""
        kept, faces = decimation(vertices, faces, self.budget)
        mesh = faces_to_polydata(np.asarray(vertices, dtype=float)[kept], faces, normals=True)
        mesh.point_data["variance"] = np.asarray(variance, dtype=float)[kept]
        mesh.set_active_scalars("variance")
        return mesh

    # ------------------------------------------------------------------ layers
    def _has(self, name, snapshot):
        if name == "hypotheses":
            return bool(snapshot.hypotheses) and self.models is not None
        if name == "map":
            return snapshot.map_faces is not None and len(snapshot.map_faces) > 0
        if name == "gpis":
            return snapshot.gpis_faces is not None and len(snapshot.gpis_faces) > 0
        if name in ("contacts", "noncontacts"):
            return len(getattr(snapshot, name)) > 0
        if name == "target":
            return snapshot.target is not None
        if name == "path":
            return bool(snapshot.paths)
        if name == "tip":
            return self.tip_radius > 0 and len(snapshot.contacts) > 0
        return True

    def _inputs(self, name, snapshot):
        """What a layer is drawn from (compared with what it was last drawn from)."""
        if name == "hypotheses":
            return [snapshot.hypotheses]
        if name in ("contacts", "noncontacts", "target"):
            return [getattr(snapshot, name), self.radius(name)]
        if name == "tip":
            return [np.asarray(snapshot.contacts)[-1], np.asarray(snapshot.normals)[-1],
                    self.tip_radius]
        if name == "gpis":
            return [snapshot.gpis_vertices, snapshot.gpis_faces, snapshot.gpis_variance,
                    self.budget]
        return [snapshot.map_vertices, snapshot.map_faces] if name == "map" else [snapshot.paths]

    def _unchanged(self, name, inputs):
        before = self._drawn.get(name)
        if before is None or len(before) != len(inputs) or name not in self.actors:
            return False
        for old, new in zip(before, inputs):
            if old is new:
                continue
            if isinstance(new, (float, int)):  # a radius, the face budget
                if old != new:
                    return False
            elif not (isinstance(new, np.ndarray) and isinstance(old, np.ndarray)
                      and np.array_equal(old, new)):
                return False  # (paths and hypotheses, sequences: drawn anew unless the same)
        return True

    def _update(self, name, snapshot):
        present = self._has(name, snapshot)
        self.present[name] = present
        if present:
            inputs = self._inputs(name, snapshot)
            if self._unchanged(name, inputs):
                self._apply_visibility(name)  # drawn as it is: nothing to upload
                return
            self._drawn[name] = inputs
            if name == "map":
                self._put("map", faces_to_polydata(snapshot.map_vertices, snapshot.map_faces,
                                                   normals=True),
                          color=LAYERS["map"][1], opacity=0.55, smooth=True)
            elif name == "hypotheses":
                self._put("hypotheses", self._ghosts(snapshot.hypotheses), scalars="rgba",
                          rgba=True, smooth=True)
            elif name == "gpis":
                variance = np.asarray(snapshot.gpis_variance, dtype=float)
                surface = self.gpis_surface(snapshot.gpis_vertices, snapshot.gpis_faces,
                                            variance)
                finite = variance[np.isfinite(variance)]
                low, high = (float(finite.min()), float(finite.max())) if len(finite) else (0, 1)
                if high <= low:
                    high = low + 1e-12
                self._variance_range = (low, high)
                self._put("gpis", surface, scalars="variance", cmap="viridis", smooth=True,
                          clim=[low, high])
                self.actors["gpis"].mapper.scalar_range = (low, high)
            elif name in ("contacts", "noncontacts"):
                self._put(name, spheres(getattr(snapshot, name), self.radius(name)),
                          color=LAYERS[name][1])
            elif name == "target":
                self._put("target", spheres(np.asarray(snapshot.target)[None],
                                            self.radius("target")), color=LAYERS["target"][1])
            elif name == "path":
                self._put("path", polylines(snapshot.paths), color=LAYERS["path"][1],
                          line_width=2)
            elif name == "tip":
                self._put("tip", self.tip_mesh(snapshot), color=LAYERS["tip"][1],
                          opacity=TIP_OPACITY, smooth=True)
        self._apply_visibility(name)

    def tip_centre(self, snapshot):
        """The tip's centre at the latest contact of ``snapshot``: the touched point plus
        the tip's radius along its outward normal, (3,) world frame."""
        point = np.asarray(snapshot.contacts, dtype=float)[-1]
        normal = np.asarray(snapshot.normals, dtype=float)[-1]
        return point + self.tip_radius * normal

    def tip_mesh(self, snapshot):
        """The fingertip as drawn: a sphere of the tip's radius at :meth:`tip_centre`."""
        return pv.Sphere(radius=self.tip_radius, center=tuple(self.tip_centre(snapshot)),
                         theta_resolution=TIP_RESOLUTION, phi_resolution=TIP_RESOLUTION)

    def _ghosts(self, hypotheses):
        """The hypotheses' shapes as one mesh, each point coloured with an opacity that grows
        with its hypothesis' weight."""
        colour = np.array(pv.Color(LAYERS["hypotheses"][1]).int_rgb, dtype=np.uint8)
        heaviest = max(weight for *_, weight in hypotheses)
        vertices, faces, rgba, offset = [], [], [], 0
        for name, rotation, translation, weight in hypotheses:
            mesh = self.models[name].mesh
            vertices.append(transform_points(mesh.vertices, rotation, translation))
            faces.append(np.asarray(mesh.faces) + offset)
            alpha = int(255 * (0.08 + 0.32 * weight / heaviest))
            rgba.append(np.tile(np.r_[colour, alpha].astype(np.uint8), (len(mesh.vertices), 1)))
            offset += len(mesh.vertices)
        ghosts = faces_to_polydata(np.vstack(vertices), np.vstack(faces), normals=True)
        ghosts.point_data["rgba"] = np.vstack(rgba)
        return ghosts

    def overlay(self):
        """A renderer drawn after the plotter's, with its camera and a depth buffer of its
        own: what it holds is never hidden by the layers (the legend is drawn there too)."""
        if self._overlay is None:
            main = self.plotter.renderer
            overlay = vtk.vtkRenderer()
            overlay.SetLayer(1)
            overlay.InteractiveOff()
            overlay.SetActiveCamera(main.GetActiveCamera())
            # pyvista may give the main renderer a new camera: follow it at every render.
            main.AddObserver("StartEvent", lambda *_: overlay.SetActiveCamera(
                main.GetActiveCamera()))
            window = self.plotter.render_window
            window.SetNumberOfLayers(max(2, window.GetNumberOfLayers()))
            window.AddRenderer(overlay)
            self._overlay = overlay
        return self._overlay

    def _add_on_top(self, mesh, color):
        mapper = pv.DataSetMapper(mesh)
        mapper.scalar_visibility = False
        actor = pv.Actor(mapper=mapper)
        actor.prop.color = color
        self.overlay().AddActor(actor)
        return actor

    def _put(self, name, mesh, smooth=False, **style):
        """Create the layer's actor once, then swap its data set in place."""
        actor = self.actors.get(name)
        if actor is None and name in ON_TOP:
            self.actors[name] = self._add_on_top(mesh, style["color"])
        elif actor is None:
            actor = self.plotter.add_mesh(mesh, name=name, reset_camera=False, render=False,
                                          show_scalar_bar=False, **style)
            # The mapper draws this data set itself: with scalars pyvista puts a filter
            # before it, which could hand the mapper its first output again (a GPIS surface
            # stuck at the one first drawn when it was decimated).
            actor.mapper.SetInputData(mesh)
            if smooth:
                actor.prop.interpolation = "gouraud"  # with the mesh's own normals
            if name in TRANSLUCENT_SURFACES:
                # Only the side facing the camera: half the fragments of a software render
                # (0.04 s instead of 0.07 s for mug_1 and its MAP shape), and no far side
                # blended over the near one out of order.
                actor.prop.culling = "back"
            self.actors[name] = actor
        else:
            actor.GetMapper().GetInput().ShallowCopy(mesh)  # (also the arrays' roles)
        self.present[name] = True
        self._apply_visibility(name)

    def _apply_visibility(self, name):
        if name in self.actors:
            self.actors[name].SetVisibility(self.shown(name))

    # ------------------------------------------------------------------ overlays
    def _sync_overlays(self):
        self._sync_scalar_bar()
        self._sync_legend()

    def _sync_scalar_bar(self):
        if self.colour_bar is not None:
            # Hidden, not removed, while a step has no GPIS surface: adding it again laid
            # out its text anew in the next render (a GPIS surface comes and goes).
            self.colour_bar.set_visible(self.shown("gpis"))
        elif self.shown("gpis"):
            # Drawn over the layers like the legend, on a box of its own: in the plotter's
            # renderer the target (drawn over it) and a sensor path cut letters out of it.
            self.colour_bar = ColourBar(self.plotter, self.overlay(),
                                        self.actors["gpis"].mapper, SCALAR_BAR,
                                        LEGEND_BACKGROUND, LEGEND_OUTLINE, LEGEND_TEXT)
            self.colour_bar.place(*self._viewport_pixels())

    def _viewport_pixels(self):
        try:
            width, height = self.plotter.window_size
        except (AttributeError, TypeError, ValueError):
            width, height = 800, 600
        return max(int(width), 100), max(int(height), 100)

    def _make_legend(self):
        """One legend actor for the life of the view; its entries are rewritten in place."""
        legend = vtk.vtkLegendBoxActor()
        legend.SetNumberOfEntries(len(LAYERS))
        legend.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        legend.GetPosition2Coordinate().SetCoordinateSystemToNormalizedViewport()
        legend.UseBackgroundOn()
        legend.SetBackgroundColor(*LEGEND_BACKGROUND)
        legend.SetBackgroundOpacity(LEGEND_BACKGROUND_OPACITY)
        legend.BorderOn()
        legend.GetProperty().SetColor(*LEGEND_OUTLINE)
        legend.SetPadding(3)
        legend.ScalarVisibilityOn()  # the markers' own cell colours
        legend.GetEntryTextProperty().SetColor(*LEGEND_TEXT)
        legend.GetEntryTextProperty().SetFontSize(12)
        self.markers = {name: legend_marker(legend_fill(name)) for name in LAYERS}
        self.overlay().AddViewProp(legend)  # over the target too
        self.legend = legend

    def _sync_legend(self):
        """A legend of the layers that exist and are switched on, sized in pixels (readable
        whatever the window's size): a dark label beside a framed marker of the layer's
        colour each (GPIS: a viridis ramp, as it is drawn)."""
        names = [name for name in LAYERS if self.shown(name)]
        pixels = self._viewport_pixels()
        key = (tuple(names), pixels)
        if key == self._legend_key:
            return
        self._legend_key = key
        if getattr(self, "legend", None) is None:
            self._make_legend()
        legend = self.legend
        legend.SetVisibility(bool(names))
        if not names:
            return
        legend.SetNumberOfEntries(len(names))
        for index, name in enumerate(names):
            # The entry's colour is its label's; the marker keeps its own colours.
            legend.SetEntry(index, self.markers[name], LAYERS[name][0], LEGEND_TEXT)
        width, height = pixels
        box_w = min(0.6, LEGEND_WIDTH_PIXELS / width)
        box_h = min(0.9, LEGEND_ROW_PIXELS * len(names) / height)
        legend.SetPosition(0.01, 0.99 - box_h)
        legend.SetPosition2(box_w, box_h)

    def legend_entries(self):
        """``(label, label colour, marker fill colours)`` of each legend entry, top to
        bottom (none while the legend is hidden); colours are RGB in [0, 1]."""
        legend = getattr(self, "legend", None)
        if legend is None or not legend.GetVisibility():
            return []
        entries = []
        for index in range(legend.GetNumberOfEntries()):
            marker = pv.wrap(legend.GetEntrySymbol(index))
            fill = np.asarray(marker.cell_data["colours"][1:], dtype=float) / 255
            entries.append((legend.GetEntryString(index), tuple(legend.GetEntryColor(index)),
                            fill))
        return entries
