"""Paired trials (E04): every drawn grasp simulated without (``outcome``) and with
execution noise (``outcome_noise``), row by row the same grasps, and their rates. A pose that starts
in collision without noise is not a trial (the feasible poses are the denominator); with
noise, rates are given of the poses feasible without it and of all drawn poses, with
95 % Wilson intervals."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import numpy as np

from graspsim.calibration import CaseSample, SimCondition, TrialTable, simulate_samples, wilson_interval
from graspsim.sim.outcomes import TrialOutcome

__all__ = ["simulate_paired", "rates", "rate_rows"]


def simulate_paired(samples: list[CaseSample], conditions: list[SimCondition], *, seed: int,
                    threads: int | None = None) -> TrialTable:
    """Every sample simulated under ``conditions`` = (exact, with noise): the exact
    table with the noisy run's outcomes as ``outcome_noise``."""
    exact, noisy = (simulate_samples(samples, c, seed=seed, threads=threads, features=()) for c in conditions)
    if not (np.array_equal(exact["case"], noisy["case"]) and np.array_equal(exact["row"], noisy["row"])):
        raise RuntimeError("the two conditions simulated different grasps")  # pragma: no cover
    return exact.with_columns(outcome_noise=noisy["outcome"])


def rate_rows(table: TrialTable, keys: tuple[str, ...]) -> list[dict]:
    out = []
    cols = [table[k] for k in keys]
    for combo in sorted(set(zip(*cols))):
        m = np.ones(len(table), bool)
        for c, v in zip(cols, combo):
            m &= c == v
        out.append({**dict(zip(keys, combo)), **rates(table.select(m))})
    return out


def _rate(k: int, n: int) -> dict:
    lo, hi = wilson_interval(k, n)
    return {"success": int(k), "of": int(n), "rate": k / n if n else None, "ci": [float(lo), float(hi)]}


def _failures(oc: np.ndarray) -> dict:
    return {o.label: int(np.sum(oc == o)) for o in TrialOutcome if o is not TrialOutcome.SUCCESS}


def rates(t: TrialTable) -> dict:
    """Rates of paired trials (``outcome`` exact, ``outcome_noise`` with noise)."""
    sc, ok = TrialOutcome.START_COLLISION, TrialOutcome.SUCCESS
    oc0 = t["outcome"] if len(t) else np.zeros(0, np.int8)
    oc1 = t["outcome_noise"] if len(t) else np.zeros(0, np.int8)
    feas = oc0 != sc
    n, f = len(oc0), int(feas.sum())
    return {"drawn": n, "start_collision": n - f, "feasible": f,
            "exact": {**_rate(int(np.sum(oc0 == ok)), f), "failures": _failures(oc0[feas])},
            "noise": {"of_feasible": _rate(int(np.sum((oc1 == ok) & feas)), f),
                      "of_drawn": _rate(int(np.sum(oc1 == ok)), n),
                      "pushed_into_collision": int(np.sum((oc1 == sc) & feas)),
                      "failures_of_feasible": _failures(oc1[feas]),
                      # the old (flattering) denominator, for comparison: feasible under noise
                      "of_feasible_with_noise": _rate(int(np.sum(oc1 == ok)), int(np.sum(oc1 != sc)))}}
