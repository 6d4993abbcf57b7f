#!/usr/bin/env python3
"""Desktop launcher for tactile_viz: a thin wrapper around tactile_viz.gui."""

from __future__ import annotations

import argparse
import os
import sys

GUI_HINT = "the desktop app needs the GUI extra: pip install -e '.[gui]'"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="tactile_viz desktop app")
    parser.add_argument("--object", default="mug_1", metavar="NAME", help="bundled object to show")
    parser.add_argument(
        "--screenshot",
        metavar="FILE",
        help="render, save a PNG of the 3D viewport to FILE and exit (no event loop)",
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    try:
        from PySide6.QtWidgets import QApplication

        from tactile_viz.gui.viewer import ViewerWindow
    except ImportError as exc:
        print(f"error: {exc}\n{GUI_HINT}", file=sys.stderr)
        return 2

    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        print(
            "error: no display (DISPLAY is not set); on a headless machine run it "
            "under Xvfb, e.g. `xvfb-run -a make run`",
            file=sys.stderr,
        )
        return 2

    from tactile_viz.engine.objects import load_bundled

    model = load_bundled(args.object)
    mesh = model.mesh

    app = QApplication.instance() or QApplication(sys.argv[:1])
    window = ViewerWindow(mesh, name=args.object)

    if args.screenshot:
        window.show()
        app.processEvents()
        window.screenshot(args.screenshot)
        window.close()
        app.processEvents()
        print(f"saved {args.screenshot}")
        return 0

    window.show()
    return app.exec()


if __name__ == "__main__":
    sys.exit(main())
