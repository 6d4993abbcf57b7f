import numpy as np
import pytest

from tactile_viz.__main__ import main
from tactile_viz.engine.explore.observations import Contact, NonContact
from tactile_viz.engine.io.observation_file import (
    ObservationFileError,
    RecordedStep,
    format_observations,
    parse_observations,
    read_observations,
    write_observations,
)

GOOD = """step,kind,x,y,z,nx,ny,nz
1,contact,0.5,-0.2,1.3,0,0.6,0.8
2,noncontact,2.0,0.4,0.1,,,
2,free,1.7,0.4,0.1,,,
2,contact,1.1,0.3,0.2,0.9,0.1,0.4
"""


def test_steps_group_rows_and_free_rows_stay_out_of_the_observations():
    steps = parse_observations(GOOD)
    assert [len(s.observations) for s in steps] == [1, 2]
    assert isinstance(steps[1].observations[0], NonContact)
    np.testing.assert_allclose(steps[1].free_space, [[1.7, 0.4, 0.1]])
    np.testing.assert_allclose(steps[0].observations[0].normal, [0, 0.6, 0.8])
    # The contact normal is renormalised like any contact.
    assert np.linalg.norm(steps[1].observations[1].normal) == pytest.approx(1.0)


def test_without_a_step_column_every_row_is_a_step():
    text = "kind,x,y,z,nx,ny,nz\n# a comment\n\ncontact,0,0,1,0,0,1\nnoncontact,0,0,3,,,\n"
    steps = parse_observations(text)
    assert len(steps) == 2 and isinstance(steps[1].observations[0], NonContact)


def test_written_file_reads_back_bit_for_bit(tmp_path, rng):
    normals = rng.normal(size=(5, 3))
    steps = [RecordedStep([Contact(rng.normal(size=3), n)]) for n in normals]
    steps.append(RecordedStep([NonContact([1e-300, -3.3, 7.0])], rng.normal(size=(3, 3))))
    path = write_observations(tmp_path / "touches.csv", steps)
    again = read_observations(path)
    for before, after in zip(steps, again):
        for a, b in zip(before.observations, after.observations):
            np.testing.assert_array_equal(a.position, b.position)
            if isinstance(a, Contact):
                np.testing.assert_array_equal(a.normal, b.normal)
        np.testing.assert_array_equal(before.free_space, after.free_space)
    assert format_observations(again) == path.read_text()


@pytest.mark.parametrize("text, line, fault", [
    ("kind,x,y,z\ncontact,0,0,0\n", 1, "header"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,nan,0,0,1\n", 2, "z is not finite"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,0,0,0\n", 2, "zero length"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,,,\n", 2, "needs its normal"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,0,1,\n", 2, "needs its normal"),
    ("step,kind,x,y,z,nx,ny,nz\n1,noncontact,0,0,0,0,0,1\n", 2, "has no normal"),
    ("step,kind,x,y,z,nx,ny,nz\n1,touch,0,0,0,,,\n", 2, "kind must be"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,zero,0,0,0,1\n", 2, "y is not a number"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,0,0\n", 2, "expected 8 fields"),
    ("step,kind,x,y,z,nx,ny,nz\n2,contact,0,0,0,0,0,1\n1,contact,0,0,1,0,0,1\n", 3,
     "must not decrease"),
    ("step,kind,x,y,z,nx,ny,nz\n1.5,contact,0,0,0,0,0,1\n", 2, "step is not an integer"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,1e9,0,0,1\n", 2, "out of range"),
    ("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0," + "1" * 200_000 + ",0,0,1\n", 2, "not CSV"),
])
def test_each_fault_is_one_error_naming_file_line_and_fault(tmp_path, text, line, fault):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ObservationFileError, match=fault) as caught:
        read_observations(path)
    assert caught.value.line == line
    assert str(caught.value).startswith(f"{path}, line {line}: ")


@pytest.mark.parametrize("text, fault", [
    ("", "empty"),
    ("step,kind,x,y,z,nx,ny,nz\n", "no observation"),
    ("step,kind,x,y,z,nx,ny,nz\n1,free,0,0,0,,,\n", "only free rows"),
    ("kind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\nfree,0,0,2,,,\n", "belong to no step"),
])
def test_files_without_usable_steps_are_refused(tmp_path, text, fault):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ObservationFileError, match=fault):
        read_observations(path)


def test_a_byte_order_mark_is_not_part_of_the_header(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("\ufeffkind,x,y,z,nx,ny,nz\ncontact,0,0,1,0,0,1\n".encode("utf-8"))
    assert len(read_observations(path)) == 1


def test_missing_or_binary_file(tmp_path):
    with pytest.raises(ObservationFileError, match="cannot read"):
        read_observations(tmp_path / "absent.csv")
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ObservationFileError, match="binary.csv"):
        read_observations(tmp_path / "binary.csv")


def test_replay_command_reports_a_bad_file_in_one_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("step,kind,x,y,z,nx,ny,nz\n1,contact,0,0,0,,,\n")
    out = tmp_path / "out.json"
    assert main(["replay", "--observations", str(path), "--json", str(out),
                 "--export", str(tmp_path / "export"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"python -m tactile_viz replay: error: {path}, line 2: a contact needs "
                   "its normal (nx, ny, nz)")
    assert not out.exists() and not (tmp_path / "export").exists()
