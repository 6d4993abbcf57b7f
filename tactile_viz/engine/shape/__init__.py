"""Shapes: meshes and their repair, object models with their signed distance, the
prior library, symmetries and shape distances, and the GPIS reconstruction of a
novel shape (paper, Section III-E).

The public names are exported by :mod:`tactile_viz.engine`."""
