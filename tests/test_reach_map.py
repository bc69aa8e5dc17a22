"""A map's ``reachable`` column: computed by the arm (graspsim.robots.mark_reach), kept by
the map file (written atomically, trial results kept), preferring reachable grasps in the
ranking and the trial selection, and ``graspsim reach``'s bad input refused with nothing
written."""

import hashlib
import json

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.errors import MapFileError
from graspsim.grippers import get_gripper
from graspsim.maps import load_map, read_sim_results, save_map, write_reach, write_sim_results
from graspsim.maps.graspmap import REACH_EXACT, REACH_FIRST_CUT, REACH_NONE
from graspsim.maps.robust import ranking
from graspsim.primitives import Box
from graspsim.sim.mapsim import select_grasps

FRANKA = get_gripper("franka_hand")
BOX = Box(0.05, 0.05, 0.05)


def _map(grades=None):
    """A 5 cm box: the best-graded grasp approaches from under the table (no arm reaches
    it), then one from above, one from the side."""
    d = FRANKA.nominal_depth
    T = np.stack([grasp_pose([0, 0, 0], [0, 0, 1], [1, 0, 0], depth=d, gripper=FRANKA),  # from below
                  grasp_pose([0, 0, 0], [0, 0, -1], [1, 0, 0], depth=d, gripper=FRANKA),  # from above
                  grasp_pose([0, 0, 0], [1, 0, 0], [0, 1, 0], depth=d, gripper=FRANKA)])  # from the side
    return hand_made_map(BOX, T, [0.05] * 3, gripper=FRANKA, grades=grades or [0.99, 0.9, 0.8], mass=0.1)


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_column_round_trips_through_the_file_and_write_reach_keeps_the_rest(tmp_path):
    from dataclasses import replace

    f = tmp_path / "m.h5"
    col = np.array([REACH_NONE, REACH_EXACT, np.nan], np.float32)
    gmap = replace(_map(), reachable=col).with_meta(extra={"reach": {"robot": "panda"}})
    save_map(gmap, f)
    back = load_map(f)
    np.testing.assert_array_equal(back.reachable, col)  # NaN where unchecked, too
    assert back.meta.extra["reach"] == {"robot": "panda"}
    save_map(_map(), f)  # a map without the column: all NaN, nothing written for it
    assert not load_map(f).has_reach
    write_sim_results(f, {"outcome": np.array([1, 0, 1], np.int8)}, "grasps/qualities/mujoco")
    write_reach(f, [REACH_FIRST_CUT, REACH_EXACT, REACH_NONE], {"robot": "panda", "base": [-0.5, 0, 0]})
    back = load_map(f)
    np.testing.assert_array_equal(back.reachable, [REACH_FIRST_CUT, REACH_EXACT, REACH_NONE])
    assert back.meta.extra["reach"]["base"] == [-0.5, 0, 0]
    assert read_sim_results(f)["outcome"].tolist() == [1, 0, 1]  # the trial results kept
    before = _digest(f)
    with pytest.raises(MapFileError, match="2 rows"):
        write_reach(f, [REACH_EXACT, REACH_EXACT], {})
    assert _digest(f) == before  # nothing written
    bad = replace(_map(), reachable=np.array([0.3, 1.0, 0.0], np.float32))
    from graspsim.maps import map_problems

    assert any("reachable holds values" in p for p in map_problems(bad))


def test_the_ranking_puts_unreachable_grasps_after_reachable_ones():
    from dataclasses import replace

    gmap = _map()
    assert ranking(gmap).tolist() == [0, 1, 2]  # by grade: no column
    # row 0 unreachable, row 2 planned exactly, row 1 passed the first cut only
    marked = replace(gmap, reachable=np.array([REACH_NONE, REACH_FIRST_CUT, REACH_EXACT], np.float32))
    for rank in ("robust", "paper"):
        assert ranking(marked, rank).tolist() == [2, 1, 0]
        assert ranking(marked, rank, reach=False).tolist() == [0, 1, 2]
    assert select_grasps(marked, top=1).tolist() == [2]  # graspsim trial --top 1 runs the reachable one
    unchecked = replace(gmap, reachable=np.array([REACH_NONE, np.nan, REACH_EXACT], np.float32))
    assert ranking(unchecked).tolist() == [2, 1, 0]  # unchecked between reachable and unreachable


@pytest.mark.slow
def test_the_arm_marks_a_maps_grasps_and_graspsim_reach_writes_them(tmp_path, monkeypatch, capsys):
    from graspsim.cli import main
    from graspsim.robots import mark_reach_file

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))  # the capability map: not the user's cache
    f = tmp_path / "box.h5"
    save_map(_map(), f)
    record = mark_reach_file(f, exact=3)
    back = load_map(f)
    assert back.reachable[0] == REACH_NONE  # from under the table: refused
    assert back.reachable[1] == REACH_EXACT  # from above, 0.5 m from the base: planned
    assert record["robot"] == "panda" and record["base"] == [-0.5, 0.0, 0.0]
    assert back.meta.extra["reach"]["T_world_obj"] == record["T_world_obj"]
    assert back.ranked().reachable[0] == REACH_EXACT
    # the command: a bad base is one line, exit 2, the file untouched
    before = _digest(f)
    for base in (["5", "0", "0"], ["0", "0", "nan"]):
        assert main(["reach", str(f), "--robot", "panda", "--robot-base", *base]) == 2
        err = capsys.readouterr().err
        assert "--robot-base" in err and "within 2 m" in err and len(err.strip().splitlines()) == 1
        assert _digest(f) == before
    with pytest.raises(SystemExit) as exc:  # no arm named: argparse's usage error
        main(["reach", str(f), "--robot-base", "0", "0", "0"])
    assert exc.value.code == 2
    capsys.readouterr()
    assert _digest(f) == before
    # a gripper simulated from its spec (the Festo) goes on the flange too: its map is marked
    g = tmp_path / "festo.h5"
    save_map(hand_made_map(BOX, grasp_pose([0, 0, 0], [0, 0, -1], [1, 0, 0])[None], [0.05]), g)
    assert main(["reach", str(g), "--robot", "panda"]) == 0
    capsys.readouterr()
    assert load_map(g).meta.extra["reach"]["robot"] == "panda"
    assert main(["reach", str(f), "--robot", "panda", "--robot-base", "-0.5", "0", "0", "--exact", "1",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["exact_checked"] == 1 and out["robot_base"] == [-0.5, 0.0, 0.0]
    assert load_map(f).meta.extra["reach"]["exact"]["rows"] == 1
    assert main(["info", str(f), "--json"]) == 0  # info says what the column holds
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["reach"]
    assert info["robot"] == "panda" and info["exact"] + info["first_cut"] + info["unreachable"] == 3


def test_adapt_refuses_an_arm_it_cannot_judge_before_reading_the_cloud(tmp_path, capsys):
    from graspsim.cli import main

    out = tmp_path / "a.h5"
    for extra, words in ((["--reach-exact", "5"], "--reach-exact needs --robot panda"),
                         (["--robot", "panda", "--gripper", "franka_hand", "--robot-base", "0", "3", "0"],
                          "within 2 m")):
        assert main(["adapt", str(tmp_path / "missing.npy"), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.slow
def test_adapt_with_an_arm_writes_the_maps_reachable_column(tmp_path, monkeypatch, capsys):
    from graspsim.cli import main
    from graspsim.primitives import Cylinder, synthetic_cloud
    from graspsim.transforms import make_transform

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))
    rng = np.random.default_rng(2)
    c = synthetic_cloud(Cylinder(0.022, 0.15), rng, resolution=0.004, noise=0.0005,
                        T_world_obj=make_transform(np.eye(3), [0.0, 0.0, 0.075]))
    np.save(tmp_path / "cloud.npy", c.points)
    coarse = ["--surface-step", "0.01", "--rotation-step-deg", "30", "--gripper", "franka_hand"]
    out = tmp_path / "a.h5"
    assert main(["adapt", str(tmp_path / "cloud.npy"), "-o", str(out), "--db", str(tmp_path / "db"), *coarse,
                 "--table", "auto", "--robot", "panda", "--reach-exact", "10", "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    gmap = load_map(out)
    assert gmap.has_reach and s["reach"]["robot"] == "panda" and s["reach"]["exact_checked"] == 10
    assert s["reach"]["exact"] == int((gmap.reachable == REACH_EXACT).sum()) >= 1
    assert np.all(np.isin(gmap.reachable, [REACH_EXACT, REACH_FIRST_CUT, REACH_NONE]))  # every row judged
    top = gmap.ranked()
    k = s["reach"]["exact"]
    assert np.all(top.reachable[:k] == REACH_EXACT)


def test_a_trial_names_what_differs_from_the_maps_reach_record():
    from graspsim.robots import base_transform
    from graspsim.robots.maptrials import reach_mismatch

    B, O = base_transform((-0.5, 0.0, 0.0)), np.eye(4)
    record = {"robot": "panda", "T_world_base": B.tolist(), "T_world_obj": O.tolist()}
    assert reach_mismatch(None, "panda", B, O) is None and reach_mismatch(record, "panda", B, O) is None
    assert reach_mismatch(record, "panda", base_transform((-0.4, 0.0, 0.0)), O) == "another base"
    lifted = O.copy()
    lifted[2, 3] = 0.01
    assert reach_mismatch(record, "panda", B, lifted) == "the object standing elsewhere"
    assert "not 'ur5'" in reach_mismatch(record, "ur5", B, O)
