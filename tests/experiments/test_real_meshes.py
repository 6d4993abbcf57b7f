"""The real-mesh check: its plumbing on meshes written here, pybullet only for one smoke test."""

import json
import sys
import types

import numpy as np
import pytest
import trimesh

from tactile_viz.__main__ import build_parser as cli_parser, main as cli_main
from tactile_viz.engine.errors import TactileVizError
from tactile_viz.experiments import real_meshes as rm
from tactile_viz.experiments.real_meshes import RealMesh, RealMeshError
from tactile_viz.experiments.runner import run_task
from tactile_viz.experiments.trial_files import read_trial


# ------------------------------------------------------------------------ missing pybullet
def test_missing_pybullet_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pybullet_data", None)  # import raises ImportError
    with pytest.raises(RealMeshError, match=r"pip install -e '\.\[realmesh\]'") as caught:
        rm.data_path()
    assert isinstance(caught.value, TactileVizError)


def test_missing_pybullet_is_a_clean_cli_error(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "pybullet_data", None)
    assert cli_main(["bench", "realmesh", "--out", str(tmp_path)]) == 2
    assert "[realmesh]" in capsys.readouterr().err


def test_missing_data_folder(monkeypatch, tmp_path):
    fake = types.SimpleNamespace(getDataPath=lambda: str(tmp_path / "gone"))
    monkeypatch.setitem(sys.modules, "pybullet_data", fake)
    with pytest.raises(RealMeshError, match="does not exist"):
        rm.data_path()


def test_registered_as_a_benchmark():
    args = cli_parser().parse_args(["bench", "realmesh", "--trials", "1"])
    assert (args.what, args.rest) == ("realmesh", ["--trials", "1"])


# ------------------------------------------------------------------------ meshes and pairs
@pytest.fixture(scope="module")
def mesh_dir(tmp_path_factory):
    """Primitives standing in for pybullet_data: a box, its 'collision hulls' (two
    overlapping boxes), an open sheet, an icosphere, a capsule and an empty file."""
    folder = tmp_path_factory.mktemp("pybullet_data")
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(folder / "box.obj")
    hulls = trimesh.util.concatenate([trimesh.creation.box(extents=(2.0, 1.0, 1.0)),
                                      trimesh.creation.box(extents=(1.0, 1.0, 2.0))])
    hulls.export(folder / "box_vhacd.obj")
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                    [[0, 1, 2], [0, 2, 3]]).export(folder / "sheet.obj")
    (folder / "shapes").mkdir()
    trimesh.creation.icosphere(subdivisions=2).export(folder / "shapes" / "ball.stl")
    trimesh.creation.capsule(height=2.0, radius=0.5).export(folder / "pill.ply")
    (folder / "empty.obj").write_text("")
    return folder


CATALOGUE = (
    RealMesh("block", ("box.obj", "box_vhacd.obj"), "visual mesh first"),
    RealMesh("hulls", ("missing.obj", "sheet.obj"), "nothing usable"),
    RealMesh("ball", ("empty.obj", "shapes/ball.stl"), "falls back to the second file"),
    RealMesh("pill", ("pill.ply",), "a capsule"),
)


@pytest.fixture(scope="module")
def loaded(mesh_dir):
    return rm.load_real_meshes(mesh_dir, CATALOGUE, rng=0)


def test_loading_prefers_the_first_usable_file(loaded):
    models, used, skipped = loaded
    assert list(models) == ["block", "ball", "pill"]
    assert {m["name"]: m["file"] for m in used} == {
        "block": "box.obj", "ball": "shapes/ball.stl", "pill": "pill.ply"}
    assert all(m["inner_fraction"] <= rm.MAX_INNER_FRACTION for m in used)
    assert models["block"].length == pytest.approx(6.0)  # normalised by ObjectModel


def test_unusable_entries_are_skipped_with_every_reason(loaded):
    _, _, skipped = loaded
    assert list(skipped) == ["hulls"]
    reason = skipped["hulls"]
    assert "missing.obj: no such file" in reason
    assert "sheet.obj:" in reason and "no inside" in reason


def test_overlapping_parts_are_measured(mesh_dir):
    from tactile_viz.engine.shape.objects import ObjectModel

    raw = trimesh.load(mesh_dir / "box_vhacd.obj", force="mesh", process=False)
    hulls = ObjectModel("hulls", raw)  # the parts as they are, inner walls and all
    box = ObjectModel.from_file(mesh_dir / "box.obj")
    assert rm.inner_surface_fraction(hulls, rng=1) > 0.1
    assert rm.inner_surface_fraction(box, rng=1) == 0.0
    # Loading unites overlapping parts, so no inner wall is left.
    united = ObjectModel.from_file(mesh_dir / "box_vhacd.obj")
    assert rm.inner_surface_fraction(united, rng=1) == 0.0


def test_pairs_leave_the_truth_out_only_when_novel():
    names = ["block", "ball", "pill"]
    assert rm.prior_names("ball", "novel", names) == ["block", "pill"]
    assert rm.prior_names("ball", "known", names) == names
    with pytest.raises(ValueError, match="case"):
        rm.prior_names("ball", "other", names)


def test_tasks_pair_the_cases_at_the_same_seeds():
    files = {"block": "/m/box.obj", "ball": "/m/ball.stl", "pill": "/m/pill.ply"}
    tasks = rm.make_tasks(["ball"], files, trials=2, seed=5, max_steps=3)
    assert [(t["case"], t["seed"]) for t in tasks] == [
        ("novel", 5), ("known", 5), ("novel", 6), ("known", 6)]
    novel, known = tasks[0], tasks[1]
    assert [p["name"] for p in novel["extra_priors"]] == ["block", "pill"]
    assert [p["name"] for p in known["extra_priors"]] == ["block", "ball", "pill"]
    assert novel["object_file"] == "/m/ball.stl" and novel["longest_side"] == 6.0
    assert rm.task_key(novel) == "ball__novel__gpis-dhd__recommended__s5__m3"
    json.dumps(tasks)


def test_expected_outcome_of_each_case():
    assert rm.expected("novel", "duck", "mug_1", True)
    assert not rm.expected("novel", "duck", "duck", False)
    assert rm.expected("known", "duck", "duck", False)
    assert not rm.expected("known", "duck", "mug_1", False)
    assert not rm.expected("known", "duck", "duck", True)


def test_object_names_are_checked(loaded):
    models, _, skipped = loaded
    assert rm.choose_objects(None, models, skipped) == ["block", "ball", "pill"]
    assert rm.choose_objects(["pill,ball"], models, skipped) == ["pill", "ball"]
    with pytest.raises(RealMeshError, match="unknown"):
        rm.choose_objects(["nope"], models, skipped)
    with pytest.raises(RealMeshError, match="cannot use hulls"):
        rm.choose_objects(["hulls"], models, skipped)


# ------------------------------------------------------------------------ summary
def _result(name, case, seed, map_class, novel, coverage=None, recon=None, terminated=None):
    last = {"t": 4, "map_class": map_class, "novel": novel, "pose_error": 1.0 + seed,
            "recon_error": recon, "dhd": 1.0, "n_particles": 10}
    if coverage is not None:
        last["truth_coverage"] = coverage
    return {"object": name, "seed": seed, "strategy": "gpis-dhd", "seconds": 2.0,
            "terminated_at": terminated, "steps": [dict(last, t=1), last],
            "task": {"case": case, "truth_file": f"/data/{name}.obj"}}


SYNTHETIC = [
    _result("duck", "novel", 0, "mug_1", True, coverage=0.5, recon=0.8, terminated=4),
    _result("duck", "novel", 1, "duck_x", False, coverage=0.7, recon=0.3),
    _result("duck", "known", 0, "duck", False, coverage=0.4),
    _result("duck", "known", 1, "duck", False, coverage=0.6),
    {"object": "duck", "seed": 2, "task": {"case": "known"}, "error": "Traceback\nBoom: x"},
]


def test_summary_rows_per_object_and_case():
    header, rows = rm.summary_rows([rm.summarise(r) for r in SYNTHETIC])
    table = {(row[0], row[1]): dict(zip(header, row)) for row in rows}
    novel, known = table["duck", "novel"], table["duck", "known"]
    assert novel["trials"] == 2 and known["trials"] == 2  # the failed trial is left out
    assert novel["as expected"] == "1/2" and novel["judged novel"] == "1/2"
    assert novel["MAP class"] == "mug_1 1, duck_x 1"
    assert novel["final pose error"] == pytest.approx(1.5)
    assert novel["final recon error (novel)"] == pytest.approx(0.8)  # judged novel only
    assert novel["final truth coverage"] == pytest.approx(0.6)
    assert novel["terminated"] == "1/2" and novel["steps"] == 4 and novel["file"] == "duck.obj"
    assert known["as expected"] == "2/2" and known["MAP class"] == "duck 2"
    assert known["final recon error (novel)"] is None


def test_summary_without_truth_coverage():
    results = [_result("bunny", "known", 0, "bunny", False)]
    header, rows = rm.summary_rows([rm.summarise(r) for r in results])
    assert "final truth coverage" not in header and len(rows[0]) == len(header)
    assert rows[0][header.index("MAP class")] == "bunny"
    assert "| bunny | known | bunny.obj | 1 | 1/1 | 0/1 | bunny |" in rm.summary_table(
        [rm.summarise(r) for r in results])


def test_report_only_rebuilds_the_summary(tmp_path, capsys):
    (tmp_path / "trials").mkdir()
    for index, result in enumerate(SYNTHETIC):
        (tmp_path / "trials" / f"t{index}.json").write_text(json.dumps(result))
    assert rm.main(["--report-only", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "summary.md").read_text()
    assert "| duck | novel | duck.obj | 2 | 1/2 |" in text
    assert "FAILED duck known seed 2: Boom: x" in text
    assert "| object | case |" in capsys.readouterr().out
    assert len(json.loads((tmp_path / "summary.json").read_text())) == 5


def test_report_of_an_empty_folder(tmp_path):
    with pytest.raises(RealMeshError, match="no trial files"):
        rm.report(tmp_path)


# ------------------------------------------------------------------------ end to end
def test_run_on_a_folder_of_meshes(mesh_dir, tmp_path, monkeypatch):
    """The whole command on the primitives (no pybullet, no bundled priors, 2 steps)."""
    monkeypatch.setattr(rm, "CATALOGUE", CATALOGUE)
    out = tmp_path / "out"
    assert rm.main(["--data-dir", str(mesh_dir), "--objects", "pill", "--trials", "1",
                    "--max-steps", "2", "--bundled", "none", "--out", str(out),
                    "--no-progress"]) == 0
    trials = sorted(p.name for p in (out / "trials").glob("*"))
    assert trials == ["pill__known__gpis-dhd__recommended__s0__m2.json.gz",
                      "pill__novel__gpis-dhd__recommended__s0__m2.json.gz"]
    novel = read_trial(out / "trials" / trials[1])
    assert "error" not in novel, novel.get("error")
    assert novel["library"] == ["block", "ball"] and len(novel["steps"]) == 2
    assert novel["object_size"] == pytest.approx(6.0)  # normalised to the paper's size
    known = read_trial(out / "trials" / trials[0])
    assert known["library"] == ["block", "ball", "pill"]
    meshes = json.loads((out / "meshes.json").read_text())
    assert list(meshes["skipped"]) == ["hulls"]
    summary = (out / "summary.md").read_text()
    assert "skipped hulls:" in summary and "| pill | novel | pill.ply | 1 |" in summary


def test_pybullet_meshes_smoke():
    """The duck from pybullet_data as truth, the bunny as the other prior, 3 steps."""
    pytest.importorskip("pybullet_data")
    root = rm.data_path()
    entries = [e for e in rm.CATALOGUE if e.name in ("duck", "bunny")]
    models, used, skipped = rm.load_real_meshes(root, entries)
    assert list(models) == ["duck", "bunny"] and not skipped
    assert used[0]["file"] == "duck.obj"  # the visual mesh, not duck_vhacd.obj
    files = {m["name"]: str(root / m["file"]) for m in used}
    task = rm.make_tasks(["duck"], files, cases=["known"], max_steps=3, bundled="none")[0]
    result = run_task(task)
    assert "error" not in result, result.get("error")
    assert len(result["steps"]) == 3 and result["library"] == ["duck", "bunny"]
    assert np.isfinite(rm.summarise(result)["pose_error"])
