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


def test_a_cloud_file_s_camera_record_reaches_the_planner(tmp_path, monkeypatch):
    """`graspsim demo --cloud F` plans with the viewpoint F's camera record gives, so the
    robust score's occlusion term sees what the camera could not."""
    import numpy as np

    import graspsim.apps.demo as demo
    import graspsim.planning.planner as planner
    from graspsim.geometry.camera import Camera, Intrinsics, look_at
    from graspsim.tabletop.cloud_io import save_cloud

    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.03, 0.03, (400, 3))
    eye = np.array([0.4, -0.2, 0.5])
    save_cloud(tmp_path / "c.pcd", pts, camera=Camera(Intrinsics.preset("d435"), look_at(eye, np.zeros(3))),
               frame="world")
    seen = {}

    class Planned(Exception):
        pass

    def fake_plan(points, **kw):
        seen.update(kw)
        raise Planned

    monkeypatch.setattr(demo, "_database", lambda cfg, step: None)
    monkeypatch.setattr(planner, "plan", fake_plan)
    with pytest.raises(Planned):
        demo.run_demo(demo.DemoConfig(out=str(tmp_path / "out"), cloud=str(tmp_path / "c.pcd")))
    np.testing.assert_allclose(seen["viewpoint"], eye, atol=1e-9)


@pytest.mark.slow
def test_quick_demo_with_the_arm(tmp_path, capsys, monkeypatch):
    """``graspsim demo --robot panda``: the same trials planned and executed by the arm,
    its reachability verdicts in the summary."""
    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))  # the capability map: not the user's cache
    out = tmp_path / "demo"
    code = main(["demo", "--quick", "--out", str(out), "--gripper", "franka_hand", "--robot", "panda", "--json"])
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and s["robot"] == "panda" and len(s["trials"]) == 6
    assert sum(s["plan"]["reach"].values()) == 6 and s["robot_base"][0][3] == -0.5
    assert {t["outcome"] for t in s["trials"]} <= {"success", "unreachable", "approach_collision", "controller_error",
                                                   "slipped", "dropped", "no_contact", "start_collision",
                                                   "place_failed"}
    assert s["success"] >= 1
