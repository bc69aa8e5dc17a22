"""The success-rate regression has teeth: deliberate breaks trip its bands.

Each mutation of ``graspsim.calibration.mutations`` patches the library where such a bug
would live (the simulated gripper's frame, the grade, the scene's grip force or pad
friction, the condition's mass); inside it, the sets the mutation names are drawn and
simulated as tests/test_success_regression.py does, and their bands (from
tests/data/success_regression.json) must trip. The full picture -- every mutation on
every case, which bands trip and which do not -- is tests/data/regression_mutations.json,
written by ``python experiments/golden_regression.py --mutations``.
"""

import json
from pathlib import Path

import pytest

import graspsim.grades.paper
import graspsim.sim
import graspsim.sim.trial_scene
from graspsim.calibration.mutations import MUTATIONS, mutated
from graspsim.calibration.regression import check_bands, regression_cases, regression_rates, regression_trials

DATA = Path(__file__).resolve().parent / "data"
GOLDEN = json.loads((DATA / "success_regression.json").read_text())
FULL = json.loads((DATA / "regression_mutations.json").read_text())
PROV = GOLDEN["provenance"]


@pytest.fixture(scope="module")
def unmutated_cases():
    groups = sorted({t.split("/")[0] for m in MUTATIONS.values() if not m.regrade for t in m.trips})
    return {c.object_group: c for c in regression_cases(groups, threads=2)}


def _run(mutation, cases: dict) -> list[dict]:
    """The checks of the mutation's bands, its sets run as the regression test runs them."""
    want = {t.split("/")[0]: set() for t in mutation.trips}
    for t in mutation.trips:
        g, s = t.split("/")
        want[g].add(s)
    chosen = [cases[g] for g in want]
    sizes = {c.name: {s: (PROV["test_sizes"][c.name][s] if s in want[c.object_group] else 0)
                      for s in ("hi", "lo")} for c in chosen}
    rates = regression_rates(regression_trials(chosen, sizes, seed=PROV["test_seed"], threads=2))
    bands = {c.name: {s: GOLDEN["bands"]["bands"][c.name][s] for s in want[c.object_group]} for c in chosen}
    return check_bands(rates, {"bands": bands})


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MUTATIONS))
def test_mutation_trips_its_bands(unmutated_cases, name):
    mutation = MUTATIONS[name]
    with mutated(name):
        cases = unmutated_cases
        if mutation.regrade:  # the grade changed: the maps must be rebuilt under it
            cases = {c.object_group: c for c in regression_cases(sorted({t.split("/")[0] for t in mutation.trips}),
                                                                 threads=2)}
        checks = _run(mutation, cases)
    held = [c for c in checks if c["ok"]]
    assert not held, f"{name} ({mutation.description}) did not trip: {held}"


def test_every_mutation_trips_a_band_in_the_full_run():
    """The recorded full run (every mutation, every case) against the committed bands:
    each break trips at least one band, the suite's bands among them."""
    assert FULL["golden_commit"] == PROV["versions"]["git_commit"]
    assert set(FULL["mutations"]) == set(MUTATIONS)
    for name, rec in FULL["mutations"].items():
        assert rec["tripped"], name
        tripped = {f"{c['case'].split('/')[0]}/{c['set']}" for c in rec["checks"] if not c["ok"]}
        assert set(MUTATIONS[name].trips) <= tripped, name


def test_mutations_restore_the_library():
    before = (graspsim.grades.paper.force_closure_angle, graspsim.grades.paper.QualityModel.combine,
              graspsim.sim.build_scene, graspsim.sim.trial_scene.build_gripper_spec)
    for name in MUTATIONS:
        with pytest.raises(RuntimeError):
            with mutated(name):
                raise RuntimeError("leave the block early")
    assert before == (graspsim.grades.paper.force_closure_angle, graspsim.grades.paper.QualityModel.combine,
                      graspsim.sim.build_scene, graspsim.sim.trial_scene.build_gripper_spec)
