"""docs/architecture.md is a map of the package: one table row per module under
tactile_viz/ (``__init__.py`` files aside), and no row for a module that is gone."""

import re
from pathlib import Path

import tactile_viz

PACKAGE = Path(tactile_viz.__file__).parent
DOC = PACKAGE.parent / "docs" / "architecture.md"
ROW = re.compile(r"^\| `([\w/]+\.py)` \| (.+) \|$", re.M)


def modules():
    """Every module file under tactile_viz/, as a path relative to it."""
    return {path.relative_to(PACKAGE).as_posix() for path in PACKAGE.rglob("*.py")
            if path.name != "__init__.py"}


def rows(text):
    """``[(module path, description)]`` of the map's table rows."""
    return ROW.findall(text)


def test_the_row_pattern_reads_a_row():
    text = "| module | what |\n| `engine/a/b.py` | does b |\n| `x.py`, `y.py` | two |\n"
    assert rows(text) == [("engine/a/b.py", "does b")]


def test_every_module_has_one_row_and_every_row_a_module():
    listed = [path for path, _ in rows(DOC.read_text())]
    missing = sorted(modules() - set(listed))
    gone = sorted(set(listed) - modules())
    twice = sorted({path for path in listed if listed.count(path) > 1})
    assert not missing, f"docs/architecture.md lacks a row for: {', '.join(missing)}"
    assert not gone, f"docs/architecture.md lists modules that do not exist: {', '.join(gone)}"
    assert not twice, f"docs/architecture.md lists these twice: {', '.join(twice)}"


def test_every_row_says_what_its_module_does():
    assert all(len(what.split()) >= 3 for _, what in rows(DOC.read_text()))
