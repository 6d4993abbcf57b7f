"""Off-screen contact sheets of the bundled objects (for the README).

``python -m tactile_viz.gui.object_sheet [--out screenshots]`` writes
``objects_known.png`` and ``objects_novel.png``; no display is needed.
"""

import argparse
from pathlib import Path

import pyvista as pv

from ..engine.shape.objects import bundled_manifest, load_bundled
from .layers import faces_to_polydata

COLUMNS = 5


def render_sheet(names, path, tile=300):
    """Render the named bundled objects in a grid of tiles and save a PNG."""
    rows = -(-len(names) // COLUMNS)
    plotter = pv.Plotter(off_screen=True, shape=(rows, COLUMNS),
                         window_size=(COLUMNS * tile, rows * tile), border=False)
    for index, name in enumerate(names):
        plotter.subplot(index // COLUMNS, index % COLUMNS)
        plotter.set_background("white")
        mesh = load_bundled(name).mesh
        plotter.add_mesh(faces_to_polydata(mesh.vertices, mesh.faces), color="tan",
                         smooth_shading=True)
        plotter.add_text(name, font_size=10, color="black")
        plotter.view_isometric()
        plotter.camera.zoom(0.95)
    plotter.screenshot(str(path))
    plotter.close()
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="screenshots", help="output folder")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    entries = bundled_manifest()
    for which in ("known", "novel"):
        names = [entry["name"] for entry in entries if entry["set"] == which]
        print("saved", render_sheet(names, out / f"objects_{which}.png"))


if __name__ == "__main__":
    main()
