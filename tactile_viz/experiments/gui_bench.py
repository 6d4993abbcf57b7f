"""``python -m tactile_viz bench gui``: does the desktop app keep up with the engine?

For each object (default: mug_1, a known object, and vase_2, a novel one) at one seed:

1. **engine** and **gui**, interleaved (engine, app, engine, ..., app, engine;
   ``--repeats`` app runs): the session stepped headless to termination (or
   ``--max-steps``), and run with *Run to termination* in the main window (stepping in the
   app's engine process, or with ``--engine thread`` in a worker thread), with the Qt
   event loop waiting for events as in the app. Wall time of each; for the app, from the
   click to the last step shown. The overhead is the mean app time over the mean engine
   time, with the t-interval of the mean of each app run against the engine runs either
   side of it (the machine's speed drifts). Also steps drawn, seconds of drawing per drawn
   step (the scene update, the viewport's render in the paint after it, and the plots' own
   draw pass) and the longest single drawing pass;
2. **loop gap**: once more with a 5 ms QTimer whose largest gap is the event loop's
   longest block from any cause (a separate run: the timer's 200 wake-ups a second cost
   the window's process time);
3. **pause**: *Run*, then *Pause* after a few steps: time from the click to the run's end
   being handled, and the part of it after the step in progress ended;
4. **close**: *Run*, then close the window after a few steps: how long ``close()`` takes,
   and the part of it after the step in progress ended.

Needs a display: run it under Xvfb (``xvfb-run -a python -m tactile_viz bench gui``).
The targets (issue 15): drawing adds at most 15% to the engine's wall time, no event-loop
block (and no drawing pass) over 150 ms, pause acts within the step in progress plus 150 ms,
closing within about a second of it.
"""

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

from ..app.engine_process import ENGINES
from ..cli import (
    ArgumentParser,
    ExtendList,
    add_preset_argument,
    bundled_object,
    count_int,
    int_range,
    seed_int,
    writable_output,
)
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.files import write_atomic

TARGET_OVERHEAD = 0.15
TARGET_BLOCK = 0.150
TARGET_PAUSE = 0.150
TARGET_CLOSE = 1.0


def window_size(text):
    """An argument type: ``WIDTHxHEIGHT`` in pixels, as a pair of ints."""
    side = int_range(100, 10_000)
    try:
        width, height = (side(part) for part in text.lower().split("x"))
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(
            f"a window size is WIDTHxHEIGHT, each 100 to 10000, got {text!r}") from None
    return width, height


def _parser():
    parser = ArgumentParser(prog="python -m tactile_viz bench gui",
                            description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", action=ExtendList, default=["mug_1", "vase_2"],
                        type=bundled_object(),
                        help="bundled objects to run (default: mug_1 known, vase_2 novel)")
    parser.add_argument("--seed", type=seed_int, default=0)
    add_preset_argument(parser)
    parser.add_argument("--strategy", default="gpis-dhd", choices=STRATEGIES)
    parser.add_argument("--max-steps", type=int_range(0), default=0,
                        help="cap the runs at this many steps (default 0: to termination)")
    parser.add_argument("--repeats", type=count_int, default=3,
                        help="app runs per object, interleaved with one engine run more "
                             "(default 3; the machine's speed drifts between runs)")
    parser.add_argument("--pause-after", type=count_int, default=5,
                        help="steps before Pause / close in the latency runs (default 5)")
    parser.add_argument("--size", default="1500x900", type=window_size,
                        help="window size (default 1500x900)")
    parser.add_argument("--engine", choices=ENGINES, default="process",
                        help="where the app steps: its engine process (default, as the app) "
                             "or a worker thread")
    parser.add_argument("--json", metavar="OUT", type=writable_output,
                        help="also write the results as JSON")
    return parser


class _LoopProbe:
    """A 5 ms QTimer recording the largest gap between its ticks (event-loop blocks)."""

    def __init__(self):
        from PySide6.QtCore import QTimer

        self.timer = QTimer()
        self.timer.setInterval(5)
        self.timer.timeout.connect(self._tick)
        self.last = None
        self.gaps = []

    def _tick(self):
        now = time.perf_counter()
        if self.last is not None:
            self.gaps.append(now - self.last)
        self.last = now

    def start(self):
        self.last, self.gaps = None, []
        self.timer.start()

    def stop(self):
        self.timer.stop()
        return sorted(self.gaps, reverse=True)


def _wait(app, condition, timeout):
    deadline = time.perf_counter() + timeout
    while not condition():
        if time.perf_counter() > deadline:
            raise TimeoutError("the GUI run did not finish in time")
        app.processEvents()
        time.sleep(0.001)


def _scene(args, name):
    from ..app.scene import Scene

    return Scene(name, seed=args.seed, strategy=args.strategy, preset=args.preset)


def _window(args, scene, settings):
    from ..gui.main_window import MainWindow

    window = MainWindow(scene, settings=settings, engine=args.engine)
    window.resize(*args.size)
    window.show()
    return window


def _engine_run(args, name):
    scene = _scene(args, name)
    session = scene.ensure_session()
    began = time.perf_counter()
    session.run(max_steps=args.max_steps or None)
    return time.perf_counter() - began, session.step_count


def _until_finished(window, timeout):
    """Run the Qt event loop until the window's run ends, as the app does: waiting for
    events, not polling."""
    from PySide6.QtCore import QEventLoop, QTimer

    loop = QEventLoop()
    window.runner.finished.connect(loop.quit)
    QTimer.singleShot(int(timeout * 1000), loop.quit)
    if window.running:
        loop.exec()
    window.runner.finished.disconnect(loop.quit)
    if window.running:
        raise TimeoutError("the GUI run did not finish in time")


def _gui_run(app, args, name, settings, probe=False):
    """Run to termination in a window; with ``probe`` a 5 ms timer records the event
    loop's gaps (its 200 wake-ups a second each take the interpreter from the engine's
    thread, so the run that times the app has none)."""
    window = _window(args, _scene(args, name), settings)
    app.processEvents()
    probe = _LoopProbe() if probe else None
    if probe is not None:
        probe.start()
    began = time.perf_counter()
    window.start(args.max_steps or None)
    _until_finished(window, 3600)
    wall = time.perf_counter() - began
    gaps = probe.stop() if probe is not None else []
    runner = window.runner
    steps = window.scene.latest.step
    shown = window.loop_panel.step_label.text()
    viewport = list(runner.draw_seconds)  # scene update of the drawn steps
    paint_log = [(start - began, seconds) for start, seconds in list(window.plotter.paint_log)
                 if start >= began]
    plots_log = [(start - began, seconds) for start, seconds in list(window.plots.draw_log)
                 if start >= began]
    paints = [seconds for _, seconds in paint_log]  # the render, in the paint after it
    plots = [seconds for _, seconds in plots_log]
    window.close()
    app.processEvents()
    passes = viewport + paints + plots
    drawn = max(runner.drawn, 1)
    return {"gui_seconds": wall, "steps": steps, "drawn": runner.drawn,
            "shown_last_step": shown.startswith(f"step {steps}"),
            "draw_per_step": sum(passes) / drawn,
            "drawing_seconds": sum(passes),
            "viewport_median": statistics.median(viewport) if viewport else 0.0,
            "paint_median": statistics.median(paints) if paints else 0.0,
            "plots_median": statistics.median(plots) if plots else 0.0,
            "longest_draw_pass": max(passes, default=0.0),
            # (seconds into the run, seconds) of the longest paint and plots pass
            "longest_paint": max(paint_log, key=lambda item: item[1], default=None),
            "longest_plots": max(plots_log, key=lambda item: item[1], default=None),
            "longest_viewport": max(viewport, default=0.0),
            "largest_loop_gap": gaps[0] if gaps else 0.0, "loop_gaps_top5": gaps[:5],
            "loop_gaps_over_150ms": sum(gap > TARGET_BLOCK for gap in gaps)}


def _interrupt_run(app, args, name, settings, how):
    """Run, then Pause (or close the window) once ``--pause-after`` steps have been taken."""
    window = _window(args, _scene(args, name), settings)
    app.processEvents()
    window.loop_panel.run_button.setChecked(True)
    runner = window.runner
    _wait(app, lambda: len(runner.step_ends) >= args.pause_after or not window.running, 600)
    clicked = time.perf_counter()
    if how == "pause":
        window.loop_panel.run_button.setChecked(False)
        _wait(app, lambda: not window.running, 600)
        done = runner.finished_at
        window.close()
    else:
        window.close()
        done = time.perf_counter()
    app.processEvents()
    # The step in progress at the click ends at the first step end after it (none: the
    # worker was between steps).
    ends_after = [t for t in runner.step_ends if t >= clicked]
    step_end = ends_after[0] if ends_after else clicked
    return {f"{how}_latency": done - clicked, f"{how}_after_step": max(0.0, done - step_end),
            f"{how}_extra_steps": max(0, len(ends_after) - 1)}


def _interval(values, confidence=0.95):
    """``(low, high)``: the t-based interval of the mean of ``values`` (None for fewer
    than two)."""
    if len(values) < 2:
        return None
    from scipy import stats

    mean, error = statistics.mean(values), statistics.stdev(values) / len(values) ** 0.5
    half = float(stats.t.ppf(0.5 + confidence / 2, len(values) - 1)) * error
    return [mean - half, mean + half]


def run(args):
    os.environ.setdefault("QT_QPA_PLATFORM", "xcb")
    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication

    app = QApplication.instance() or QApplication(sys.argv[:1])
    folder = tempfile.mkdtemp(prefix="tactile_viz-bench-gui-")
    settings = QSettings(os.path.join(folder, "settings.ini"), QSettings.IniFormat)
    rows = []
    for name in args.objects:
        _scene(args, name).ensure_session().step()  # warm the caches for both runs
        if args.engine == "process":  # start the engine process and give it the priors
            from ..app.engine_process import shared_engine

            warm = _scene(args, name).ensure_session()
            for _ in shared_engine().steps(warm, 1):
                pass
        engine_runs, runs = [], []
        for _ in range(args.repeats):  # engine, app, engine, ..., app, engine
            seconds, steps = _engine_run(args, name)
            engine_runs.append(seconds)
            runs.append(_gui_run(app, args, name, settings))
        engine_runs.append(_engine_run(args, name)[0])
        row = {"object": name, "engine_steps": steps, "load_average": os.getloadavg()[0],
               "cpus": os.cpu_count(), "engine": args.engine, "repeats": args.repeats}
        row.update(runs[0])
        for key in ("gui_seconds", "drawing_seconds", "draw_per_step"):
            row[key] = sum(run[key] for run in runs) / len(runs)
        row["gui_runs"] = [run["gui_seconds"] for run in runs]
        row["drawn_runs"] = [run["drawn"] for run in runs]
        row["longest_draw_pass"] = max(run["longest_draw_pass"] for run in runs)
        row["longest_passes_runs"] = [{key: run[key] for key in (
            "longest_viewport", "longest_paint", "longest_plots")} for run in runs]
        row["engine_runs"] = engine_runs
        row["engine_seconds"] = engine_seconds = statistics.mean(engine_runs)
        row["overhead"] = row["gui_seconds"] / engine_seconds - 1.0
        # Each app run against the engine runs either side of it (the machine's speed drifts).
        ratios = [run["gui_seconds"] / ((engine_runs[i] + engine_runs[i + 1]) / 2) - 1.0
                  for i, run in enumerate(runs)]
        row["overhead_runs"] = ratios
        row["overhead_interval"] = _interval(ratios)
        probed = _gui_run(app, args, name, settings, probe=True)
        for key in ("largest_loop_gap", "loop_gaps_top5", "loop_gaps_over_150ms"):
            row[key] = probed[key]
        row["longest_draw_pass"] = max(row["longest_draw_pass"], probed["longest_draw_pass"])
        row["probed_gui_seconds"] = probed["gui_seconds"]
        row.update(_interrupt_run(app, args, name, settings, "pause"))
        row.update(_interrupt_run(app, args, name, settings, "close"))
        rows.append(row)
        print(f"{name}: done", file=sys.stderr, flush=True)
    return rows


def format_table(rows):
    head = ("object", "steps", "engine s (runs)", "app s (runs)", "overhead (95% interval)",
            "drawn", "draw/step s", "longest draw s", "loop gap s (>150 ms)",
            "pause s (after step)", "close s (after step)")
    lines = [" | ".join(head), " | ".join("---" for _ in head)]
    for r in rows:
        interval = r.get("overhead_interval")
        spread = ("" if interval is None else
                  f" ({100 * interval[0]:+.1f} to {100 * interval[1]:+.1f})")
        lines.append(" | ".join([
            r["object"], str(r["steps"]),
            f"{r['engine_seconds']:.1f} ({' / '.join(f'{v:.1f}' for v in r['engine_runs'])})",
            f"{r['gui_seconds']:.1f} ({' / '.join(f'{v:.1f}' for v in r['gui_runs'])})",
            f"{100 * r['overhead']:+.1f}%{spread}",
            " / ".join(str(v) for v in r.get("drawn_runs", [r["drawn"]])),
            f"{r['draw_per_step']:.3f}", f"{r['longest_draw_pass']:.3f}",
            f"{r['largest_loop_gap']:.3f} ({r['loop_gaps_over_150ms']})",
            f"{r['pause_latency']:.2f} ({r['pause_after_step']:.3f})",
            f"{r['close_latency']:.2f} ({r['close_after_step']:.3f})"]))
    return "\n".join(lines)


def verdicts(rows):
    """The issue's targets, one line each: drawing overhead, the longest event-loop block
    (the 5 ms timer's largest gap, from any cause) and the longest drawing pass, pause and
    close after the step in progress."""
    def judge(value, limit):
        return "ok" if value <= limit else "over"

    lines = []
    for r in rows:
        lines.append(
            f"{r['object']}: overhead {100 * r['overhead']:+.1f}% "
            f"({judge(r['overhead'], TARGET_OVERHEAD)} 15%), "
            f"longest event-loop block {1000 * r['largest_loop_gap']:.0f} ms "
            f"({judge(r['largest_loop_gap'], TARGET_BLOCK)} 150 ms), "
            f"longest draw pass {1000 * r['longest_draw_pass']:.0f} ms "
            f"({judge(r['longest_draw_pass'], TARGET_BLOCK)} 150 ms), "
            f"pause after the step {1000 * r['pause_after_step']:.0f} ms "
            f"({judge(r['pause_after_step'], TARGET_PAUSE)} 150 ms), "
            f"close after the step {1000 * r['close_after_step']:.0f} ms "
            f"({judge(r['close_after_step'], TARGET_CLOSE)} 1 s)")
    return "\n".join(lines)


def main(argv=None):
    args = _parser().parse_args(argv)
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        print("python -m tactile_viz bench gui: error: needs a display; run it under Xvfb: "
              "xvfb-run -a python -m tactile_viz bench gui", file=sys.stderr)
        return 2
    try:
        import PySide6  # noqa: F401
        import pyvistaqt  # noqa: F401
    except ImportError as error:
        print(f"python -m tactile_viz bench gui: error: {error}; it needs the gui extra: "
              "pip install -e '.[gui]'", file=sys.stderr)
        return 2
    rows = run(args)
    print(format_table(rows))
    print(f"{rows[0]['cpus']} CPUs; 1-minute load average at the start of each object: "
          + ", ".join(f"{r['load_average']:.1f}" for r in rows))
    print(verdicts(rows))
    if args.json:
        command = "python -m tactile_viz bench gui " + " ".join(argv or sys.argv[3:])
        write_atomic(args.json, json.dumps({"command": command, "rows": rows,
                                            "verdicts": verdicts(rows).splitlines()},
                                           indent=2).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
