"""The belief over object class and pose: the particle filter (paper, Algorithm 1),
its likelihood, hypotheses from point pairs, resampling, and the steps beyond the
paper that tell near twins apart and decide a known object.

The public names are exported by :mod:`tactile_viz.engine`."""
