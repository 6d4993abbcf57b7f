"""Viewport layers: one pyvista actor per kind of thing shown, each with a visibility toggle.

All methods touch VTK and must run on the GUI thread. Actors are replaced by name with
``reset_camera=False``, so the camera keeps its position across steps.
"""

import numpy as np
import pyvista as pv

# name -> (legend label, colour)
LAYERS = {
    "truth": ("ground truth", "lightsteelblue"),
    "map": ("MAP shape", "salmon"),
    "gpis": ("GPIS (colour: variance)", "mediumseagreen"),
    "contacts": ("contacts", "red"),
    "noncontacts": ("non-contacts", "green"),
    "target": ("target", "gold"),
    "path": ("sensor path", "dimgray"),
}
CONTACT_RADIUS = 0.07


def faces_to_polydata(vertices, faces):
    """A ``pv.PolyData`` from (n, 3) vertices and (m, 3) triangle indices."""
    faces = np.asarray(faces, dtype=np.int64)
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    return pv.PolyData(np.asarray(vertices, dtype=float), cells)


def spheres(points, radius=CONTACT_RADIUS):
    """Small spheres at (k, 3) points, as one mesh."""
    cloud = pv.PolyData(np.asarray(points, dtype=float).reshape(-1, 3))
    return cloud.glyph(geom=pv.Sphere(radius=radius, theta_resolution=10, phi_resolution=10),
                       scale=False, orient=False)


def polylines(paths):
    """One ``pv.PolyData`` holding every (k, 3) path as a line."""
    points, cells, offset = [], [], 0
    for path in paths:
        path = np.asarray(path, dtype=float)
        points.append(path)
        cells.append(np.r_[len(path), offset + np.arange(len(path))])
        offset += len(path)
    return pv.PolyData(np.vstack(points), lines=np.concatenate(cells))


class ViewportLayers:
    """The actors of a plotter, by layer name.

    Parameters
    ----------
    plotter : pyvista.Plotter or pyvistaqt.QtInteractor
    """

    def __init__(self, plotter):
        self.plotter = plotter
        self.visible = {name: True for name in LAYERS}
        self.actors = {}
        plotter.add_legend(labels=[[label, color] for label, color in LAYERS.values()],
                           bcolor="white", face="circle", size=(0.22, 0.24), loc="upper left")

    def set_visible(self, name, visible):
        self.visible[name] = bool(visible)
        if name in self.actors:
            self.actors[name].SetVisibility(bool(visible))
            if name == "gpis":
                self._show_scalar_bar(bool(visible))
        self.plotter.render()

    def show_truth(self, truth):
        """The ground truth at its pose, translucent."""
        vertices = truth.to_world(truth.model.mesh.vertices)
        self._put("truth", faces_to_polydata(vertices, truth.model.mesh.faces),
                  color=LAYERS["truth"][1], opacity=0.35, smooth_shading=True)

    def show_snapshot(self, snapshot):
        """MAP shape, GPIS, contacts, non-contacts, target and path of one step."""
        self._put("map", faces_to_polydata(snapshot.map_vertices, snapshot.map_faces),
                  color=LAYERS["map"][1], opacity=0.55, smooth_shading=True)
        if snapshot.gpis_faces is not None and len(snapshot.gpis_faces):
            surface = faces_to_polydata(snapshot.gpis_vertices, snapshot.gpis_faces)
            surface["variance"] = np.asarray(snapshot.gpis_variance)
            self._put("gpis", surface, scalars="variance", cmap="viridis", smooth_shading=True,
                      scalar_bar_args={"title": "variance", "vertical": True,
                                       "position_x": 0.88, "position_y": 0.1})
            self._show_scalar_bar(self.visible["gpis"])
        else:
            self._remove("gpis")
        self._points("contacts", snapshot.contacts)
        self._points("noncontacts", snapshot.noncontacts)
        if snapshot.target is not None:
            self._put("target", spheres(np.asarray(snapshot.target)[None], 1.6 * CONTACT_RADIUS),
                      color=LAYERS["target"][1])
        else:
            self._remove("target")
        if snapshot.paths:
            self._put("path", polylines(snapshot.paths), color=LAYERS["path"][1], line_width=2)
        self.plotter.render()

    def clear_session(self):
        """Remove everything but the ground truth."""
        for name in list(self.actors):
            if name != "truth":
                self._remove(name)
        self.plotter.render()

    def _points(self, name, points):
        if len(points):
            self._put(name, spheres(points), color=LAYERS[name][1])
        else:
            self._remove(name)

    def _put(self, name, mesh, **style):
        actor = self.plotter.add_mesh(mesh, name=name, reset_camera=False,
                                      show_scalar_bar=False, **style)
        actor.SetVisibility(self.visible[name])
        self.actors[name] = actor

    def _remove(self, name):
        if name in self.actors:
            self.plotter.remove_actor(self.actors.pop(name), reset_camera=False, render=False)
            if name == "gpis":
                self._show_scalar_bar(False)

    def _show_scalar_bar(self, visible):
        bars = getattr(self.plotter, "scalar_bars", {})
        if visible and "gpis" in self.actors and "variance" not in bars:
            self.plotter.add_scalar_bar(title="variance", mapper=self.actors["gpis"].mapper,
                                        vertical=True, position_x=0.88, position_y=0.1)
        elif not visible and "variance" in bars:
            self.plotter.remove_scalar_bar("variance", render=False)
