import json

import pytest

from graspsim.cli import main


def _last_json(capsys):
    out = capsys.readouterr().out.strip().splitlines()
    return json.loads(out[-1])


def test_map_info_show(tmp_path, capsys):
    f = tmp_path / "c.h5"
    assert main(["map", "cylinder", "--radius", "0.02", "--height", "0.1", "-o", str(f),
                 "--surface-step", "0.01", "--json"]) == 0
    s = _last_json(capsys)
    assert s["grasps"] > 0 and 0 < s["accepted"] <= s["grasps"] and 0 < s["SR"] <= 1
    assert {"VR", "seconds"} <= set(s)
    assert main(["info", str(f), "--json"]) == 0
    assert _last_json(capsys)["grasps"] == s["grasps"]
    png = tmp_path / "c.png"
    assert main(["show", str(f), "-o", str(png), "--json"]) == 0
    assert png.stat().st_size > 10_000


def test_bad_dimensions_exit_2_with_message(tmp_path, capsys):
    code = main(["map", "cylinder", "--radius", "-0.02", "--height", "0.1", "-o", str(tmp_path / "x.h5")])
    assert code == 2
    assert "radius must be > 0" in capsys.readouterr().err
    code = main(["map", "cylinder", "--radius", "0.02", "-o", str(tmp_path / "x.h5")])
    assert code == 2 and "missing ['height']" in capsys.readouterr().err
    code = main(["map", "sphere", "--radius", "0.02", "-o", str(tmp_path / "no" / "x.h5")])
    assert code == 2 and "does not exist" in capsys.readouterr().err


def test_db_build_and_lookup(tmp_path, capsys):
    root = str(tmp_path / "db")
    args = ["--db", root, "--surface-step", "0.01", "--rotation-step-deg", "22", "--json"]
    assert main(["db", "build", "--primitives", "sphere", *args]) == 0
    assert len(_last_json(capsys)["maps"]) == 1
    # the stored sphere is the paper's, r 3.5 cm: known within 3 % of each dimension, else scaled
    assert main(["db", "lookup", "sphere", "--radius", "0.0355", *args]) == 0
    assert _last_json(capsys)["match"] == "known"
    assert main(["db", "lookup", "sphere", "--radius", "0.04", *args]) == 0  # 14 % larger (within 1 cm)
    assert _last_json(capsys)["match"] == "familiar"
    assert main(["db", "lookup", "sphere", "--radius", "0.06", *args]) == 0
    assert _last_json(capsys)["match"] == "familiar"
    assert main(["db", "list", "--db", root, "--json"]) == 0
    assert len(_last_json(capsys)["maps"]) == 1


def test_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "map" in out and "db" in out and "show" in out
