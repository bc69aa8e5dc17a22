"""Golden values for tests/test_success_regression.py (provenance inside the file).

Runs the regression procedure of ``graspsim.calibration.regression`` with many grasps
(another seed than the test's) to pin the reference success rates per case and set,
and the pooled AUC of each grade on the stratified set with its bootstrap standard
error at the test's sample size; then runs the test's own small samples once and
records what they gave (for information: the test checks bands, not exact counts).

    python experiments/e04_regression_golden.py --out tests/data/success_regression.json
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from graspsim.calibration import roc_auc
from graspsim.calibration.outputs import library_versions, write_json
from graspsim.calibration.regression import (
    REGRESSION_MAPS, REGRESSION_SCALED, RegressionSizes, adapted_glue_case, auc_floor, rate_ceiling,
    rate_floor, regression_cases, regression_rates, regression_trials)
from graspsim.grades import get_grade
from graspsim.maps.database import PAPER_SHAPES

TEST_SIZES = RegressionSizes()  # the test reads sizes and seed from the golden file
TEST_SEED = 7


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="tests/data/success_regression.json")
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--hi", type=int, default=300)
    p.add_argument("--lo", type=int, default=200)
    p.add_argument("--per-bin", type=int, default=60)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--boot", type=int, default=1000)
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("graspsim.sim.batch").setLevel(logging.WARNING)
    t0 = time.perf_counter()
    pad = get_grade("pad_contact")
    scores = {"paper": "grade", "pad_contact": "grade_pad_contact"}
    cases = regression_cases(dict(PAPER_SHAPES), REGRESSION_SCALED, threads=a.threads)
    big = RegressionSizes(a.hi, a.lo, a.per_bin)
    ref = regression_trials(cases, big, seed=a.seed, threads=a.threads, grade_models=[pad])
    golden = regression_rates(ref, scores)
    # the AUC's spread at the test's size: bootstrap draws of the test's strat size per case
    f = ref.select(ref.feasible & (ref["set"] == "strat"))
    n_test = {c: min(int(np.sum(f["case"] == c)), 10 * TEST_SIZES.per_bin) for c in np.unique(f["case"])}
    rng = np.random.default_rng(a.seed)
    se = {}
    for k, col in scores.items():
        reps = []
        for _ in range(a.boot):
            idx = np.concatenate([rng.choice(np.flatnonzero(f["case"] == c), n, replace=True)
                                  for c, n in n_test.items()])
            reps.append(roc_auc(f[col][idx], f["success"][idx]))
        se[k] = float(np.nanstd(reps))
    with tempfile.TemporaryDirectory() as tmp:
        glue = adapted_glue_case(Path(tmp) / "db")
    adapted = regression_rates(regression_trials([glue], RegressionSizes(a.hi, 0, 0), seed=a.seed,
                                                 threads=a.threads), {})["rates"]
    test_t = regression_trials(cases, TEST_SIZES, seed=TEST_SEED, threads=a.threads, grade_models=[pad])
    test_vals = regression_rates(test_t, scores)
    bands = {}
    for case, sets in golden["rates"].items():
        for s, kn in sets.items():
            n = test_vals["rates"].get(case, {}).get(s, {}).get("n")
            if not n or s == "strat":
                continue
            b = ({"floor": rate_floor(kn["k"], kn["n"], n)} if s == "hi"
                 else {"ceiling": rate_ceiling(kn["k"], kn["n"], n)})
            bands.setdefault(case, {})[s] = {"n_test": n, **b}
    out = {"provenance": {"script": "experiments/e04_regression_golden.py", "seed": a.seed,
                          "test_seed": TEST_SEED, "sizes": asdict(big), "test_sizes": asdict(TEST_SIZES),
                          "map_config": REGRESSION_MAPS.to_dict(), "protocol": ref.meta.get("protocol"),
                          "condition": ref.meta.get("condition"), "mujoco_version": ref.meta.get("mujoco_version"),
                          "grade_model": {k: v for k, v in pad.to_dict().items() if k != "provenance"},
                          "versions": library_versions(), "seconds": time.perf_counter() - t0},
           "rates": golden["rates"], "adapted": adapted, "auc": golden["auc"], "auc_se_at_test_size": se,
           "auc_floor": {k: auc_floor(golden["auc"][k], se[k]) for k in scores},
           "bands_at_test_size": bands, "test_run": test_vals}
    write_json(a.out, out)
    print({"auc": golden["auc"], "se": se, "test_auc": test_vals["auc"], "bands": bands})


if __name__ == "__main__":
    main()
