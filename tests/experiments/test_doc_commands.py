"""The commands of README.md and docs/*.md, run as written in a fresh folder.

Every fenced block of those documents (not docs/journal/, a dated log) is one of three: a
```` ```python ```` block (run by ``test_doc_snippets.py``), a block that is not code (a
layout, a diagram, output, a file's format: listed in :data:`NOT_RUN_BLOCKS` by its document
and first line), or shell commands. A command is a line that starts at the left margin with
its ``\\`` continuations (and the lines of a quoted string it opens); an indented line
goes on with a usage synopsis or a comment. Every ``python ...`` command is either run (the
commands of one block in order, in one empty folder, each expected to exit 0; those in
:data:`CAPPED` with fewer steps) or listed in :data:`NOT_RUN` with the reason; a usage
synopsis (``[--seed N]``, ``NAME``), a benchmark and the desktop app are recognised as such.
Any other command (``make ...``) needs its reason in :data:`NOT_RUN`. A new command or block
in the documents is run unless it is added to a table: documented commands keep working.
"""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCUMENTS = ["README.md", *sorted(f"docs/{path.name}" for path in (REPO / "docs").glob("*.md"))]
TIMEOUT = 120  # seconds; each command runs in under 30 s on a free 2-core machine
FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```", flags=re.S | re.M)
# Commands that are not run, by their text as written (continuations joined, comments off).
NOT_RUN = {
    "make run": "the desktop app",
    "make test": "the whole test suite, this test among it",
    "make screenshots": "regenerates screenshots/ (windows under Xvfb)",
    "python -m tactile_viz bench sdf": "a benchmark: over 2 minutes",
    "python -m tactile_viz bench step": "a benchmark: timings of 20 s",
    "python -m tactile_viz trial --object mug_1 --seed 0 --json before.json":
        "a full trial (232 steps) at an old commit, compared with the next one's",
    "python -m tactile_viz trial --object mug_1 --seed 0 --json after.json":
        "a full trial (232 steps) at an old commit, compared with the one before",
    "python examples/robot.py --object mug_1 --seed 0 --steps 300":
        "three runs of 300 steps (minutes); tests/examples/test_robot_example.py runs the "
        "example at 40 and 6 steps",
    "python examples/robot.py --object mug_1 --seed 0 --steps 300 --no-table --reach-angle "
    "180 --tip-radius 0": "three runs of 300 steps (minutes), the same example without a table",
    "python examples/robot_bag.py --object mug_1 --steps 20 --style gazebo --out robot_bag":
        "13 s; tests/examples/test_bag_example.py runs the example at 6 steps, both styles",
    "python -m tactile_viz replay --observations run.mcap --library-dir mylib "
    "--contacts-topic /probe/contacts --misses-topic /probe/misses --step-gap 0.5":
        "the options for a bag of your own, recorded on other topics",
}
# Commands run with these arguments added (a later --max-steps overrides an earlier one): the
# documents report the full runs, which take half a minute each.
CAPPED = {
    "python -m tactile_viz trial --object-file rod_mm.stl --prior-file block_mm.stl "
    "ball_mm.stl --mesh-units mm --seed 1 --learn rod_learned --learn-to lib --json "
    "learn.json": ["--max-steps", "5", "--no-progress"],
    "python -m tactile_viz trial --object-file rod_mm.stl --library-dir lib --mesh-units mm "
    "--seed 5 --max-steps 60 --json again.json": ["--max-steps", "5", "--no-progress"],
}
# Fenced blocks that are not code, by document and first line (stripped).
NOT_RUN_BLOCKS = {
    ("docs/architecture.md", "app.py                     the desktop app from a clone: "
     "runs tactile_viz/launcher.py"): "the repository's layout",
    ("docs/architecture.md", "flowchart TD"): "a diagram (Mermaid)",
    ("docs/architecture.md", "sensor ─▶ observations ─▶ filter update ─▶ novelty test ─┬─ "
     "known ─▶ MAP shape ─┐"): "a diagram",
    ("docs/architecture.md", "GUI controls ──settings, priors, truth──▶ app.Scene ──creates──▶ "
     "engine.Session"): "a diagram",
    ("docs/cli.md", "mug_1: known: mug_1, decided at step 26; stopped by itself at step 26 "
     "(24 contacts, 17 misses, 10.4 s)"): "a command's output",
    ("docs/engine.md", "step,kind,x,y,z,nx,ny,nz"): "a recording's format (CSV)",
}
PLACEHOLDER = re.compile(r"[\[\]|]|^[A-Z][A-Z_]*(\.\.\.)?$|^[A-Z]+[:=]")


def fenced_blocks(document):
    """The fenced blocks of ``document``: ``[(line, language, text)]``."""
    text = (REPO / document).read_text()
    return [(text.count("\n", 0, found.start()) + 1, found.group(1).strip(), found.group(2))
            for found in FENCE.finditer(text)]


def first_line(text):
    return next((line.strip() for line in text.splitlines() if line.strip()), "")


def commands(text):
    """The commands of the shell block ``text``, each as its words (comments removed)."""
    found, pending = [], None
    for line in re.sub(r"\\\n\s*", " ", text).splitlines():
        if pending is not None:
            line = f"{pending}\n{line}"
        elif not line.strip() or line[0].isspace() or line.startswith("#"):
            continue  # a synopsis or comment carried on, or nothing
        try:
            words = shlex.split(line, comments=True)
        except ValueError:  # a quoted string goes on to the next line
            pending = line
            continue
        pending = None
        if words:
            found.append(words)
    assert pending is None, f"an unclosed quote: {pending}"
    return found


def documented_blocks(document):
    """The shell blocks of ``document``: ``[(line, commands)]``."""
    return [(line, commands(text)) for line, language, text in fenced_blocks(document)
            if language != "python" and (document, first_line(text)) not in NOT_RUN_BLOCKS]


def why_not_run(words):
    """Why the command ``words`` is not run (None: it is run)."""
    text = " ".join(words)
    if text in NOT_RUN:
        return NOT_RUN[text]
    if words[0] == "tactile-viz" and words[1:2] == ["app"]:
        return "the desktop app (a window)"
    if words[0] != "python":
        return None  # not run either: test_every_documented_command_... asks for a reason
    if words[1:2] == ["app.py"]:
        return "the desktop app (a window)"
    if words[1:3] == ["-m", "tactile_viz.assetgen"]:
        return "regenerates assets/"
    if any(PLACEHOLDER.search(word) for word in words[1:]):
        return "a usage synopsis"
    if words[1:4] == ["-m", "tactile_viz", "bench"]:
        return "a benchmark"
    return None


def _cases():
    """One case a distinct block: a block whose commands are word for word an earlier
    one's (docs/cli.md's quick start is the README's) runs once, under the first's id."""
    cases, seen = [], set()
    for document in DOCUMENTS:
        for line, block in documented_blocks(document):
            key = tuple(map(tuple, block))
            if key not in seen and any(words[0] == "python" and why_not_run(words) is None
                                       for words in block):
                seen.add(key)
                cases.append(pytest.param(block, id=f"{document}:{line}"))
    return cases


@pytest.mark.slow
@pytest.mark.parametrize("block", _cases())
def test_documented_commands_run_as_written(block, tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    for words in block:
        if words[0] != "python" or why_not_run(words) is not None:
            continue
        extra = CAPPED.get(" ".join(words), [])
        done = subprocess.run([sys.executable, *words[1:], *extra], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT)
        assert done.returncode == 0, f"{shlex.join(words)}\n{done.stderr[-2000:]}"


def test_every_documented_command_is_run_or_has_a_reason():
    blocks = {(document, line): block for document in DOCUMENTS
              for line, block in documented_blocks(document)}
    # A block that is no shell command (a diagram, output) is listed as not code.
    assert [key for key, block in blocks.items() if not block] == []
    commands = [words for block in blocks.values() for words in block]
    # A command the test cannot run (make, an installed script) has its reason.
    assert [shlex.join(words) for words in commands
            if words[0] != "python" and why_not_run(words) is None] == []
    run = [" ".join(words) for words in commands if why_not_run(words) is None]
    assert any("--learn" in text for text in run)  # docs/cli.md's quick start is among them
    # Every block with a command to run is a case, or word for word an earlier case's.
    cases = {tuple(map(tuple, case.values[0])) for case in _cases()}
    assert [key for key, block in blocks.items() if tuple(map(tuple, block)) not in cases
            and any(why_not_run(words) is None and words[0] == "python" for words in block)
            ] == []
    assert any(text.startswith("python -m tactile_viz replay") for text in run)
    assert set(CAPPED) <= set(run)
    # Listed but no longer in the documents: the tables are kept to what is there.
    texts = {" ".join(words) for words in commands}
    assert [text for text in NOT_RUN if text not in texts] == []
    present = {(document, first_line(text)) for document in DOCUMENTS
               for _, _, text in fenced_blocks(document)}
    assert [key for key in NOT_RUN_BLOCKS if key not in present] == []


def test_a_command_of_several_lines():
    block = ('python -m tactile_viz trial --object mug_1 \\\n    --seed 1   # a comment\n'
             '       [--synopsis carried on]\n# a comment line\n'
             'python -c "import sys\nprint(sys.argv)"\nmake run     # the app\n')
    assert commands(block) == [["python", "-m", "tactile_viz", "trial", "--object", "mug_1",
                                "--seed", "1"], ["python", "-c", "import sys\nprint(sys.argv)"],
                               ["make", "run"]]
