"""experiments/bench_viewer.py: a served map timed as a user meets it, and its published
summary renders the README block."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _load(name: str):
    sys.path.insert(0, str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up while the class is built
    spec.loader.exec_module(mod)
    return mod



@pytest.mark.slow
def test_bench_viewer_times_a_served_map_and_its_first_frame(tmp_path):
    from graspsim.viewer.snapshot import find_browser

    pytest.importorskip("viser")
    if find_browser() is None:
        pytest.skip("no Chromium on this machine (Debian: apt-get install chromium)")
    from hand_made import grasp_pose, hand_made_map

    from graspsim.maps import save_map
    from graspsim.primitives import Cylinder

    T = np.stack([grasp_pose([0, 0, z], [-1, 0, 0], [0, 1, 0]) for z in np.linspace(-0.05, 0.05, 20)])
    path = save_map(hand_made_map(Cylinder(0.02, 0.2), T, np.full(20, 0.04)), tmp_path / "m.h5")
    bench = _load("bench_viewer")
    assert bench.main(["--map", str(path), "--repeat", "2", "--out", str(tmp_path / "b")]) == 0
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    h = s["headline"]
    assert h["grasps"] == 20 and h["fresh_runs"] == 2 and h["sigint_exit_codes"] == [0]
    assert h["fresh_median_url_s"] > h["fresh_median_ready_inside_s"] > 0 and h["fresh_median_cpu_s_at_url"] > 0
    assert h["frame_inside_s"] > h["browser_frame_s"] > h["browser_connect_s"] > 0
    assert all(r["page_status"] == 200 for r in s["fresh"]) and s["viewer_versions"]["viser"]
    assert s["command"] in bench.readme_section(s)


def test_bench_viewer_reported_summary_renders():
    """The viewer's published timings come with their command, load and goal."""
    bench = _load("bench_viewer")
    s = json.loads((EXPERIMENTS / "reported" / "bench_viewer.json").read_text())
    md = bench.readme_section(s)
    assert s["command"].startswith("python experiments/bench_viewer.py") and s["command"] in md
    h = s["headline"]
    assert h["grasps"] > 1_000_000 and h["fresh_runs"] >= 2 and h["sigint_exit_codes"] == [0]
    assert ("met" if h["goal_met"] else "NOT met") in md and len(s["machine"]["load_avg_start"]) == 3
