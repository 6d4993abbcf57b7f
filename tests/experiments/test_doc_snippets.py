"""The ```` ```python ```` blocks of README.md and docs/*.md, run as written.

Each block is complete: it makes its own meshes or loads bundled ones, defines its robot and
caps its loops. The blocks of one document run in one Python process, in the order they
appear (one process a document spares the imports, seconds each), but none builds on
another: each runs in a fresh namespace (``__name__`` ``"__main__"``) and an empty folder
of its own, and must end without an exception or a warning. A block that is not meant to
run (an API signature, a fragment) is listed in :data:`NOT_RUN` by its document and first
line, with the reason; a new block is run unless it is added there. The other fenced blocks
are ``test_doc_commands.py``'s.
"""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCUMENTS = ["README.md", *sorted(f"docs/{path.name}" for path in (REPO / "docs").glob("*.md"))]
TIMEOUT = 120  # seconds for a document's blocks; each runs in under 10 s on 2 free cores
PYTHON = re.compile(r"^```python\n(.*?)^```", flags=re.S | re.M)
# Blocks that are not run, by document and first line (stripped): none now.
NOT_RUN: dict[tuple[str, str], str] = {}
RUNNER = """\
import json, os, sys
for number, (name, code) in enumerate(json.loads(open(sys.argv[1]).read())):
    os.chdir(f"block{number}")
    exec(compile(code, name, "exec"), {"__name__": "__main__"})
    os.chdir("..")
"""


def python_blocks(document):
    """The ``python`` blocks of ``document``: ``[(line, text)]``."""
    text = (REPO / document).read_text()
    return [(text.count("\n", 0, found.start()) + 1, found.group(1))
            for found in PYTHON.finditer(text)]


def first_line(text):
    return next((line.strip() for line in text.splitlines() if line.strip()), "")


def blocks_run(document):
    return [(line, text) for line, text in python_blocks(document)
            if (document, first_line(text)) not in NOT_RUN]


@pytest.mark.slow
@pytest.mark.parametrize("document", [document for document in DOCUMENTS
                                      if blocks_run(document)])
def test_the_python_blocks_run_as_written(document, tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    blocks = [(f"{document}, the block at line {line}", text)
              for line, text in blocks_run(document)]
    for number in range(len(blocks)):
        (tmp_path / f"block{number}").mkdir()
    (tmp_path / "blocks.json").write_text(json.dumps(blocks))
    done = subprocess.run([sys.executable, "-c", RUNNER, "blocks.json"], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Warning" not in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_every_python_block_is_run_or_has_a_reason():
    run = {document for document in DOCUMENTS if blocks_run(document)}
    assert {"README.md", "docs/engine.md", "docs/robots.md"} <= run
    # Listed but no longer in the documents: the table is kept to the blocks there.
    present = {(document, first_line(text)) for document in DOCUMENTS
               for _, text in python_blocks(document)}
    assert [key for key in NOT_RUN if key not in present] == []
