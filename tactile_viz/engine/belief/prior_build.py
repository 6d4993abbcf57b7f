"""Building the priors' derived data (SDF grids, features, point pairs) in a child process.

A prior bank built from meshes in the process that then uses it ended larger than one read
from the disk cache: with 1,000 priors, 3.3 GB resident against 1.3 GB. Most of it was
trimesh's arrays left on each mesh by the feature sampling (now sampled on a bare copy);
the rest is the allocator's fragments of libigl's threaded distance queries (some 0.25 MB
a prior, which ``malloc_trim`` does not return). When many priors lack their cache
entries, a child interpreter builds them into the disk cache and exits; the bank then reads
every prior from the cache, exactly as a warm load does.

The child is a plain ``python -m tactile_viz.engine.belief.prior_build FILE``, not
multiprocessing: it never re-imports the caller's main script, and a daemonic process may
start it. The priors go to it through a temporary pickle file (name, vertices, faces,
parameters and cache folder, one after another); it answers one line on stdout per prior
built and, on failure, one line on stderr naming the prior and the fault.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from ..io.cache import ArrayCache
from ..errors import LibraryError

CHILD_MIN = 20  # priors to build below which the build stays in this process


def build_derived(model, distance_step, angle_step_deg):
    """Build (or read) ``model``'s grid, features and pair table, keeping none of the build's
    temporaries; what the disk cache holds afterwards is what a prior bank reads."""
    with model.transient_exact():
        model.load_sdf()
        model.features  # noqa: B018 (a cached property: computed and stored)
        model.pair_table(distance_step, angle_step_deg, keep=False)


def missing(models, distance_step, angle_step_deg):
    """The models with a disk cache that lacks some of their derived data."""
    return [model for model in models if model.cache.folder is not None
            and not model.derived_stored(distance_step, angle_step_deg)]


def build_in_child(models, distance_step, angle_step_deg, progress=None, minimum=CHILD_MIN):
    """Build in a child process the derived data that ``models`` lack in their disk cache,
    when at least ``minimum`` of them do.

    Parameters
    ----------
    models : sequence of ObjectModel
    distance_step : float
        Point-pair distance key step, scene units.
    angle_step_deg : float
    progress : callable, optional
        Wraps an iteration over the priors being built (for example ``tqdm``).
    minimum : int

    Returns
    -------
    int
        How many priors the child built (0: it was not started).

    Raises
    ------
    LibraryError
        One line naming the prior and the fault, if the child failed.
    """
    todo = missing(models, distance_step, angle_step_deg)
    if len(todo) < max(minimum, 1) or not sys.executable or getattr(sys, "frozen", False):
        return 0
    with tempfile.TemporaryDirectory(prefix="tactile_viz-build-") as folder:
        priors, errors = Path(folder) / "priors.pickle", Path(folder) / "errors.txt"
        with open(priors, "wb") as stream:
            pickle.dump((float(distance_step), float(angle_step_deg), len(todo)), stream)
            for model in todo:  # one at a time: no second copy of every mesh at once
                pickle.dump((model.name, np.asarray(model.mesh.vertices),
                             np.asarray(model.mesh.faces), model.params,
                             str(model.cache.folder)), stream, pickle.HIGHEST_PROTOCOL)
        _run(priors, errors, len(todo), progress)
    return len(todo)


def _run(priors, errors, count, progress):
    package_root = str(Path(__file__).resolve().parents[3])
    path = os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")]))
    with open(errors, "w") as stderr:
        child = subprocess.Popen([sys.executable, "-m", __name__, str(priors)],
                                 stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                 stderr=stderr, text=True,
                                 env={**os.environ, "PYTHONPATH": path})
        with child:
            for _ in progress(range(count)) if progress else range(count):
                if not child.stdout.readline():
                    break
            child.stdout.read()
    if child.returncode:
        lines = [line.strip() for line in errors.read_text().splitlines() if line.strip()]
        if child.returncode < 0:
            reason = f"it was killed by signal {-child.returncode} (out of memory?)"
        else:
            reason = lines[-1] if lines else f"it stopped with status {child.returncode}"
        raise LibraryError(f"building the grids of {count} priors in a child process "
                           f"failed: {reason}")


def main(argv=None):
    """The child: build every prior of the pickle file named by the one argument."""
    from ..shape.objects import ObjectModel

    (path,) = sys.argv[1:] if argv is None else argv
    with open(path, "rb") as stream:
        distance_step, angle_step_deg, count = pickle.load(stream)
        for _ in range(count):
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
