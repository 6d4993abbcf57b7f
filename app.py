#!/usr/bin/env python3
"""The desktop app from a clone: ``python app.py [options]`` runs what the installed
``tactile-viz app [options]`` runs (:mod:`tactile_viz.launcher`; ``--help`` lists the
options)."""

import sys

from tactile_viz.launcher import (  # noqa: F401
    build_scene,
    load_priors,
    log_errors_shown,
    main,
    parse_args,
    scene_from_args,
)

if __name__ == "__main__":
    sys.exit(main())
