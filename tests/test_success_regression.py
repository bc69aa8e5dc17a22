"""Success-rate regression: fixed grasp sets against golden rates (tests/data).

Golden values and their provenance (script, seeds, sizes, MuJoCo version) are in
tests/data/success_regression.json, written by experiments/e04_regression_golden.py.
Bands come from ``graspsim.calibration.regression``: a physics, map or planner change
that drops a rate (or an AUC) out of its band fails here.
"""

import json
from pathlib import Path

import pytest

from graspsim.calibration.regression import (
    REGRESSION_SCALED,
    adapted_glue_case,
    RegressionSizes,
    auc_floor,
    rate_ceiling,
    rate_floor,
    regression_cases,
    regression_rates,
    regression_trials,
)
from graspsim.grades import get_grade
from graspsim.maps.database import PAPER_SHAPES

GOLDEN = json.loads((Path(__file__).parent / "data" / "success_regression.json").read_text())
SCORES = {"paper": "grade", "pad_contact": "grade_pad_contact"}


@pytest.fixture(scope="module")
def measured():
    prov = GOLDEN["provenance"]
    cases = regression_cases(dict(PAPER_SHAPES), REGRESSION_SCALED, threads=2)
    t = regression_trials(cases, RegressionSizes(**prov["test_sizes"]), seed=prov["test_seed"], threads=2,
                          grade_models=[get_grade("pad_contact")])
    return regression_rates(t, SCORES)


def _cases(kind):
    return sorted(c for c, sets in GOLDEN["rates"].items() if kind in sets)


@pytest.mark.parametrize("case", _cases("hi"))
def test_high_grade_grasps_keep_succeeding(measured, case):
    ref = GOLDEN["rates"][case]["hi"]
    got = measured["rates"][case]["hi"]
    floor = rate_floor(ref["k"], ref["n"], got["n"])
    assert got["k"] >= floor, (f"{case}: {got['k']}/{got['n']} grade > 0.7 grasps succeeded; golden "
                               f"{ref['k']}/{ref['n']} allows no fewer than {floor}")


@pytest.mark.parametrize("case", _cases("lo"))
def test_low_grade_grasps_do_not_start_succeeding(measured, case):
    ref = GOLDEN["rates"][case]["lo"]
    got = measured["rates"][case]["lo"]
    ceiling = rate_ceiling(ref["k"], ref["n"], got["n"])
    assert got["k"] <= ceiling, (f"{case}: {got['k']}/{got['n']} grade < 0.3 grasps succeeded; golden "
                                 f"{ref['k']}/{ref['n']} allows at most {ceiling}")


@pytest.mark.parametrize("score", sorted(SCORES))
def test_auc_floors(measured, score):
    floor = auc_floor(GOLDEN["auc"][score], GOLDEN["auc_se_at_test_size"][score])
    assert measured["auc"][score] >= floor, (f"AUC of the {score} grade {measured['auc'][score]:.3f} is "
                                             f"below its floor {floor:.3f} (golden {GOLDEN['auc'][score]:.3f})")


def test_calibrated_grade_still_beats_the_papers(measured):
    assert measured["auc"]["pad_contact"] > measured["auc"]["paper"]


def test_golden_file_has_its_provenance():
    prov = GOLDEN["provenance"]
    for k in ("script", "seed", "test_seed", "mujoco_version", "map_config", "protocol", "grade_model"):
        assert k in prov
    assert set(GOLDEN["auc"]) == set(SCORES)
    # golden rates come from at least as many trials as the test draws (all of them where
    # a map has fewer: the half-toroid's coarse map has 18 table-clear grasps > 0.7)
    for case, sets in GOLDEN["bands_at_test_size"].items():
        for s, band in sets.items():
            assert GOLDEN["rates"][case][s]["n"] >= band["n_test"]


def test_adapted_glue_bottle_map_high_grades_succeed_on_the_true_shape(tmp_path):
    """Cloud -> planner -> combined map of the glue-bottle analog; grade > 0.7 grasps
    simulated against the true compound standing as in the cloud."""
    prov = GOLDEN["provenance"]
    case = adapted_glue_case(tmp_path / "db")
    sizes = RegressionSizes(hi=prov["test_sizes"]["hi"], lo=0, per_bin=0)
    got = regression_rates(regression_trials([case], sizes, seed=prov["test_seed"], threads=2),
                           {})["rates"][case.name]["hi"]
    ref = GOLDEN["adapted"][case.name]["hi"]
    assert got["k"] >= rate_floor(ref["k"], ref["n"], got["n"]), (got, ref)
