"""The benchmarks, ``python -m tactile_viz bench NAME``: each a module with a
``main(argv)``, registered once here.

:data:`BENCHMARKS` maps a benchmark's name to its module and its one-line help, in the
order ``bench --help`` lists them; ``tactile_viz.__main__`` builds the ``bench`` command's
choices, help and dispatch from it (a module is imported only when its benchmark runs).
"""

BENCHMARKS = {
    "sdf": ("tactile_viz.experiments.sdf_speed", "grid SDF vs exact queries per second"),
    "step": ("tactile_viz.experiments.step_timing",
             "time of each part of a step at 50/200/400 contacts, full vs incremental GPIS"),
    "paper": ("tactile_viz.experiments.paper", "the paper's protocol, tables and plots"),
    "tradeoff": ("tactile_viz.experiments.tradeoff",
                 "time per trial vs errors over presets and knobs, Pareto front"),
    "scaling": ("tactile_viz.experiments.scaling",
                "time per step vs contacts and vs number of priors"),
    "noise": ("tactile_viz.experiments.noise", "recognition and pose error vs sensor noise"),
    "sizes": ("tactile_viz.experiments.sizes",
              "the objects at real sizes in one metric library vs the paper's scale"),
    "decide": ("tactile_viz.experiments.decide",
               "right at the decision, steps to it, known judged novel, on real sizes and hard "
               "pairs under noise"),
    "learn": ("tactile_viz.experiments.learn",
              "novel objects at real sizes left out, learned and met again"),
    "realmesh": ("tactile_viz.experiments.real_meshes",
                 "known/novel trials on meshes pybullet ships (extra realmesh)"),
    "gui": ("tactile_viz.experiments.gui_bench",
            "does the desktop app keep up with the engine (under Xvfb)"),
}

__all__ = ["BENCHMARKS"]
