import json
import subprocess
import sys

from tactile_viz.__main__ import main


def test_objects_json_contract(capsys):
    assert main(["objects", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert len(listed) == 20
    assert all(set(item) == {"name", "set"} for item in listed)
    assert sum(item["set"] == "known" for item in listed) == 10
    assert {"mug_1", "home_chair"} <= {item["name"] for item in listed}


def test_objects_table_for_people():
    result = subprocess.run([sys.executable, "-m", "tactile_viz", "objects"],
                            capture_output=True, text=True, check=True)
    lines = result.stdout.splitlines()
    assert lines[0].split()[:2] == ["name", "set"]
    assert any(line.split()[:3] == ["mug_2", "novel", "mug_1"] for line in lines)


def test_help_lists_commands():
    result = subprocess.run([sys.executable, "-m", "tactile_viz", "--help"],
                            capture_output=True, text=True, check=True)
    assert "objects" in result.stdout and "bench" in result.stdout
