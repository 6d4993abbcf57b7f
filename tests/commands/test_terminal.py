"""What a person sees in the terminal: one-line warnings, a quiet end on a closed pipe, and
a short summary at the end of a trial (``--quiet`` silences it)."""

import json
import subprocess
import sys

import trimesh

from tactile_viz.__main__ import main
from tactile_viz.commands.summary import result_summary


def test_a_closed_pipe_ends_quietly_with_status_0():
    command = f"{sys.executable} -m tactile_viz objects | head -1"
    result = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split()[:2] == ["name", "set"]
    assert "Error" not in result.stderr and "Traceback" not in result.stderr


def test_a_repaired_mesh_warns_in_one_line_and_the_trial_sums_up(tmp_path, capsys):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=3.0)
    sphere.faces = sphere.faces[:-1]  # one small hole: closed on loading, with a warning
    sphere.export(tmp_path / "holey.stl")
    out = tmp_path / "out.json"
    assert main(["trial", "--object-file", str(tmp_path / "holey.stl"), "--library", "known",
                 "--max-steps", "3", "--no-progress", "--json", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    warnings = [line for line in err if "warning" in line]
    assert warnings == ["python -m tactile_viz trial: warning: holey.stl: repaired on "
                        "loading: 1 hole closed"]
    assert err[-1] == f"  JSON: {out}"
    verdict = next(line for line in err if line.startswith("holey: "))
    assert "ran to step 3 without stopping" in verdict
    assert json.loads(out.read_text())["steps"][-1]["t"] == 3
    assert main(["trial", "--object", "mug_1", "--library", "known", "--max-steps", "1",
                 "--no-progress", "--json", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_the_summary_says_what_was_judged_when_and_where_the_files_went():
    step = {"t": 14, "n_contacts": 12, "n_noncontacts": 5, "novel": False,
            "map_class": "mug_1", "map_rotation": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
            "map_translation": [0.1, 0.0, 0.02], "pose_error": 0.003,
            "rotation_error_deg": 0.5}
    result = {"object": "mug_1", "steps": [step], "units": "m", "decided_at": 14,
              "terminated_at": 14, "seconds": 2.0, "library": ["mug_1", "mug_2"],
              "truth_pose": {}}
    lines = result_summary(result, [("JSON", "out.json")])
    assert lines[0] == ("mug_1: known: mug_1, decided at step 14; stopped by itself at "
                        "step 14 (12 contacts, 5 misses, 2.0 s)")
    assert lines[1] == "  MAP pose: turned 90.0 deg about (1, 0, 0), at (0.1, 0, 0.02) m"
    assert "pose error 0.003 m" in lines[2] and lines[-1] == "  JSON: out.json"
    novel = dict(result, decided_at=None, terminated_at=None, truth_pose=None,
                 steps=[dict(step, novel=True)])
    lines = result_summary(novel)
    assert lines == ["mug_1: novel (none of the 2 priors); ran to step 14 without "
                     "stopping (12 contacts, 5 misses, 2.0 s)"]
    lines = result_summary(dict(novel, steps=[dict(step, novel=True, gpis_prior="ellipsoid")]))
    assert lines[0].startswith("mug_1: novel (none of the 2 priors), reconstructed from an "
                               "ellipsoid fitted to the contacts; ran to step 14")
    lines = result_summary(dict(novel, steps=[dict(step, novel=True, gpis_prior="mug_2")]))
    assert "reconstructed from the prior mug_2;" in lines[0]
    assert result_summary({"steps": []}) == ["no step was taken"]
    # A session the step cap ended did not stop by itself.
    capped = dict(novel, terminated_at=14, params={"max_steps_novel": 14, "max_steps_known": 9})
    assert "; stopped at its step cap (14) (12 contacts" in result_summary(capped)[0]
    assert "stopped by itself at step 14" in result_summary(
        dict(capped, params={"max_steps_novel": 400}))[0]


def test_ctrl_c_keeps_the_touches_done_and_says_interrupted(tmp_path, capsys, monkeypatch):
    from tactile_viz.engine import Session

    step, calls = Session.step, []

    def interrupted_at_three(self):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return step(self)

    monkeypatch.setattr(Session, "step", interrupted_at_three)
    out, export = tmp_path / "out.json", tmp_path / "export"
    status = main(["trial", "--object", "mug_1", "--library", "known", "--max-steps", "10",
                   "--no-progress", "--json", str(out), "--export", str(export)])
    assert status == 130
    result = json.loads(out.read_text())
    assert result["interrupted"] is True and len(result["steps"]) == 2
    recording = (export / "observations.csv").read_text()
    assert recording.startswith("# interrupted: at step 2")
    assert json.loads((export / "estimate.json").read_text())["interrupted"] is True
    from tactile_viz.engine.io.observation_file import read_observations

    assert len(read_observations(export / "observations.csv")) == 2  # the mark is a comment
    assert "interrupted at step 2" in capsys.readouterr().err
    calls.clear()
    monkeypatch.setattr(Session, "step", lambda self: (_ for _ in ()).throw(KeyboardInterrupt))
    assert main(["trial", "--object", "mug_1", "--library", "known", "--no-progress",
                 "--json", str(tmp_path / "none.json")]) == 130
    assert not (tmp_path / "none.json").exists()  # nothing done, nothing written


def test_an_object_far_smaller_than_the_priors_is_named_as_the_likely_cause(tmp_path, capsys):
    """No first contact: the error says how near the origin the lines pass and asks about
    the size, after the size warning."""
    trimesh.creation.icosphere(radius=0.05).export(tmp_path / "tiny.stl")
    assert main(["trial", "--object-file", str(tmp_path / "tiny.stl"), "--library", "known",
                 "--no-progress", "--quiet", "--json", str(tmp_path / "t.json")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "60 times smaller" in err[0]
    assert err[-1].endswith("within 0.866 of the origin and the rest within 2.6, as the "
                            "priors' size sets it: is the object there, and of about the "
                            "priors' size?")
    assert not (tmp_path / "t.json").exists()
