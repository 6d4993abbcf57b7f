"""Building the priors' derived data (SDF grids, features, point pairs) in child processes.

A prior bank built from meshes in the process that then uses it ended larger than one read
from the disk cache: with 1,000 priors, 3.3 GB resident against 1.3 GB. Most of it was
trimesh's arrays left on each mesh by the feature sampling (now sampled on a bare copy);
the rest is the allocator's fragments of libigl's threaded distance queries (some 0.25 MB
a prior, which ``malloc_trim`` does not return). When several priors lack their cache
entries, child interpreters, one a core, build them into the disk cache and exit; the bank
then reads every prior from the cache, exactly as a warm load does.

Each child is a plain ``python -m tactile_viz.engine.belief.prior_build FILE``, not
multiprocessing: it never re-imports the caller's main script, and a daemonic process may
start it. The priors go to the children through one temporary pickle file (name, vertices,
faces, parameters and cache folder of each). The parent hands a child the file offset of
one prior on its stdin and the next as soon as it answers (one line on stdout per prior
built), so a child held up by a slow prior (a refined grid) leaves the rest to the others.
A child that fails writes one line on stderr naming the prior and the fault and stops; the
parent then hands out no more priors, lets the others finish the one they hold and raises
that line. A prior's cache entries are the same bytes whichever process builds it: the
same code on the same arrays (``tests/engine/belief/test_prior_build.py`` compares the files).
"""

from __future__ import annotations

import os
import pickle
import selectors
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from ..errors import LibraryError
from ..io.cache import ArrayCache

CHILD_MIN = 4  # priors to build below which the build stays in this process
# A child's peak: 230 MB of interpreter and libraries, 90 MB more for a refined 2-million-
# node grid (the largest, sdf_build.MAX_REFINED_NODES); no more children than memory holds.
CHILD_BYTES = 400e6
# libigl splits each query over this many threads (default: every core). With one child a
# core each gets two: more would crowd the cores, one would leave a core idle while the
# last child finishes a slow prior alone (16 scan-like priors: 31.6 s against 36.4 s).
IGL_THREADS = "IGL_NUM_THREADS"


def build_derived(model, distance_step, angle_step_deg):
    """Build (or read) ``model``'s grid, features, pair table and inertia, keeping none of
    the build's temporaries; what the disk cache holds afterwards is what a prior bank and
    its decisions read."""
    with model.transient_exact():
        model.load_sdf()
        model.features  # noqa: B018 (a cached property: computed and stored)
        model.pair_table(distance_step, angle_step_deg, keep=False)
        model.inertia  # noqa: B018


def missing(models, distance_step, angle_step_deg):
    """The models with a disk cache that lacks some of their derived data."""
    return [model for model in models if model.cache.folder is not None
            and not model.derived_stored(distance_step, angle_step_deg)]


def default_workers(count):
    """How many child processes build ``count`` priors: one a core, at most one a prior, and
    no more than the available memory holds (:data:`CHILD_BYTES` each)."""
    workers = min(count, os.cpu_count() or 1)
    available = _available_bytes()
    if available is not None:
        workers = min(workers, int(available // CHILD_BYTES))
    return max(1, workers)


def _available_bytes():
    """Memory the system can give without swapping (Linux ``MemAvailable``; None
    elsewhere)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def build_in_child(models, distance_step, angle_step_deg, progress=None, minimum=CHILD_MIN,
                   workers=None):
    """Build in child processes the derived data that ``models`` lack in their disk cache,
    when at least ``minimum`` of them do.

    Parameters
    ----------
    models : sequence of ObjectModel
    distance_step : float
        Point-pair distance key step, scene units.
    angle_step_deg : float
    progress : callable, optional
        Wraps an iteration over the priors being built, one item as each is done (for
        example ``tqdm``).
    minimum : int
    workers : int, optional
        Child processes; default :func:`default_workers` (one a core).

    Returns
    -------
    int
        How many priors the children built (0: none was started).

    Raises
    ------
    LibraryError
        One line naming the prior and the fault, if a child failed.
    """
    todo = missing(models, distance_step, angle_step_deg)
    if len(todo) < max(minimum, 1) or not sys.executable or getattr(sys, "frozen", False):
        return 0
    workers = max(1, min(len(todo), workers or default_workers(len(todo))))
    with tempfile.TemporaryDirectory(prefix="tactile_viz-build-") as folder:
        priors, offsets = Path(folder) / "priors.pickle", []
        with open(priors, "wb") as stream:
            pickle.dump((float(distance_step), float(angle_step_deg)), stream)
            for model in todo:  # one at a time: no second copy of every mesh at once
                offsets.append(stream.tell())
                pickle.dump((model.name, np.asarray(model.mesh.vertices),
                             np.asarray(model.mesh.faces), model.params,
                             str(model.cache.folder)), stream, pickle.HIGHEST_PROTOCOL)
        _run(priors, offsets, [model.name for model in todo], workers, progress)
    return len(todo)


def build_missing(models, distance_step, angle_step_deg, progress=None, minimum=CHILD_MIN):
    """Build the derived data ``models`` lack in their disk cache without loading it here:
    in child processes when at least ``minimum`` lack it (:func:`build_in_child`), else in
    this process one after another. ``progress`` wraps the iteration over the priors built.
    Returns how many were built."""
    built = build_in_child(models, distance_step, angle_step_deg, progress, minimum)
    if built:
        return built
    todo = missing(models, distance_step, angle_step_deg)
    for model in progress(todo) if progress and todo else todo:
        build_derived(model, distance_step, angle_step_deg)
    return len(todo)


def _child_environment(workers):
    package_root = str(Path(__file__).resolve().parents[3])
    path = os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")]))
    environment = {**os.environ, "PYTHONPATH": path}
    if workers > 1:
        cores = os.cpu_count() or 1
        environment.setdefault(IGL_THREADS, str(max(2, -(-cores // workers))))
    return environment


def _run(priors, offsets, names, workers, progress):
    environment = _child_environment(workers)
    children, errors, built, finished = [], [], None, False
    try:
        for _ in range(workers):
            errors.append(tempfile.TemporaryFile("w+"))
            children.append(subprocess.Popen(
                [sys.executable, "-m", __name__, str(priors)], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, stderr=errors[-1], text=True, env=environment))
        built = _Built(children, offsets)
        for _ in progress(built) if progress else built:
            pass
        finished = True
    finally:
        for child in children:
            if not finished and child.poll() is None:
                child.kill()  # interrupted (Ctrl-C): leave nothing running
            for pipe in (child.stdin, child.stdout):
                _close(pipe)
            child.wait()
    if built.failure is not None:
        child, index = built.failure
        errors[children.index(child)].seek(0)
        lines = [line.strip() for line in errors[children.index(child)] if line.strip()]
        for stream in errors:
            stream.close()
        what = "a child process" if workers == 1 else f"{workers} child processes"
        raise LibraryError(f"building the grids of {len(offsets)} priors in {what} failed: "
                           f"{_reason(names[index], child.returncode, lines)}")
    for stream in errors:
        stream.close()


def _reason(name, status, lines):
    """The one line that says which prior stopped a child, and why."""
    if status is not None and status < 0:
        reason = f"it was killed by signal {-status} (out of memory?)"
    else:
        reason = lines[-1] if lines else f"it stopped with status {status}"
    prefix = f"prior {name!r}: "
    return reason if reason.startswith(prefix) else prefix + reason


def _close(pipe):
    try:
        pipe.close()
    except OSError:  # a child that died leaves a broken pipe
        pass


class _Built:
    """Iterating hands out the priors, one to each idle child, and yields each prior's index
    as its child reports it built. A child that stops without its line has failed: no more
    priors are handed out, the others finish theirs, and ``failure`` holds
    ``(child, index)``."""

    def __init__(self, children, offsets):
        self.children, self.offsets = children, offsets
        self.failure = None

    def __len__(self):
        return len(self.offsets)

    def __iter__(self):
        pending = iter(range(len(self.offsets)))
        working = {}  # child -> the index of the prior it builds
        with selectors.DefaultSelector() as selector:
            for child in self.children:
                selector.register(child.stdout, selectors.EVENT_READ, child)
                self._hand(child, pending, working)
            while working:
                for key, _ in selector.select():
                    child = key.data
                    index = working.pop(child, None)
                    if child.stdout.readline():
                        yield index
                        self._hand(child, pending, working)
                        continue
                    selector.unregister(child.stdout)
                    if index is not None and self.failure is None:
                        self.failure = (child, index)
                        pending = iter(())
                        for other in self.children:
                            _close(other.stdin)  # each stops after the prior it holds

    def _hand(self, child, pending, working):
        index = next(pending, None) if self.failure is None else None
        if index is None:
            _close(child.stdin)
            return
        try:
            child.stdin.write(f"{self.offsets[index]}\n")
            child.stdin.flush()
        except OSError:  # it died before asking: its missing line reports it
            pass
        working[child] = index


def main(argv=None):
    """A child: build each prior whose offset in the pickle file (the one argument) comes on
    stdin, one a line, answering its name on stdout; stop at the end of stdin."""
    from ..shape.objects import ObjectModel

    (path,) = sys.argv[1:] if argv is None else argv
    with open(path, "rb") as stream:
        distance_step, angle_step_deg = pickle.load(stream)
        for line in iter(sys.stdin.readline, ""):
            stream.seek(int(line))
            name, vertices, faces, params, folder = pickle.load(stream)
            model = ObjectModel(name, trimesh.Trimesh(vertices, faces, process=False),
                                params, ArrayCache(folder))
            try:
                build_derived(model, distance_step, angle_step_deg)
            except Exception as error:  # one line for the parent; a bug shows its type
                fault = " ".join(str(error).split()) or "no message"
                print(f"prior {name!r}: {type(error).__name__}: {fault}", file=sys.stderr)
                return 1
            print(name.encode("unicode_escape").decode(), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
