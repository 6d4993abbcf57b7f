"""Files in and out: atomic writes, the derived-data cache, saved sessions, recorded
touches (CSV, ROS 2 bags) and exports.

The public names are exported by :mod:`tactile_viz.engine`."""
