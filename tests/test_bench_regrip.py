"""bench_regrip (issue 18's time goal): the quick mode end to end and its README block."""

import json

from test_experiments import _load  # the experiment scripts' loader


def test_bench_regrip_quick(tmp_path):
    bench = _load("bench_regrip")
    out = tmp_path / "b"
    assert bench.main(["--quick", "--kinds", "box", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    (row,) = s["rows"]
    assert row["kind"] == "box" and 0 < row["adapted"] <= row["source_grasps"]
    assert len(row["warm_runs_s"]) == 2 and row["warm_s"] > 0 and row["cold_s"] > 0
    md = bench.readme_section(s)
    assert s["command"] in md and "| box |" in md
