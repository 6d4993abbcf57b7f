"""The one atomic-write helper: whole files, the usual mode, nothing left behind."""

import os
import stat

import numpy as np
import pytest
import trimesh

from tactile_viz.engine import PriorLibrary
from tactile_viz.engine.io.files import current_umask, write_atomic


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def test_current_umask_reads_without_changing_it():
    old = os.umask(0o027)
    try:
        assert current_umask() == 0o027
        assert current_umask() == 0o027
    finally:
        os.umask(old)


def test_written_file_has_the_mode_open_would_give(tmp_path, umask_022):
    path = write_atomic(tmp_path / "a.bin", b"hello")
    assert path.read_bytes() == b"hello"
    assert mode(path) == 0o644  # mkstemp alone gives 0600
    os.umask(0o077)
    write_atomic(tmp_path / "b.bin", b"x")
    assert mode(tmp_path / "b.bin") == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "b.bin"]


def test_writer_function_and_replacing(tmp_path, umask_022):
    path = tmp_path / "arrays.npz"
    path.write_bytes(b"old")
    os.chmod(path, 0o600)
    write_atomic(path, lambda stream: np.savez(stream, x=np.arange(3)))
    with np.load(path) as stored:
        assert stored["x"].tolist() == [0, 1, 2]
    assert mode(path) == 0o644


def test_failure_mid_write_keeps_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "data.json"
    path.write_bytes(b"good")

    def half_then_fail(stream):
        stream.write(b"half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        write_atomic(path, half_then_fail)
    assert path.read_bytes() == b"good"
    assert [p.name for p in tmp_path.iterdir()] == ["data.json"]


def test_failing_rename_leaves_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "data.bin"

    def fail(*args):
        raise OSError("no rename")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="no rename"):
        write_atomic(path, b"new")
    assert list(tmp_path.iterdir()) == []


def test_saved_library_and_session_are_readable_by_others(tmp_path, umask_022):
    """Saved priors and sessions get 0644 under umask 022 (they were 0600)."""
    from tactile_viz.engine.session import Session, make_truth

    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    library = PriorLibrary()
    model = library.add_arrays(box.vertices, box.faces, "box")
    folder = library.save(tmp_path / "library")
    assert {mode(p) for p in folder.iterdir()} == {0o644}
    session = Session.simulated(make_truth(model, rng=1), library, seed=1)
    path = session.save(tmp_path / "trial.npz")
    assert mode(path) == 0o644


def test_paper_records_use_unique_temporaries(tmp_path, umask_022):
    """Benchmark records no longer share a fixed ``.tmp`` name between writers."""
    from tactile_viz.experiments.paper import write_json

    write_json(tmp_path / "a.json", {"x": 1})
    assert (tmp_path / "a.json").read_text() == '{\n "x": 1\n}'
    assert mode(tmp_path / "a.json") == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]
