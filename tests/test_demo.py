"""The main job, end to end, in its reduced (CI) mode."""

import json

import pytest

from graspsim.cli import main


@pytest.mark.slow
def test_quick_demo_runs_end_to_end(tmp_path, capsys):
    out = tmp_path / "demo"
    code = main(["demo", "--quick", "--out", str(out), "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["status"] == "complete"
    assert [p["primitive"] for p in s["parts"]] == ["cylinder", "cylinder"]
    assert s["accepted"] > 0 and len(s["trials"]) == 6
    assert 0 < s["clear_of_table"] <= s["accepted"]  # the trials' pool, said in words
    assert s["feasible"] >= 1 and s["success"] / s["feasible"] >= 0.5
    for f in ("adapted_map.h5", "adapted_map.png", "summary.json"):
        assert (out / f).stat().st_size > 0
    assert json.loads((out / "summary.json").read_text())["grasps"] == s["grasps"]
    assert (out / "db" / "index.json").exists()  # the quick database, built on first use
