"""One headless trial: ``python -m tactile_viz trial ...``.

Its JSON is what scripts and the benchmarks read, so its keys only grow: the set-up
(``object``, ``seed``, ``strategy``, ``preset``, ``params``, ``library``, ``truth_pose``,
``code_version``), ``terminated_at``, ``seconds`` and ``steps``, one
:meth:`~tactile_viz.engine.Snapshot.record` per step (``t``, ``map_class``, ``pose_error``,
``dhd``, ``novel``, ``recon_error``, ...). ``tests/engine/test_session.py`` checks the keys.
"""

import functools
import json
import subprocess
import sys
import time
from pathlib import Path

from ..cli import (ExtendList, bundled_object, existing_dir, existing_file, output_dir,
                   positive_int, seed_int, writable_output)
from ..engine.errors import LibraryError, ParameterError
from ..engine.exploration import STRATEGIES
from ..engine.export import export_session
from ..engine.files import write_atomic
from ..engine.library import PriorLibrary
from ..engine.objects import ObjectModel, bundled_names, load_bundled
from ..engine.session import SESSION_PRESETS, Session, make_truth, session_preset


def add_prior_arguments(parser):
    """``--library`` or ``--library-dir``, plus any ``--prior-file`` (see :func:`load_priors`)."""
    priors = parser.add_mutually_exclusive_group()
    priors.add_argument("--library", choices=["known", "novel", "all"], default=None,
                        help="the filter's priors: a bundled set (default known)")
    priors.add_argument("--library-dir", metavar="DIR", type=existing_dir,
                        help="a saved prior library folder")
    parser.add_argument("--prior-file", metavar="MESH", action=ExtendList, type=existing_file,
                        help="mesh files added to --library or --library-dir as priors; "
                             "alone, the only priors (repeats add up)")


def add_output_arguments(parser, export_help):
    parser.add_argument("--json", metavar="OUT", type=writable_output,
                        help="write the JSON here (default stdout)")
    parser.add_argument("--export", metavar="DIR", type=output_dir, help=export_help)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def add_trial_arguments(parser):
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--object", metavar="NAME", type=bundled_object(),
                      help="a bundled object (see `objects`)")
    what.add_argument("--object-file", metavar="MESH", type=existing_file,
                      help="any mesh file trimesh reads")
    add_prior_arguments(parser)
    parser.add_argument("--strategy", choices=STRATEGIES, default="gpis-dhd")
    parser.add_argument("--seed", type=seed_int, default=0,
                        help="pose, exploration and filter seed")
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="stop after this many steps (default: the paper's caps 300/400)")
    parser.add_argument("--preset", choices=list(SESSION_PRESETS), default="paper",
                        help="speed/accuracy preset (default paper)")
    add_output_arguments(parser, "write observations.csv, map_shape.ply, reconstruction.ply "
                                 "(when novel) and estimate.json of the last step to DIR")


def load_priors(args):
    """The priors of ``args``: the bundled set (``--library``, default known) or the saved
    library (``--library-dir``), plus the ``--prior-file`` meshes; ``--prior-file`` alone
    gives only those.

    Raises
    ------
    LibraryError
        If an extra file would have the name (its stem) of a prior already there.
    """
    extra = args.prior_file or []
    bundled = args.library or (None if extra or args.library_dir else "known")
    library = PriorLibrary.load(args.library_dir) if args.library_dir else PriorLibrary()
    # Names are checked before the bundled and extra meshes are read: a clash shows at once.
    names = library.names + (bundled_names(bundled) if bundled else [])
    for path in extra:
        name = Path(path).stem
        if name in names:
            raise LibraryError(f"--prior-file {path}: there is already a prior named "
                               f"{name!r}; rename the file")
        names.append(name)
    if bundled:
        library = PriorLibrary.bundled(bundled)
    for path in extra:
        library.add_file(path)
    return library


def write_output(text, path):
    """Write ``text`` to the file ``path`` atomically, or print it when ``path`` is None."""
    if path:
        write_atomic(path, text.encode())
    else:
        print(text)


@functools.cache
def code_version():
    """The commit this package runs from (``git describe``), ``-dirty`` if the package's own
    files differ from it; None outside a git checkout.

    Trials are deterministic per seed for one version of the code; recording it tells which
    trial files belong together. Changes outside the package (results, docs) do not count.
    """
    package = Path(__file__).resolve().parents[1]

    def git(*args):
        out = subprocess.run(["git", *args], capture_output=True, text=True, timeout=10,
                             cwd=package)
        return out.stdout.strip() if out.returncode == 0 else None

    try:
        commit = git("describe", "--always")
        changed = git("status", "--porcelain", "--", ".")
    except (OSError, subprocess.SubprocessError):
        return None
    if not commit:
        return None
    return commit + ("-dirty" if changed else "")


def run_trial(truth_model, library, strategy="gpis-dhd", seed=0, preset="paper",
              max_steps=None, progress=False, params=None, finish=None):
    """Run one trial and return its JSON-ready result dict.

    ``params`` (a ``SessionParams``) replaces the preset's parameters when given (``preset``
    is then only a label). ``finish(session)`` is called after the last step; the dict it
    returns is merged into the result (benchmarks add final contacts, baselines, ...).
    """
    if max_steps is not None and max_steps < 1:
        raise ParameterError(f"max_steps must be at least 1, got {max_steps}")
    params = params or session_preset(preset)
    truth = make_truth(truth_model, rng=[seed, 0])
    session = Session(truth, library, strategy, params, seed=seed)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_steps or params.max_steps_novel, desc=truth_model.name,
                   unit="step", file=sys.stderr, delay=2.0)
    start = time.perf_counter()
    steps = []
    while not session.terminated and (max_steps is None or len(steps) < max_steps):
        snapshot = session.step()
        steps.append(snapshot.record())
        if bar is not None:
            bar.update(1)
            bar.set_postfix(cls=snapshot.map_class, novel=snapshot.novel,
                            dhd=f"{snapshot.dhd:.2f}")
    if bar is not None:
        bar.close()
    last = session.latest
    result = {"object": truth_model.name, "seed": seed, "strategy": strategy, "preset": preset,
            "params": params.to_dict(), "library": library.names,
            "truth_pose": {"rotation": truth.rotation.tolist(),
                           "translation": truth.translation.tolist()},
            "terminated_at": last.step if last.terminated else None,
            "code_version": code_version(),
            "seconds": time.perf_counter() - start, "steps": steps}
    if finish is not None:
        result.update(finish(session))
    return result


def run_trial_command(args):
    truth_model = (load_bundled(args.object) if args.object
                   else ObjectModel.from_file(args.object_file))
    library = load_priors(args)

    def finish(session):
        export_session(session, args.export)
        return {}

    result = run_trial(truth_model, library, args.strategy, args.seed, args.preset,
                       args.max_steps, progress=not args.no_progress,
                       finish=finish if args.export else None)
    write_output(json.dumps(result, indent=1), args.json)
    return 0
