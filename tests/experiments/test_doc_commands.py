"""The commands of README.md and docs/cli.md, run as written in a fresh folder.

Every ``python ...`` line of a fenced block (with its ``\\`` continuations) is either run
(the commands of one block in order, in one empty folder, each expected to exit 0) or
listed in :data:`NOT_RUN` with the reason. A usage synopsis (``[--seed N]``, ``NAME``) and
the desktop app are recognised as such. A new command in the documents is run unless it is
added to :data:`NOT_RUN`: documented commands keep working.
"""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCUMENTS = ["README.md", "docs/cli.md"]
TIMEOUT = 120  # seconds; each command runs in under 30 s on a free 2-core machine
# Commands that are not run, by their text as written (continuations joined, comments off).
NOT_RUN = {
    "python -m tactile_viz bench sdf": "a benchmark: over 2 minutes",
    "python -m tactile_viz bench step": "a benchmark: timings of 20 s",
}
PLACEHOLDER = re.compile(r"[\[\]|]|^[A-Z][A-Z_]*(\.\.\.)?$|^[A-Z]+[:=]")


def documented_blocks(document):
    """The fenced blocks of ``document``, each as its list of commands (one string each,
    continuations joined, comments removed)."""
    text = (REPO / document).read_text()
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.S | re.M)
    found = []
    for block in blocks:
        joined = re.sub(r"\\\n\s*", " ", block)
        commands = []
        for line in joined.splitlines():
            words = shlex.split(line, comments=True) if line.lstrip().startswith("python ") \
                else []
            if words:
                commands.append(words)
        if commands:
            found.append(commands)
    return found


def why_not_run(words):
    """Why the command ``words`` is not run (None: it is run)."""
    text = " ".join(words)
    if text in NOT_RUN:
        return NOT_RUN[text]
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
    cases = []
    for document in DOCUMENTS:
        for number, block in enumerate(documented_blocks(document)):
            if any(why_not_run(words) is None for words in block):
                cases.append(pytest.param(block, id=f"{document}:block{number}"))
    return cases


@pytest.mark.slow
@pytest.mark.parametrize("block", _cases())
def test_documented_commands_run_as_written(block, tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    for words in block:
        if why_not_run(words) is not None:
            continue
        done = subprocess.run([sys.executable, *words[1:]], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT)
        assert done.returncode == 0, f"{shlex.join(words)}\n{done.stderr[-2000:]}"


def test_every_documented_command_is_run_or_has_a_reason():
    commands = [words for document in DOCUMENTS for block in documented_blocks(document)
                for words in block]
    run = [shlex.join(words) for words in commands if why_not_run(words) is None]
    assert any("--learn" in text for text in run)  # docs/cli.md's quick start is among them
    assert any(text.startswith("python -m tactile_viz replay") for text in run)
    # Listed but no longer in the documents: the table is kept to the commands there.
    texts = {" ".join(words) for words in commands}
    stale = [text for text in NOT_RUN if text not in texts]
    assert stale == []


def python_blocks(document):
    """The fenced ``python`` blocks of ``document``."""
    text = (REPO / document).read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.mark.slow
@pytest.mark.parametrize("number", range(len(python_blocks("README.md"))))
def test_the_readme_python_runs_as_written(number, tmp_path):
    """Each Python block of README.md is complete: run alone in an empty folder."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    (tmp_path / "snippet.py").write_text(python_blocks("README.md")[number])
    done = subprocess.run([sys.executable, "snippet.py"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Warning" not in done.stderr and "Traceback" not in done.stderr
