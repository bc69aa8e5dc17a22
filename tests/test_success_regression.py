"""Success-rate regression: fixed grasp sets, tried where grades matter, against bands
from a golden run of the current code.

The golden values, the bands and their provenance (command, seeds, sizes, git commit,
library versions) are in tests/data/success_regression.json, written by
``python experiments/golden_regression.py``. The cases, the friction-limited condition,
the counting (successes out of grasps requested: START_COLLISION is a failure) and the
statistical rule are documented in ``graspsim.calibration.regression``; which breaks
the bands catch is shown by tests/test_regression_mutations.py.
"""

import json
from pathlib import Path

import pytest

from graspsim.calibration.regression import (
    FAMILY_ALPHA,
    SPECS,
    band_problems,
    check_bands,
    regression_bands,
    regression_cases,
    regression_rates,
    regression_trials,
)

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = json.loads((ROOT / "tests" / "data" / "success_regression.json").read_text())
PROV = GOLDEN["provenance"]
BANDS = [(c, s) for c, sets in GOLDEN["bands"]["bands"].items() for s in sets]


@pytest.fixture(scope="module")
def measured():
    cases = regression_cases(threads=2)
    return regression_rates(regression_trials(cases, PROV["test_sizes"], seed=PROV["test_seed"], threads=2))


@pytest.mark.parametrize("case,which", BANDS)
def test_success_stays_in_its_band(measured, case, which):
    band = GOLDEN["bands"]["bands"][case][which]
    got = measured[case][which]
    [check] = [c for c in check_bands({case: {which: got}}, {"bands": {case: {which: band}}})]
    grades = (f"grade > {SPECS[case.split('/')[0]].hi_min}" if which == "hi"
              else f"grade < {SPECS[case.split('/')[0]].lo_max}")
    assert check["ok"], (
        f"{case}: {got['k']} of {got['n']} requested {grades} grasps succeeded ({got['drawn']} drawn, "
        f"{got['start_collision']} START_COLLISION); golden {band['golden_k']}/{band['golden_n']} allows "
        f"{'no fewer' if which == 'hi' else 'no more'} than {check['bound']}")


def test_every_case_has_a_floor_and_a_ceiling_that_can_fail():
    bands = GOLDEN["bands"]["bands"]
    assert {c.split("/")[0] for c in bands} == set(SPECS)
    for case, sets in bands.items():
        assert set(sets) == {"hi", "lo"}, case
        assert 0 < sets["hi"]["floor"] <= sets["hi"]["n"], case
        assert 0 <= sets["lo"]["ceiling"] < sets["lo"]["n"], case
    assert band_problems(GOLDEN["bands"]) == []


def _same(a, b) -> bool:
    """Nested dicts and lists equal: floats to a relative 1e-9, everything else exactly."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return a == pytest.approx(b, rel=1e-9)
    return a == b


def test_bands_follow_the_stated_rule_from_the_golden_counts():
    """The committed bands are what the rule gives for the golden counts (no hand edits),
    and together they false-alarm less than once in a thousand runs."""
    again = regression_bands({c: {s: {"k": v["k"], "n": v["n"]} for s, v in sets.items()}
                              for c, sets in GOLDEN["golden"].items()}, PROV["test_sizes"])
    # the counts exactly; the false-alarm probabilities to a relative 1e-9 (scipy's binomial tail
    # differs in its last bits between releases)
    assert _same(again["bands"], GOLDEN["bands"]["bands"])
    total = sum(b["p_false_alarm"] for sets in again["bands"].values() for b in sets.values())
    assert total <= FAMILY_ALPHA
    # the golden run drew ten times the test's grasps (or more), from non-empty pools
    for case, sets in GOLDEN["golden"].items():
        for s, v in sets.items():
            assert v["n"] >= 10 * PROV["test_sizes"][case][s] and v["drawn"] == v["n"], (case, s)
            assert PROV["pool"][case][s] > 0, (case, s)


def test_golden_file_has_its_provenance():
    for k in ("script", "command", "seed", "test_seed", "sizes", "test_sizes", "map_config", "condition",
              "conditions", "specs", "protocol", "mujoco_version", "versions", "rule"):
        assert k in PROV, k
    assert (ROOT / PROV["script"]).is_file()
    assert PROV["command"].startswith("python experiments/golden_regression.py")
    assert PROV["seed"] != PROV["test_seed"]
    assert PROV["versions"]["git_commit"] and PROV["versions"]["git_dirty"] is False
    assert PROV["condition"]["name"] == "friction_limited"
    assert {c: v["mass"] for c, v in PROV["specs"].items()} == {c: s.mass for c, s in SPECS.items()}
