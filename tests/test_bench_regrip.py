"""bench_regrip (issue 18's time goal): the quick mode end to end and its README block."""

import importlib.util
import json
import sys
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def test_bench_regrip_quick(tmp_path):
    sys.path.insert(0, str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location("bench_regrip", EXPERIMENTS / "bench_regrip.py")
    bench = importlib.util.module_from_spec(spec)
    sys.modules["bench_regrip"] = bench
    spec.loader.exec_module(bench)
    out = tmp_path / "b"
    assert bench.main(["--quick", "--kinds", "box", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    (row,) = s["rows"]
    assert row["kind"] == "box" and 0 < row["adapted"] <= row["source_grasps"]
    assert len(row["warm_runs_s"]) == 2 and row["warm_s"] > 0 and row["cold_s"] > 0
    md = bench.readme_section(s)
    assert s["command"] in md and "| box |" in md
