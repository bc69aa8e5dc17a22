"""``--gripper`` on the commands where the gripper matters: maps, the database, trials,
identify's lookup; a user's own JSON spec gets maps and trials; a bad one is one line."""

import json

import pytest

from graspsim.cli import main
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.maps import load_map

COARSE = ["--surface-step", "0.01", "--rotation-step-deg", "22"]
MY_GRIPPER = GripperSpec(name="my_gripper", housing_size=(0.12, 0.04, 0.05), jaw_size=(0.02, 0.04, 0.01),
                         finger_size=(0.008, 0.015, 0.06), pad_length=0.03, stroke_per_jaw=0.035,
                         rated_force=100.0, closing_speed=0.1)


def _last_json(capsys):
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


@pytest.fixture()
def spec_file(tmp_path):
    path = tmp_path / "my_gripper.json"
    path.write_text(MY_GRIPPER.to_json())
    return path


def test_a_json_spec_gets_its_own_map_and_trials(tmp_path, spec_file, capsys):
    f = tmp_path / "box.h5"
    assert main(["map", "box", "--x", "0.04", "--y", "0.04", "--z", "0.04", "-o", str(f), *COARSE,
                 "--gripper", str(spec_file), "--json"]) == 0
    assert _last_json(capsys)["gripper"] == "my_gripper"
    gmap = load_map(f)
    assert gmap.meta.gripper_spec == MY_GRIPPER
    assert gmap.width.max() <= MY_GRIPPER.max_opening + 1e-9
    assert main(["trial", str(f), "--sample", "8", "--min-grade", "0.7", "--threads", "1", "--no-write",
                 "--json", "--gripper", str(spec_file)]) == 0
    s = _last_json(capsys)
    # every pose that starts clear of the table (the rest approach from below) lifts and places
    assert s["trials"] == 8 and s["counts"]["success"] == s["feasible"] >= 1
    # the map's poses are its gripper's: another gripper is refused, in one line
    assert main(["trial", str(f), "--top", "1", "--gripper", "franka_hand"]) == 2
    err = capsys.readouterr().err
    assert "made for gripper 'my_gripper', not 'franka_hand'" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("text, message", [
    ('{"name": "g", "stroke_per_jaw": -0.01}', "stroke_per_jaw must be finite and > 0"),
    ('{"name": "g", "fingers": 3}', "unknown gripper parameters ['fingers']"),
    ("{oops", "not valid JSON"),
])
def test_a_bad_spec_is_one_line_and_exit_2_before_any_output(tmp_path, capsys, text, message):
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    out = tmp_path / "m.h5"
    code = main(["map", "sphere", "--radius", "0.02", "-o", str(out), *COARSE, "--gripper", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()
    assert main(["db", "list", "--db", str(tmp_path / "db"), "--gripper", "robotiq"]) == 2
    assert "unknown gripper 'robotiq'" in capsys.readouterr().err


def test_one_database_keeps_each_grippers_maps_apart(tmp_path, spec_file, capsys):
    root = str(tmp_path / "db")
    for g in ([], ["--gripper", str(spec_file)]):
        assert main(["db", "build", "--primitives", "cylinder", "--db", root, *COARSE, *g, "--json",
                     "--executor", "serial"]) == 0
        capsys.readouterr()
    assert main(["db", "list", "--db", root, "--json"]) == 0
    maps = _last_json(capsys)["maps"]
    assert sorted(m["gripper"] for m in maps) == sorted([HGPL_25_60_A.name, "my_gripper"])
    assert len({m["settings"] for m in maps}) == 2 and len({m["file"] for m in maps}) == 2
    for g, name in (([], HGPL_25_60_A.name), (["--gripper", str(spec_file)], "my_gripper")):
        assert main(["db", "lookup", "cylinder", "--radius", "0.02", "--height", "0.2", "--db", root,
                     *COARSE, *g, "--json"]) == 0
        s = _last_json(capsys)
        assert s["match"] == "known" and s["nearest"]["gripper"] == name
