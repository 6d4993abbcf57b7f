"""``python -m tactile_viz library build|add|remove|list|show``: a library folder made and
kept from the command line.

``library build DIR [NAME=]PATH[:UNIT] ...`` makes a library from meshes (a plain path
keeps the file's name, or its folder's with ``--name-from parent|grandparent``, for sets
that ship every object as ``<object>/google_16k/textured.obj``); ``add`` grows one, also
from another library (``--from-library``); ``remove`` drops priors by name; ``list`` and
``show`` print what a library holds. Meshes with a named unit are stored in metres; each
mesh is size-checked against the others; ``build`` and ``add`` then build the priors'
grids and tables, so the first trial starts at once.
"""

import sys
from pathlib import Path

import numpy as np

from ..cli import ArgumentParser, ExtendList, add_preset_argument, output_dir
from ..engine.errors import LibraryError
from ..engine.shape.library import MANIFEST, PriorLibrary, size_warning
from ..engine.shape.meshes import UNITS, split_units, unit_factor
from ..engine.shape.objects import ObjectModel

NAME_FROM = {"file": 0, "parent": 1, "grandparent": 2}


def add_library_arguments(parser):
    """The ``library`` command's actions and their options."""
    actions = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    for action, text in (("build", "make a library folder from mesh files"),
                         ("add", "add mesh files (or another library's priors) to a library")):
        sub = actions.add_parser(action, help=text, description=text)
        sub.add_argument("folder", metavar="DIR", type=output_dir if action == "build" else str,
                         help="the library folder")
        sub.add_argument("meshes", metavar="[NAME=]PATH[:UNIT]", nargs="*",
                         help="mesh files; NAME= names the prior (default: see --name-from), "
                              ":UNIT (m, cm, mm, in or a factor) its unit")
        sub.add_argument("--mesh-units", metavar="UNIT",
                         help="the unit of every mesh without its own :UNIT")
        sub.add_argument("--name-from", choices=list(NAME_FROM), default="file",
                         help="a prior's default name: the file's (default), its folder's or "
                              "its folder's folder's (<object>/google_16k/textured.obj)")
        add_preset_argument(sub, purpose="; the grids and tables are built for this "
                            "preset's trials (recognise: exact only near the surface, faster)")
        sub.add_argument("--no-progress", action="store_true", help="no progress bars")
        if action == "add":
            sub.add_argument("--from-library", metavar="DIR",
                             help="also add every prior of this library folder")
        sub.set_defaults(prog=sub.prog)
    remove = actions.add_parser("remove", help="remove priors from a library by name")
    remove.add_argument("folder", metavar="DIR")
    remove.add_argument("names", metavar="NAME", action=ExtendList)
    remove.set_defaults(prog=remove.prog)
    for action, text in (("list", "list a library's priors"),
                         ("show", "describe one prior of a library")):
        sub = actions.add_parser(action, help=text, description=text)
        sub.add_argument("folder", metavar="DIR")
        if action == "show":
            sub.add_argument("name", metavar="NAME")
        sub.set_defaults(prog=sub.prog)


def run_library_command(args):
    """Run one ``library`` action; returns the exit status."""
    return {"build": _build, "add": _add, "remove": _remove, "list": _list,
            "show": _show}[args.action](args)


def mesh_entries(texts, mesh_units=None, name_from="file"):
    """``(name, path, unit)`` of each ``[NAME=]PATH[:UNIT]`` (``unit`` None: none given).

    Raises
    ------
    LibraryError
        For a missing file or a name given twice.
    """
    entries, seen = [], {}
    for text in texts:
        name, equals, rest = text.partition("=")
        if not equals or not name or "/" in name:
            name, rest = None, text
        path, unit = split_units(rest)
        path = Path(path)
        if not path.is_file():
            raise LibraryError(f"{text}: no such file")
        if name is None:
            up = NAME_FROM[name_from]
            name = path.stem if up == 0 else path.resolve().parents[up - 1].name
        if name in seen:
            raise LibraryError(f"{text}: the name {name!r} is {seen[name]}'s too; name the "
                               f"prior (NAME=PATH) or use --name-from")
        seen[name] = text
        entries.append((name, path, unit if unit is not None else mesh_units))
    return entries


def _load(entries, library, progress, prog):
    """Load each entry into ``library`` (metres for a named unit), one line per problem."""
    for name, path, unit in _bar(entries, "meshes", progress):
        if name in library:
            raise LibraryError(f"{path}: the library already has a prior named {name!r}")
        scale = unit_factor(unit) if unit is not None else 1.0
        kept = "m" if isinstance(unit, str) and unit.strip().lower() in UNITS else None
        library.add(ObjectModel.from_file(path, name=name, scale=scale), units=kept)
    for name, path, _ in entries:
        others = [m for m in library if m.name != name]
        if others:
            message = size_warning(path.name, library[name].length,
                                   PriorLibrary(others).reference_size,
                                   library.units_of(name), remedy="give it as {unit}: "
                                   f"{name}={path}:{{unit}}")
            if message:
                print(f"{prog}: warning: {message}", file=sys.stderr)


def _bar(items, what, progress, unit="file"):
    if not progress:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=what, unit=unit, file=sys.stderr, delay=1.0)


def prior_bar(items):
    """A progress bar on stderr over priors whose grids and tables are built (or read),
    shown once it has taken a second."""
    return _bar(items, "priors' grids and tables", True, unit="prior")


def prepare(library, progress=False, preset=None):
    """Build the grids and tables a session over ``library`` needs with ``preset`` (default
    the default preset) into the disk cache (in child processes, one a core, when there are
    several): the first trial with that preset then starts at once. Nothing is loaded
    here."""
    from ..engine.belief.prior_build import build_missing
    from ..engine.presets import DEFAULT_PRESET, session_preset
    from ..engine.session import Session

    pf = Session(library, params=session_preset(preset or DEFAULT_PRESET)).filter
    build_missing(pf.models, pf.params.distance_step, pf.params.angle_step_deg,
                  progress=prior_bar if progress else None)


def _build(args):
    folder = Path(args.folder)
    if (folder / MANIFEST).exists():
        raise LibraryError(f"{folder} already holds a library: use library add")
    if not args.meshes:
        raise LibraryError("library build needs at least one mesh file")
    library = PriorLibrary()
    _load(mesh_entries(args.meshes, args.mesh_units, args.name_from), library,
          not args.no_progress, args.prog)
    return _save(library, folder, args, f"built {_count(len(library))}")


def _add(args):
    folder = Path(args.folder)
    library = PriorLibrary.load(folder) if (folder / MANIFEST).exists() else PriorLibrary()
    before = len(library)
    if args.from_library:
        other = PriorLibrary.load(args.from_library, units=library.units)
        for model in other:
            library.add(model, units=other.units_of(model.name))
    _load(mesh_entries(args.meshes, args.mesh_units, args.name_from), library,
          not args.no_progress, args.prog)
    if len(library) == before:
        raise LibraryError("nothing to add: give mesh files or --from-library DIR")
    return _save(library, folder, args, f"added {_count(len(library) - before)}")


def _save(library, folder, args, done):
    library.save(folder)
    prepare(library, not args.no_progress, args.preset)
    unit = library.units or "scene units"
    print(f"{done}; {folder} holds {len(library)} ({_sizes(library)} {unit} long)")
    return 0


def _count(number):
    return f"{number} prior{'' if number == 1 else 's'}"


def _sizes(library):
    lengths = [model.length for model in library]
    low, high = min(lengths), max(lengths)
    return f"{low:.3g}" if np.isclose(low, high) else f"{low:.3g} to {high:.3g}"


def _remove(args):
    library = PriorLibrary.load(args.folder)
    for name in args.names:
        library.remove(name)
    if not len(library):
        raise LibraryError(f"removing {', '.join(args.names)} would leave {args.folder} empty")
    library.save(args.folder)
    print(f"removed {', '.join(args.names)}; {args.folder} holds {len(library)}")
    return 0


def _list(args):
    library = PriorLibrary.load(args.folder)
    width = max(len("name"), *(len(name) for name in library.names))
    print(f"{'name':<{width}}  {'longest side':>12}  unit    faces  learned")
    for model in library:
        unit = library.units_of(model.name) or "-"
        print(f"{model.name:<{width}}  {model.length:>12.4g}  {unit:<4}  "
              f"{len(model.mesh.faces):>7}  {'yes' if model.learned else 'no'}")
    return 0


def _show(args):
    library = PriorLibrary.load(args.folder)
    model, unit = library[args.name], library.units_of(args.name) or "scene units"
    extents = model.mesh.extents
    print(f"{model.name}: {'learned' if model.learned else 'a mesh'}, "
          f"{len(model.mesh.vertices)} vertices, {len(model.mesh.faces)} faces")
    print(f"  extents {extents[0]:.4g} x {extents[1]:.4g} x {extents[2]:.4g} {unit}, "
          f"longest side {model.length:.4g} {unit}")
    print(f"  watertight {model.mesh.is_watertight}, volume {model.mesh.volume:.4g} "
          f"{unit}^3")
    return 0


def main(argv=None):
    """``python -m tactile_viz library ...`` on its own (tests)."""
    parser = ArgumentParser(prog="python -m tactile_viz library")
    add_library_arguments(parser)
    return run_library_command(parser.parse_args(argv))
