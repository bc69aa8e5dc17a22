"""``graspsim adapt-gripper`` and ``graspsim design``."""

import json

from graspsim.apps.design import PARAMS
from graspsim.cli import design_cmd as cli_design
from graspsim.cli import main
from graspsim.maps.io import load_map


def _last_json(capsys):
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_the_cli_names_the_libraries_design_parameters():
    assert set(cli_design.PARAMS) == set(PARAMS)


def test_adapt_gripper_writes_a_map_of_the_new_gripper(tmp_path, capsys):
    src, dst = tmp_path / "s.h5", tmp_path / "f.h5"
    assert main(["map", "sphere", "--radius", "0.03", "--surface-step", "0.01", "--rotation-step-deg", "22",
                 "-o", str(src), "--json"]) == 0
    accepted = _last_json(capsys)["accepted"]
    assert main(["adapt-gripper", str(src), "--to-gripper", "franka_hand", "-o", str(dst), "--json"]) == 0
    s = _last_json(capsys)
    m = load_map(dst)
    assert s["source_grasps"] == accepted and 0 < len(m) == s["grasps"] <= accepted
    assert m.meta.gripper_spec.name == "franka_hand"
    assert m.meta.extra["source_gripper"]["name"] == "festo_hgpl_25_60_a"


def test_adapt_gripper_refuses_an_unknown_gripper_and_writes_nothing(tmp_path, capsys):
    src = tmp_path / "s.h5"
    assert main(["map", "sphere", "--radius", "0.03", "--surface-step", "0.01", "-o", str(src)]) == 0
    capsys.readouterr()
    code = main(["adapt-gripper", str(src), "--to-gripper", "robotiq", "-o", str(tmp_path / "x.h5")])
    err = capsys.readouterr().err
    assert code == 2 and "unknown gripper 'robotiq'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.h5").exists()


def test_design_sweeps_one_parameter(tmp_path, capsys):
    out, png = tmp_path / "d.json", tmp_path / "d.png"
    assert main(["design", "--param", "stroke", "--values", "0.03", "0.06", "--primitives", "box", "sphere",
                 "--sim-grasps", "0", "--surface-step", "0.01", "--rotation-step-deg", "22",
                 "-o", str(out), "--plot", str(png), "--json"]) == 0
    s = _last_json(capsys)
    assert [(r["value"], r["kind"]) for r in s["rows"]] == [(0.03, "box"), (0.03, "sphere"),
                                                             (0.06, "box"), (0.06, "sphere")]
    assert json.loads(out.read_text())["rows"] == s["rows"] and png.stat().st_size > 10_000
    # a 3 cm stroke (6 cm opening) cannot hold the 6 cm cube across its faces: fewer grasps
    assert s["rows"][0]["accepted"] < s["rows"][2]["accepted"]
    code = main(["design", "--param", "stroke", "--values", "0.03", "--primitives", "torus"])
    assert code == 2 and "--primitives" in capsys.readouterr().err


def test_adapt_gripper_and_design_take_a_model_file(tmp_path, capsys):
    import shutil

    from graspsim.grippers import get_gripper, model_folder

    shutil.copytree(model_folder("rethink_gripper"), tmp_path / "g")
    model = str(tmp_path / "g" / "rethink_gripper.xml")
    src, dst = tmp_path / "s.h5", tmp_path / "r.h5"
    assert main(["map", "sphere", "--radius", "0.02", "--surface-step", "0.01", "--rotation-step-deg", "22",
                 "-o", str(src), "--json"]) == 0
    capsys.readouterr()
    assert main(["adapt-gripper", str(src), "--to-gripper", model, "-o", str(dst), "--json"]) == 0
    assert _last_json(capsys)["gripper"] == "rethink_gripper"
    m = load_map(dst)  # the adapted map records the model file: its trials simulate it as authored
    assert len(m) > 0 and m.meta.gripper_spec == get_gripper(model) and m.meta.gripper_spec.model == str(
        (tmp_path / "g" / "rethink_gripper.xml").resolve())
    assert main(["design", "--gripper", model, "--param", "finger_length", "--values", "0.045",
                 "--primitives", "cylinder", "--sim-grasps", "0", "--surface-step", "0.01",
                 "--rotation-step-deg", "22", "--threads", "1", "--json"]) == 0
    s = _last_json(capsys)
    assert s["gripper"] == "rethink_gripper" and s["rows"][0]["gripper"] == "rethink_gripper[finger_length=45mm]"
    assert s["rows"][0]["accepted"] > 0  # the variant of the measured spec takes the 4 cm cylinder
