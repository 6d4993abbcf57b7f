"""The GPIS layer's colour bar: pyvista's scalar bar on an opaque framed box, drawn over the
layers and laid out in pixels.

The scalar bar's own background covers only its bar's box, while its title and end labels
reach beyond it; the box here holds all of them, so no marker or surface behind them shows
through their letters. Both are in the overlay renderer (drawn after the layers), the box
first.
"""

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

BAR_WIDTH_PIXELS = 80  # the bar's box: the colours and the labels beside them
BAR_HEIGHT = 0.5  # of the viewport's height
BAR_BOTTOM = 0.12  # of the viewport's height
RIGHT_MARGIN_PIXELS = 12  # from the box's right edge to the viewport's
# The box around the bar's box, pixels: the end labels stand half a line beyond the bar and
# the title above it.
PAD_PIXELS = {"left": 6, "right": 4, "bottom": 10, "top": 10}
FRAME_PIXELS = 1


class ColourBar:
    """A vertical scalar bar of ``mapper``'s colours titled ``title``, on a framed box.

    Parameters
    ----------
    plotter : pyvista.Plotter
        It makes the bar (it is then ``plotter.scalar_bars[title]``).
    overlay : vtkRenderer
        Where the box and the bar are drawn: over the layers.
    mapper : the mapper whose lookup table the bar shows
    title : str
    background, outline, text : RGB in [0, 1]
        The box's fill, its frame, and the title's and labels' colour.
    """

    def __init__(self, plotter, overlay, mapper, title, background, outline, text):
        plotter.add_scalar_bar(title=title, mapper=mapper, vertical=True, n_labels=4,
                               fmt="%.1e", label_font_size=11, title_font_size=12,
                               render=False)
        bar = plotter.scalar_bars[title]
        bar.SetBarRatio(0.22)  # of the box's width; the labels take the rest
        bar.SetVerticalTitleSeparation(6)  # the title clear of the top label
        for prop in (bar.GetLabelTextProperty(), bar.GetTitleTextProperty()):
            prop.SetColor(*text)
        plotter.renderer.RemoveViewProp(bar)
        self.box = _box_actor(background, outline)
        overlay.AddViewProp(self.box)
        overlay.AddViewProp(bar)
        self.bar = bar

    def set_visible(self, visible):
        self.bar.SetVisibility(bool(visible))
        self.box.SetVisibility(bool(visible))

    def place(self, width, height):
        """Lay the bar and its box out for a viewport of ``width`` x ``height`` pixels."""
        bar_w = min(0.3, BAR_WIDTH_PIXELS / width)
        left = 1.0 - (BAR_WIDTH_PIXELS + RIGHT_MARGIN_PIXELS + PAD_PIXELS["right"]) / width
        left = max(0.0, left)
        self.bar.SetPosition(left, BAR_BOTTOM)
        self.bar.SetPosition2(bar_w, BAR_HEIGHT)
        x0 = left * width - PAD_PIXELS["left"]
        x1 = (left + bar_w) * width + PAD_PIXELS["right"]
        y0 = BAR_BOTTOM * height - PAD_PIXELS["bottom"]
        y1 = (BAR_BOTTOM + BAR_HEIGHT) * height + PAD_PIXELS["top"]
        outer = np.array([x0, y0, x1, y1])
        inner = outer + FRAME_PIXELS * np.array([1, 1, -1, -1])
        points = np.vstack([_corners(outer), _corners(inner)]) / [width, height, 1]
        self.box.GetMapper().GetInput().GetPoints().SetData(numpy_to_vtk(points, deep=True))
        self.box.GetMapper().GetInput().Modified()

    def box_pixels(self, width, height):
        """``(left, bottom, right, top)`` of the box's outer edge, pixels from the bottom
        left corner of a ``width`` x ``height`` viewport."""
        points = vtk_to_numpy(self.box.GetMapper().GetInput().GetPoints().GetData())[:4]
        return (points[0, 0] * width, points[0, 1] * height, points[2, 0] * width,
                points[2, 1] * height)


def _corners(rect):
    x0, y0, x1, y1 = rect
    return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])


def _box_actor(background, outline):
    """A 2D actor of two quads in normalised viewport coordinates: the frame (drawn first)
    and the fill inside it, coloured per cell; :meth:`ColourBar.place` sets the corners."""
    points = vtk.vtkPoints()
    points.SetNumberOfPoints(8)
    quads = vtk.vtkCellArray()
    for start in (0, 4):
        quads.InsertNextCell(4, [start, start + 1, start + 2, start + 3])
    colours = vtk.vtkUnsignedCharArray()
    colours.SetNumberOfComponents(3)
    for colour in (outline, background):
        colours.InsertNextTuple3(*(round(255 * c) for c in colour))
    box = vtk.vtkPolyData()
    box.SetPoints(points)
    box.SetPolys(quads)
    box.GetCellData().SetScalars(colours)
    coordinate = vtk.vtkCoordinate()
    coordinate.SetCoordinateSystemToNormalizedViewport()
    mapper = vtk.vtkPolyDataMapper2D()
    mapper.SetInputData(box)
    mapper.SetTransformCoordinate(coordinate)
    mapper.SetScalarModeToUseCellData()
    actor = vtk.vtkActor2D()
    actor.SetMapper(mapper)
    return actor
