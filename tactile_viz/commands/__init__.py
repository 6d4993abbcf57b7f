"""The user commands, shared by the command line (``tactile_viz.__main__``) and the app's
launcher: ``trial`` (:mod:`.trial`), ``replay`` (:mod:`.replay`), ``library``
(:mod:`.library`), what they and ``tactile-viz app`` share (:mod:`.inputs`) and the lines
a trial or replay ends with (:mod:`.summary`).

They import the engine and :mod:`tactile_viz.cli`, never the benchmarks
(:mod:`tactile_viz.experiments`), which import them to run their trials.
"""
