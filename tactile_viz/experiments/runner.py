"""Running many trials: task descriptions, one code path per trial, and three ways to run
them (in this process, in a local process pool, on a Dask distributed cluster).

A *task* is a plain dict (picklable, mostly JSON)::

    {"kind": "protocol", "object": "mug_1", "strategy": "gpis-dhd", "seed": 0,
     "preset": "recommended", "library": "known", "extra_priors": [], "params": None,
     "max_steps": None, "poisson": True, "learn_as": None}

``sizes`` (optional) maps bundled names to a longest side in scene units (metres in
``bench sizes``): the object and the bundled priors of those names are scaled to it.
``extra_priors`` holds ``{"name", "vertices", "faces"}`` models added to the bundled library
(the learned prior travels this way, so remote workers need no shared disk); ``params`` is a
``SessionParams.to_dict()`` that replaces the preset's values.

A task may also take its meshes from files (``bench realmesh``, ``bench decide``):
``object_file`` names the object's mesh, an extra prior may be ``{"name", "file"}`` (and its
own ``"longest_side"``), and both are scaled to the task's ``longest_side`` (None keeps the
file's size); an extra prior ``{"name", "bundled", "longest_side"}`` is a bundled object at
that size. Files are read where the task runs
(a local disk), once per process. ``library`` may be ``none`` (no bundled priors).

``scene`` (optional) is a :meth:`~tactile_viz.engine.scene.Scene.as_dict` record: the
object rests on its table and is probed with its tip within its reach cone.

:func:`run_task` runs one task through :func:`~tactile_viz.commands.trial.run_trial` and
adds what the benchmarks need (final contacts and normals, the Screened Poisson baseline,
the learned surface). Every random choice comes from the task's seed, so where a task runs
does not change its result (only the timing fields differ).
"""

import concurrent.futures as cf
import functools
import multiprocessing
import sys
import traceback
import warnings

import numpy as np

from ..cli import one_line_warning
from ..threads import one_blas_thread

TIMING_KEYS = ("seconds", "step_seconds", "timings")


def make_task(object_name, strategy="gpis-dhd", seed=0, preset="recommended", kind="protocol",
              library="known", extra_priors=(), params=None, max_steps=None, poisson=False,
              learn_as=None, poisson_depth=9, sizes=None, sensor=None, object_file=None,
              longest_side=None, scene=None):
    """A task dict (see the module docstring)."""
    task = {"kind": kind, "object": object_name, "strategy": strategy, "seed": int(seed),
            "preset": preset, "library": library, "extra_priors": list(extra_priors),
            "params": params, "max_steps": max_steps, "poisson": bool(poisson),
            "poisson_depth": int(poisson_depth), "learn_as": learn_as}
    if sizes:
        task["sizes"] = {str(name): float(size) for name, size in sizes.items()}
    if sensor and any(value for value in sensor.values()):
        task["sensor"] = dict(sensor)
    if object_file is not None:
        task["object_file"] = str(object_file)
    if longest_side is not None:
        task["longest_side"] = float(longest_side)
    return with_scene(task, scene)


def with_scene(task, scene):
    """``task`` with the robot's ``scene`` (a Scene, its dict, or None: free space, no key)."""
    if scene is not None and not isinstance(scene, dict):
        scene = None if scene.is_free else scene.as_dict()
    if scene is not None:
        task["scene"] = dict(scene)
    return task


def scene_label(record):
    """A short file-name-safe label of a task's scene record: ``table0-reach60-tip0.005``."""
    parts = []
    if record.get("table_point") is not None:
        point, up = record["table_point"], record.get("up", (0.0, 0.0, 1.0))
        parts.append("table" + "_".join(f"{v:g}" for v in point)
                     if list(up) != [0.0, 0.0, 1.0] or any(point[:2])
                     else f"table{point[2]:g}")
    if record.get("reach_angle_deg", 180.0) < 180.0:
        parts.append(f"reach{record['reach_angle_deg']:g}")
    if record.get("tip_radius", 0.0) > 0:
        parts.append(f"tip{record['tip_radius']:g}")
    return "-".join(parts) or "free"


def library_label(task):
    """``known`` or ``known+NAME+...`` for the bundled set plus the extra priors."""
    return "+".join([task["library"]] + [p["name"] for p in task["extra_priors"]])


def task_key(task):
    """A file-name-safe key that identifies a task within one benchmark run."""
    tag = task.get("tag")
    parts = [task["kind"], task["object"], task["strategy"], library_label(task),
             task["preset"] + (f"-{tag}" if tag else ""), f"s{task['seed']}"]
    if task["max_steps"] is not None:
        parts.append(f"m{task['max_steps']}")
    if task.get("sizes"):
        parts.append("sized")
    if task.get("sensor"):
        parts.append("noise-" + "-".join(f"{v:g}" for v in task["sensor"].values()
                                         if v is not None))
    if task.get("scene"):
        parts.append("scene-" + scene_label(task["scene"]))
    return "__".join(parts)


@functools.lru_cache(maxsize=8)
def _bundled_library(which, sizes=()):
    from ..engine.shape.library import PriorLibrary
    from ..engine.shape.objects import bundled_names

    names = [] if which == "none" else bundled_names(which)
    return PriorLibrary(_bundled_model(name, dict(sizes).get(name)) for name in names)


@functools.lru_cache(maxsize=64)
def _bundled_model(name, size=None):
    from ..engine.shape.objects import load_bundled

    return load_bundled(name, size=size)


@functools.lru_cache(maxsize=64)
def _file_model(path, name, longest_side=None):
    from ..engine.shape.objects import ObjectModel

    return ObjectModel.from_file(path, name=name, longest_side=longest_side)


def _sizes(task):
    return tuple(sorted((task.get("sizes") or {}).items()))


def task_library(task):
    """The :class:`PriorLibrary` of a task: a bundled set plus its extra priors."""
    from ..engine.shape.library import PriorLibrary
    from ..engine.shape.objects import OWN_ERRORS

    library = PriorLibrary(list(_bundled_library(task["library"], _sizes(task))))
    for prior in task["extra_priors"]:
        if "bundled" in prior:
            library.add(_bundled_model(prior["bundled"], prior.get("longest_side")))
            continue
        if "file" in prior:
            library.add(_file_model(prior["file"], prior["name"],
                                    prior.get("longest_side", task.get("longest_side"))))
            continue
        library.add_arrays(np.asarray(prior["vertices"]), np.asarray(prior["faces"]),
                           prior["name"], longest_side=None,
                           learned=prior.get("learned", True),
                           **{name: prior[name] for name in OWN_ERRORS if name in prior})
    return library


def _finisher(task):
    """The ``finish`` callback of :func:`run_trial` for a task."""

    def finish(session):
        from ..engine.shape.metrics import surface_samples
        from ..engine.transforms import transform_points

        last = session.latest
        extra = {"final": {"contacts": last.contacts.tolist(), "normals": last.normals.tolist(),
                           "noncontacts": int(len(last.noncontacts))}}
        if task["poisson"]:
            from .poisson import poisson_error

            truth = session.truth
            samples = transform_points(surface_samples(truth.model,
                                                       session.params.metric_samples),
                                       truth.rotation, truth.translation)
            extra["poisson"] = poisson_error(last.contacts, last.normals, samples,
                                             session.params.metric_samples,
                                             task.get("poisson_depth", 9))
        if task["learn_as"]:
            try:
                model = session.learned_model(task["learn_as"])
                extra["learned"] = {"name": model.name, "vertices": model.mesh.vertices.tolist(),
                                    "faces": model.mesh.faces.tolist(),
                                    **model.own_errors()}
            except Exception as error:  # not novel, no surface, or a mesh the loader refuses
                extra["learned"] = {"name": task["learn_as"], "error": str(error)}
        return extra

    return finish


def task_object(task):
    """The truth :class:`ObjectModel` of a task: its ``object_file`` or a bundled object."""
    if task.get("object_file"):
        return _file_model(task["object_file"], task["object"], task.get("longest_side"))
    return _bundled_model(task["object"], dict(_sizes(task)).get(task["object"]))


def run_task(task, progress=False):
    """Run one task; returns the trial result dict with ``task`` (and ``error`` on failure).

    Never raises for a failing trial: the traceback is returned under ``error`` so that a
    long benchmark keeps its other results.
    """
    from ..commands.trial import run_trial
    from ..engine.scene import Scene
    from ..engine.session import SessionParams

    meta = {key: value for key, value in task.items() if key != "extra_priors"}
    meta["library_label"] = library_label(task)
    try:
        params = SessionParams.from_dict(task["params"]) if task["params"] else None
        result = run_trial(task_object(task), task_library(task),
                           task["strategy"], task["seed"], task["preset"], task["max_steps"],
                           progress=progress, params=params, finish=_finisher(task),
                           sensor=task.get("sensor"),
                           scene=Scene.from_dict(task["scene"]) if task.get("scene") else None)
    except Exception:
        return {"object": task["object"], "seed": task["seed"], "strategy": task["strategy"],
                "task": meta, "error": traceback.format_exc()}
    result["task"] = meta
    return result


def strip_timings(value):
    """A copy of a result without its timing fields (they differ from run to run)."""
    if isinstance(value, dict):
        return {k: strip_timings(v) for k, v in value.items() if k not in TIMING_KEYS}
    if isinstance(value, list):
        return [strip_timings(v) for v in value]
    return value


# ------------------------------------------------------------------------------- pools
class SerialPool:
    """Runs each task in this process when it is waited for (shows per-step progress)."""

    def __init__(self, progress=False):
        self.progress = progress
        self._pending = {}

    def submit(self, task):
        future = cf.Future()
        self._pending[future] = task
        return future

    def wait_any(self, futures):
        for future in futures:  # the first pending one in the order given
            if not future.done():
                future.set_result(run_task(self._pending.pop(future), self.progress))
                break
        done = [f for f in futures if f.done()]
        return done, [f for f in futures if not f.done()]

    def close(self):
        self._pending.clear()


def _limit_threads():
    """One BLAS/OpenMP thread per worker process (they thrash when processes compete)."""
    one_blas_thread()


def one_line_warnings_in_worker(prog):
    """Show a worker process's Python warnings as one line, as the command that started it
    does (:func:`~tactile_viz.cli.one_line_warning`)."""
    warnings.showwarning = one_line_warning(prog)


class ProcessPool:
    """A local pool of ``workers`` processes (spawned, one BLAS thread each)."""

    def __init__(self, workers):
        _limit_threads()  # inherited by the spawned workers before they import numpy
        # A command's one-line warnings (``python -m tactile_viz``) hold in its workers too.
        prog = getattr(warnings.showwarning, "prog", None)
        self.executor = cf.ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
            initializer=None if prog is None else one_line_warnings_in_worker,
            initargs=() if prog is None else (prog,))

    def submit(self, task):
        return self.executor.submit(run_task, task)

    def wait_any(self, futures):
        done, pending = cf.wait(futures, return_when=cf.FIRST_COMPLETED)
        return set(done), set(pending)

    def close(self):
        interrupted = sys.exc_info()[0] is not None  # closing while an exception unwinds
        if interrupted:
            # Ctrl-C: running trials can take minutes; waiting for them (or leaving the
            # workers to finish on their own) would keep the cores busy after the run died.
            for process in list(getattr(self.executor, "_processes", {}).values()):
                process.terminate()
        self.executor.shutdown(wait=not interrupted, cancel_futures=True)


class DaskPool:
    """Tasks on a Dask distributed cluster (``tcp://host:port``, or a ``Client``)."""

    def __init__(self, scheduler):
        try:
            from distributed import Client
        except ImportError:
            raise SystemExit("--scheduler needs Dask distributed: pip install "
                             "'tactile_viz[bench]' (or pip install 'dask[distributed]')") from None
        self.own_client = not hasattr(scheduler, "submit")
        self.client = Client(scheduler) if self.own_client else scheduler

    def submit(self, task):
        return self.client.submit(run_task, task, pure=False)

    def wait_any(self, futures):
        from distributed import wait

        result = wait(list(futures), return_when="FIRST_COMPLETED")
        return set(result.done), set(result.not_done)

    def close(self):
        if self.own_client:
            self.client.close()


def open_pool(workers=1, scheduler=None, progress=False):
    """A Dask pool when ``scheduler`` is given, else a process pool for ``workers`` > 1,
    else a serial pool."""
    if scheduler is not None:
        return DaskPool(scheduler)
    if workers > 1:
        return ProcessPool(workers)
    return SerialPool(progress)


def run_tasks(tasks, pool, follow_up=None, progress=True, description="trials"):
    """Run tasks on a pool and yield ``(task, result)`` as each one finishes.

    Parameters
    ----------
    tasks : list of dict
    pool : SerialPool, ProcessPool or DaskPool
    follow_up : callable, optional
        ``follow_up(task, result)`` returns further tasks to submit (e.g. the trials with a
        learned prior once the trial that learns it is done).
    progress : bool
        A progress bar over trials on stderr.
    """
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc=description, unit="trial", file=sys.stderr,
               disable=not progress)
    futures = {pool.submit(task): task for task in tasks}
    try:
        while futures:
            done = set(pool.wait_any(list(futures))[0])
            for future in [f for f in futures if f in done]:  # in submission order
                task = futures.pop(future)
                result = future.result()
                bar.update(1)
                bar.set_postfix_str(f"{task['object']} {task['strategy']} s{task['seed']}"
                                    f"{' FAILED' if 'error' in result else ''}")
                for extra in (follow_up(task, result) if follow_up else []):
                    futures[pool.submit(extra)] = extra
                    bar.total += 1
                    bar.refresh()
                yield task, result
    finally:
        bar.close()


def run_all(tasks, workers=1, progress=True, description="trials"):
    """Run every task on a local pool of ``workers``; returns ``(results, failed)``, the
    failed trials' tracebacks printed (a long benchmark keeps the others)."""
    pool = open_pool(workers)
    try:
        results = [result for _, result in run_tasks(tasks, pool, progress=progress,
                                                     description=description)]
    finally:
        pool.close()
    failed = [r for r in results if "error" in r]
    for result in failed:
        print(f"trial {result['object']} s{result['seed']} failed:\n{result['error']}")
    return [r for r in results if "error" not in r], failed
