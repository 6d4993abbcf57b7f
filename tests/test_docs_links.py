"""Every relative link of README.md and docs/**/*.md points to a file or folder the
repository holds (in a git checkout, one git tracks or would add: an ignored file on this
disk, such as a benchmark's per-trial output under results/, is missing in a fresh clone),
and every ``#anchor`` to a heading (or an ``<a id>``) of the page it names."""

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)


def documents():
    return [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]


def tracked():
    """Paths the repository holds, relative to it (files and their folders); None when
    this is not a git checkout."""
    try:
        done = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                               "--exclude-standard"], cwd=REPO, capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    files = {Path(name) for name in done.stdout.decode().split("\0") if name}
    return {str(path) for path in files} | {str(parent) for path in files
                                               for parent in path.parents}


def anchor(heading):
    """GitHub's anchor of a Markdown heading's text."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path):
    text = FENCE.sub("", path.read_text())
    return ({anchor(title) for title in re.findall(r"^#+ (.+)$", text, re.M)}
            | set(re.findall(r'<a (?:id|name)="([^"]+)"', text)))


def links(path):
    """The relative links of the document ``path``: ``[(target, fragment)]``."""
    found = []
    for target in LINK.findall(FENCE.sub("", path.read_text())):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
            continue
        file, _, fragment = target.partition("#")
        found.append((file, fragment))
    return found


def broken():
    held = tracked()
    faults = []
    for document in documents():
        for file, fragment in links(document):
            target = (document.parent / file).resolve() if file else document
            try:
                relative = str(target.relative_to(REPO)) if target != REPO else "."
            except ValueError:
                faults.append(f"{document.relative_to(REPO)}: {file} is outside the repo")
                continue
            exists = relative in held if held is not None else target.exists()
            if not exists:
                faults.append(f"{document.relative_to(REPO)}: {file} does not exist")
            elif fragment and target.suffix == ".md" and fragment not in anchors(target):
                faults.append(f"{document.relative_to(REPO)}: {file}#{fragment} names no heading")
    return faults


def test_the_anchor_of_a_heading():
    assert anchor("48 check lines (issue 39; seeds 19000-19403)") == \
        "48-check-lines-issue-39-seeds-19000-19403"
    assert anchor("The lead: a pose the positions prefer to the particle's") == \
        "the-lead-a-pose-the-positions-prefer-to-the-particles"


def test_every_relative_link_resolves():
    faults = broken()
    assert not faults, "\n".join(faults)
