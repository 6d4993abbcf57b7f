"""Move the engine's modules into subpackages and rewrite every reference to them.

Run from the repository's root, on a clean work tree::

    python tools/relayout.py            # git mv + rewrite; refuses if already applied
    python tools/relayout.py --dry-run  # print the moves and the files it would rewrite

What it does:

1. ``git mv`` each module of :data:`MOVES` (old name -> new dotted name under
   ``tactile_viz/engine``) and writes each new subpackage's ``__init__.py`` (:data:`PACKAGES`).
2. Rewrites the import statements of every ``.py`` file under :data:`PY_ROOTS` (absolute
   ``tactile_viz.engine.X`` and relative ``from .X`` / ``from ..engine.X`` /
   ``from . import X`` forms, at any indentation, so also inside functions), resolving each
   relative import against the file's old place and writing it relative to its new place.
3. Rewrites the dotted names ``tactile_viz.engine.X...`` anywhere else in those files
   (strings given to ``monkeypatch``/``mock.patch``, docstrings, comments), and in the
   Markdown files under :data:`DOC_ROOTS` also ``engine.X`` and ``engine/X.py``.
4. Applies :data:`EXTRA_EDITS` (references the rules above cannot see).

A multi-line ``from ... import`` whose names go to different modules stops the run
(after the moves) with its file and line, to be split by hand. New modules added since
the table was written stay where they are; their imports are rewritten like the rest.

It is not idempotent: a moved name can be a prefix of a new one (``belief`` is now a
package), so it refuses when any module of :data:`MOVES` is missing or any target exists.
Not imported by the package or the tests.
"""

import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

ENGINE = "tactile_viz.engine"

# old module (under tactile_viz/engine) -> new dotted name (under tactile_viz/engine).
# errors, params, param_schema, presets and transforms stay at the top: every part uses them.
MOVES = {
    # belief: the particle filter over class and pose (paper, Algorithm 1) and beyond it.
    "particle_filter": "belief.particle_filter",
    "belief": "belief.particles",
    "likelihood": "belief.likelihood",
    "kernels": "belief.kernels",
    "resampling": "belief.resampling",
    "features": "belief.features",
    "ppf": "belief.ppf",
    "prior_bank": "belief.prior_bank",
    "prior_build": "belief.prior_build",
    "pose_refinement": "belief.pose_refinement",
    "discrimination": "belief.discrimination",
    "decision": "belief.decision",
    # shape: meshes, object models and their distances; the GPIS of a novel shape.
    "meshes": "shape.meshes",
    "mesh_repair": "shape.mesh_repair",
    "objects": "shape.objects",
    "library": "shape.library",
    "sdf": "shape.sdf",
    "symmetry": "shape.symmetry",
    "metrics": "shape.metrics",
    "gpis": "shape.gpis",
    "gpis_prior": "shape.gpis_prior",
    "gpis_incremental": "shape.gpis_incremental",
    "gpis_variance": "shape.gpis_variance",
    "gpis_compiled": "shape.gpis_compiled",
    # explore: the touch: observations, the simulated sensor, where to touch next.
    "observations": "explore.observations",
    "simulator": "explore.simulator",
    "exploration": "explore.exploration",
    # io: files in and out.
    "files": "io.files",
    "cache": "io.cache",
    "persistence": "io.persistence",
    "export": "io.export",
    "observation_file": "io.observation_file",
    "bags": "io.bags",
    "bag_export": "io.bag_export",
}

PACKAGES = {
    "belief": "The belief over object class and pose: the particle filter (paper, Algorithm 1),\n"
              "its likelihood, hypotheses from point pairs, resampling, and the steps beyond the\n"
              "paper that tell near twins apart and decide a known object.",
    "shape": "Shapes: meshes and their repair, object models with their signed distance, the\n"
             "prior library, symmetries and shape distances, and the GPIS reconstruction of a\n"
             "novel shape (paper, Section III-E).",
    "explore": "The touch: tactile observations, the simulated point sensor, and where to touch\n"
               "next (paper, Section III-F).",
    "io": "Files in and out: atomic writes, the derived-data cache, saved sessions, recorded\n"
          "touches (CSV, ROS 2 bags) and exports.",
}

# (path, old text, new text): references the rules cannot see.
EXTRA_EDITS = [
    # The repository's root, one level further up from a module in a subpackage.
    ("tactile_viz/engine/shape/objects.py", 'Path(__file__).resolve().parents[2] / "assets"',
     'Path(__file__).resolve().parents[3] / "assets"'),
    ("tactile_viz/engine/belief/prior_build.py", "str(Path(__file__).resolve().parents[2])",
     "str(Path(__file__).resolve().parents[3])"),
    ("tests/engine/test_import_graph.py", 'f"{PACKAGE}.persistence"',
     'f"{PACKAGE}.io.persistence"'),
]

PY_ROOTS = ["tactile_viz", "tests", "examples", "scripts", "app.py"]
DOC_ROOTS = ["docs"]


def new_name(dotted):
    """``dotted`` (absolute) with a moved module (or its prefix) renamed; else unchanged."""
    if not (dotted == ENGINE or dotted.startswith(ENGINE + ".")):
        return dotted
    rest = dotted[len(ENGINE) + 1:].split(".") if dotted != ENGINE else []
    if rest and rest[0] in MOVES:
        return ".".join([ENGINE, MOVES[rest[0]], *rest[1:]])
    return dotted


def is_moved_module(dotted):
    return dotted.startswith(ENGINE + ".") and dotted[len(ENGINE) + 1:] in MOVES


def module_of(path, root):
    """Dotted module of ``path`` (relative to the repo ``root``) and whether it is a package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    if is_package:
        parts.pop()
    return ".".join(parts), is_package


def old_module_of(new_path, root, moved_back):
    """The module ``new_path`` had before the move (``moved_back``: new path -> old path)."""
    return module_of(moved_back.get(new_path, new_path), root)


def resolve(level, module, here, is_package):
    """The absolute module of ``from <level dots><module> import`` in module ``here``."""
    if not level:
        return module or ""
    anchor = here.split(".")
    anchor = anchor[:len(anchor) - level + (1 if is_package else 0)]
    return ".".join(anchor + ([module] if module else []))


def relative(target, here, is_package):
    """``(level, module)`` reaching the absolute ``target`` from module ``here``."""
    package = here.split(".") if is_package else here.split(".")[:-1]
    parts = target.split(".")
    common = 0
    while common < min(len(package), len(parts)) and package[common] == parts[common]:
        common += 1
    return len(package) - common + 1, ".".join(parts[common:])


def _head(level, module):
    return "." * level + module


def _alias(alias):
    return alias.name + (f" as {alias.asname}" if alias.asname else "")


def rewrite_from(node, old_here, new_here, old_is_package, new_is_package):
    """The groups ``[(head, [alias text])]`` a ``from ... import`` becomes, or None if it
    stays as it is."""
    base = resolve(node.level, node.module, old_here, old_is_package)
    groups = {}
    for alias in node.names:
        full = f"{base}.{alias.name}"
        if is_moved_module(full):
            target = new_name(full)
            parent, name = target.rsplit(".", 1)
            text = (f"{name} as {alias.asname or alias.name}" if name != alias.name
                    else _alias(alias))
        else:
            parent, text = new_name(base), _alias(alias)
        if node.level:
            parent = _head(*relative(parent, new_here, new_is_package))
        groups.setdefault(parent, []).append(text)
    if node.level:
        unchanged = list(groups) == [_head(node.level, node.module or "")]
    else:
        unchanged = list(groups) == [node.module]
    if unchanged and all(" as " not in t or t in map(_alias, node.names)
                         for texts in groups.values() for t in texts):
        return None
    return list(groups.items())


FROM_HEAD = re.compile(r"from\s+[.\w]+\s+import\s", re.S)


def _line_starts(text):
    starts, offset = [], 0
    for line in text.splitlines(keepends=True):
        starts.append(offset)
        offset += len(line)
    starts.append(offset)
    return starts


def import_edits(text, path, old_here, new_here, old_is_package, new_is_package):
    """``[(start, end, replacement)]`` of the import statements of ``text``, and the spans
    of every import statement (left alone by the dotted-name pass)."""
    tree = ast.parse(text, str(path))
    starts = _line_starts(text)
    edits, spans = [], []
    for node in ast.walk(tree):
        if not isinstance(node, (ast.Import, ast.ImportFrom)):
            continue
        start = starts[node.lineno - 1] + node.col_offset
        end = starts[node.end_lineno - 1] + node.end_col_offset
        spans.append((start, end))
        source = text[start:end]
        if isinstance(node, ast.Import):
            replaced = DOTTED.sub(lambda m: new_name(m.group(0)), source)
            if replaced != source:
                edits.append((start, end, replaced))
            continue
        groups = rewrite_from(node, old_here, new_here, old_is_package, new_is_package)
        if groups is None:
            continue
        if len(groups) == 1:
            head, _ = groups[0]
            same_names = [t for t in groups[0][1]] == [_alias(a) for a in node.names]
            if same_names:
                edits.append((start, end, FROM_HEAD.sub(f"from {head} import ", source, 1)))
                continue
        if node.end_lineno != node.lineno:
            raise SystemExit(f"{path}:{node.lineno}: a multi-line import to split; edit it "
                             "by hand, then run again")
        indent = text[starts[node.lineno - 1]:start]
        lines = [f"from {head} import {', '.join(names)}" for head, names in groups]
        edits.append((start, end, ("\n" + indent).join(lines)))
    return edits, spans


DOTTED = re.compile(r"(?<![\w.])" + re.escape(ENGINE) + r"(?:\.\w+)+")
DOC_DOTTED = re.compile(r"(?<![\w./])engine\.(\w+)\b")
DOC_PATH = re.compile(r"(?<![\w.])engine/(\w+)\.py\b")


def rewrite_dotted(text):
    """Every ``tactile_viz.engine.X...`` renamed, and every path ``engine/X.py``."""
    text = DOTTED.sub(lambda m: new_name(m.group(0)), text)
    return DOC_PATH.sub(
        lambda m: f"engine/{MOVES.get(m.group(1), m.group(1)).replace('.', '/')}.py", text)


def rewrite_doc(text):
    """:func:`rewrite_dotted`, and ``engine.X`` (Markdown names the package so)."""
    text = rewrite_dotted(text)
    return DOC_DOTTED.sub(lambda m: f"engine.{MOVES.get(m.group(1), m.group(1))}", text)


def apply(text, edits):
    for start, end, replacement in sorted(edits, reverse=True):
        text = text[:start] + replacement + text[end:]
    return text


def rewrite_python(path, root, moved_back):
    text = path.read_text()
    old_here, old_is_package = old_module_of(path, root, moved_back)
    new_here, new_is_package = module_of(path, root)
    edits, spans = import_edits(text, path, old_here, new_here, old_is_package, new_is_package)
    # Dotted names outside import statements: applied on the text between the spans.
    out, last = [], 0
    for start, end in sorted(spans):
        if start < last:
            continue
        out += [rewrite_dotted(text[last:start]), text[start:end]]
        last = end
    out.append(rewrite_dotted(text[last:]))
    shifted = "".join(out)
    if shifted != text:
        # The dotted pass may change lengths; redo the import edits on the new text.
        edits, _ = import_edits(shifted, path, old_here, new_here, old_is_package,
                                new_is_package)
    return apply(shifted, edits)


def files_under(root, roots, suffix):
    for name in roots:
        place = root / name
        if place.is_file() and place.suffix == suffix:
            yield place
        elif place.is_dir():
            yield from (p for p in sorted(place.rglob(f"*{suffix}"))
                        if ".venv" not in p.parts and "__pycache__" not in p.parts)


def check(engine_dir):
    missing = [old for old in MOVES if not (engine_dir / f"{old}.py").is_file()]
    present = [new for new in MOVES.values()
               if (engine_dir / (new.replace(".", "/") + ".py")).exists()]
    if missing or present:
        raise SystemExit(f"relayout: already applied (or partly): {len(missing)} of "
                         f"{len(MOVES)} modules missing, {len(present)} targets present "
                         f"(e.g. {(missing or present)[0]}); nothing done")


def git(root, *args):
    subprocess.run(["git", *args], cwd=root, check=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1])
    parser.add_argument("--dry-run", action="store_true")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    engine_dir = root / "tactile_viz" / "engine"
    check(engine_dir)
    for package in PACKAGES:
        if (engine_dir / package).exists() and not (engine_dir / package).is_dir():
            raise SystemExit(f"relayout: {engine_dir / package} exists and is not a folder")
    moved_back = {engine_dir / (new.replace(".", "/") + ".py"): engine_dir / f"{old}.py"
                  for old, new in MOVES.items()}
    if args.dry_run:
        for old, new in MOVES.items():
            print(f"git mv tactile_viz/engine/{old}.py "
                  f"tactile_viz/engine/{new.replace('.', '/')}.py")
    else:
        for package, doc in PACKAGES.items():
            folder = engine_dir / package
            folder.mkdir(exist_ok=True)
            init = folder / "__init__.py"
            if not init.exists():
                init.write_text(f'"""{doc}\n\nThe public names are exported by '
                                f':mod:`tactile_viz.engine`."""\n')
                git(root, "add", str(init.relative_to(root)))
        for new, old in moved_back.items():
            git(root, "mv", str(old.relative_to(root)), str(new.relative_to(root)))
    changed = []
    for path in files_under(root, PY_ROOTS, ".py"):
        if path.resolve() == Path(__file__).resolve():
            continue
        if args.dry_run:
            continue
        text = path.read_text()
        new = rewrite_python(path, root, moved_back)
        if new != text:
            path.write_text(new)
            changed.append(path)
    for path in files_under(root, DOC_ROOTS, ".md"):
        text = path.read_text()
        new = rewrite_doc(text)
        if new != text and not args.dry_run:
            path.write_text(new)
            changed.append(path)
    for name, old, new in EXTRA_EDITS:
        path = root / name
        text = path.read_text()
        if old not in text:
            print(f"relayout: warning: {name} no longer holds {old!r}; check it by hand",
                  file=sys.stderr)
        elif not args.dry_run:
            path.write_text(text.replace(old, new))
            changed.append(path)
    for path in sorted(set(changed)):
        print("rewrote", path.relative_to(root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
