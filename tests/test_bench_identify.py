"""bench_identify (issue 15's time goal): the quick mode end to end on the vendored
bread mesh -- E09's clouds, per-stage times that add up, a fresh 'graspsim adapt' -- and
the helpers it relies on: the planner's stage clock and the row ids of repeated lines."""

import json
import time
from pathlib import Path

import numpy as np
import pytest
from test_experiments import _load  # the experiment scripts' loader

from graspsim.maps.rowids import first_rows, row_ids
from graspsim.planning.stages import StageClock

ROOT = Path(__file__).resolve().parents[1]


def test_row_ids_number_distinct_rows_and_first_rows_finds_them():
    rng = np.random.default_rng(0)
    base = rng.normal(size=(7, 2, 3)).astype(np.float32)
    pick = rng.integers(0, 7, 60)
    rows = base[pick]
    ids = row_ids(rows)
    # equal rows share an id, different rows do not; ids as np.unique numbers them
    expect = np.unique(rows.reshape(60, -1).view(np.dtype((np.void, 24))).ravel(), return_inverse=True)[1]
    assert np.array_equal(ids, expect.ravel())
    first = first_rows(ids)
    assert np.array_equal(rows[first][ids], rows)
    assert all(first[i] == np.flatnonzero(ids == i)[0] for i in range(len(first)))
    assert len(row_ids(rows[:0])) == 0 and len(first_rows(row_ids(rows[:0]))) == 0


def test_stage_clock_counts_production_not_consumption():
    clock = StageClock("make", "use")

    def slow_items():
        for i in range(3):
            time.sleep(0.02)
            yield i

    for _ in clock.iterate(slow_items(), "make"):
        time.sleep(0.05)  # the consumer's time is not the producer's
        clock.lap("use")
    # counted in, the consumer's 0.15 s would put "make" above "use"
    assert 0.06 <= clock.seconds["make"] < clock.seconds["use"] and clock.seconds["use"] >= 0.15


@pytest.mark.slow
def test_bench_identify_quick(tmp_path):
    bench = _load("bench_identify")
    out = tmp_path / "b"
    objects = ROOT / "assets" / "objects"
    assert bench.main(["--quick", "--objects-dir", str(objects), "--objects", "robosuite/bread.stl",
                       "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    (row,) = s["objects"]
    for view in ("full", "single"):
        m = row[view]["median"]
        parts = sum(m[k] for k in ("identify", "adapt", "agreement", "combine", "table", "robust"))
        assert 0 < parts <= m["total"] + 1e-6 and m["total"] <= m["wall"] + 1e-6
    (cli,) = s["fresh_cli"]
    assert cli["first"]["exit"] == 0 and cli["second"]["plan_s"] > 0
    md = bench.readme_section(s)
    assert s["command"] in md and "| full |" in md
