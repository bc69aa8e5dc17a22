"""`graspsim trial`: outcome table, JSON summary, results in the file, clear errors."""

import json

import numpy as np
import pytest
from hand_made import grasp_pose, hand_made_map

from graspsim.cli import main
from graspsim.maps import read_sim_results, save_map
from graspsim.primitives import Cylinder


def _map(tmp_path, n=4):
    ang = np.linspace(0.0, np.pi / 2, n)
    T = np.stack([grasp_pose([0, 0, 0], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for a in ang])
    m = hand_made_map(Cylinder(0.02, 0.20), T, np.full(n, 0.04), grades=np.linspace(0.5, 0.9, n))
    return save_map(m, tmp_path / "cyl.h5")


def test_json_summary_and_results_in_the_file(tmp_path, capsys):
    path = _map(tmp_path)
    assert main(["trial", str(path), "--top", "3", "--threads", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["trials"] == 3 and summary["counts"]["success"] == 3
    assert summary["success_rate"] == 1.0 and summary["trials_per_second"] > 0
    assert set(summary["counts"]) >= {"success", "start_collision", "sim_unstable"}
    assert read_sim_results(path)["simulated"].sum() == 3


def test_table_output_tug_sample_and_noise(tmp_path, capsys):
    path = _map(tmp_path)
    code = main(["trial", str(path), "--protocol", "tug", "--sample", "2", "--min-grade", "0.6",
                 "--noise", "--seed", "2", "--threads", "2", "--no-write"])
    assert code == 0
    out = capsys.readouterr().out
    assert "outcome" in out and "success rate" in out
    assert read_sim_results(path) == {}


def test_empty_selection_is_an_error(tmp_path, capsys):
    path = _map(tmp_path)
    assert main(["trial", str(path), "--top", "0", "--json"]) == 2
    assert "nothing to simulate" in capsys.readouterr().err
    assert read_sim_results(path) == {}


def test_bad_input_exits_with_a_clear_error(tmp_path, capsys):
    assert main(["trial", str(tmp_path / "missing.h5")]) == 2
    assert "does not exist" in capsys.readouterr().err
    path = _map(tmp_path)
    assert main(["trial", str(path), "--mass", "-1", "--no-write"]) == 2
    assert "mass" in capsys.readouterr().err


def test_top_executes_the_best_by_the_chosen_ranking(tmp_path, capsys):
    from dataclasses import replace

    from graspsim.maps import load_map

    m = load_map(_map(tmp_path))  # grades rise with the row: row 3 is the paper's best
    scored = replace(m, robust=np.array([0.9, 0.1, np.nan, 0.0]))  # row 0: the robust best
    for rank, row in (("robust", 0), ("paper", 3)):
        path = save_map(scored, tmp_path / f"{rank}.h5")
        assert main(["trial", str(path), "--top", "1", "--rank", rank, "--threads", "1", "--json"]) == 0
        assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["rank"] == rank
        assert np.flatnonzero(read_sim_results(path)["simulated"]).tolist() == [row]
    # the robust order: scored > 0 by score, unscored by grade, scored 0 last
    from graspsim.sim.mapsim import select_grasps

    assert select_grasps(load_map(path), top=4).tolist() == [0, 1, 2, 3]
    assert select_grasps(load_map(path), top=4, rank="paper").tolist() == [3, 2, 1, 0]


@pytest.mark.slow
def test_trial_reads_the_map_once_in_full(tmp_path, capsys, monkeypatch):
    """--grip-force (the friction from the map's header), --gripper and --render read the
    header or nothing more: the grasps are read once, by the simulation."""
    import graspsim.maps.io as io

    reads = []
    real = io._check_memory
    monkeypatch.setattr(io, "_check_memory", lambda f, n, path: (reads.append(n), real(f, n, path))[1])
    path = _map(tmp_path, n=6)
    assert main(["trial", str(path), "--top", "2", "--threads", "1", "--grip-force", "100", "--gripper",
                 "festo_hgpl_25_60_a", "--render", str(tmp_path / "r"), "--render-count", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["trials"] == 2 and summary["renders"]
    assert sorted(reads) == [0, 6]  # the header once (no rows), the whole map once
