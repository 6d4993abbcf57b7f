"""The touch: tactile observations, the simulated point sensor, and where to touch
next (paper, Section III-F).

The public names are exported by :mod:`tactile_viz.engine`."""
