"""Success-rate regression checks: fixed grasp sets, golden rates, binomial bands.

One procedure serves the test suite (small samples) and the script that writes the
golden values (large samples, ``experiments/e04_sim_validation.py --golden``): coarse
FS maps of the five paper primitives (and maps scaled from them), then per case

* ``hi``: grasps with paper grade > 0.7 that clear the table, uniform over the surface;
* ``lo``: grasps with paper grade < 0.3 that clear the table;
* ``strat``: grasps stratified over ten grade bins (for the AUC of each grade).

Bands turn a golden rate into a check that tolerates sampling noise but not a real
drop: with the golden rate's Wilson interval [p_lo, p_hi] (from many trials), a test of
n trials must see at least the 0.1 % quantile of Binomial(n, p_lo) successes (``hi``)
and at most the 99.9 % quantile of Binomial(n, p_hi) (``lo``); an AUC must stay above
the golden AUC minus 3.3 bootstrap standard errors at the test's sample size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import binom

from graspsim.calibration.sampling import stratified_rows
from graspsim.calibration.stats import roc_auc, wilson_interval
from graspsim.calibration.table import TrialTable
from graspsim.maps.generate import MapConfig
from graspsim.primitives import Box, Cylinder

__all__ = ["REGRESSION_MAPS", "REGRESSION_SCALED", "RegressionSizes", "regression_cases", "regression_trials",
           "regression_rates", "rate_floor", "rate_ceiling", "auc_floor"]

# coarse maps (1 cm, 22 deg, closing directions to 44 deg): fast, whole grade range
REGRESSION_MAPS = MapConfig(surface_step=0.01, rotation_step=math.radians(22.0),
                            closing_cone=math.radians(44.0))

# familiar objects: maps scaled from a paper primitive's FS map
REGRESSION_SCALED = {"cylinder@1.25": ("cylinder", Cylinder(0.025, 0.25)),
                     "box@0.8": ("box", Box(0.048, 0.048, 0.048))}


@dataclass(frozen=True)
class RegressionSizes:
    """Grasps per case: hi / lo sets and per grade bin of the stratified set."""

    hi: int = 30
    lo: int = 20
    per_bin: int = 6


def regression_cases(shapes: dict, scaled_to: dict | None = None, *, threads: int | None = None) -> list:
    """FS cases of ``shapes`` ({name: primitive}) and scaled cases ({name: (source name,
    target primitive)}), Combined scaling of the coarse FS map."""
    from graspsim.calibration.trials import CalibrationCase
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.scaling import scale_map

    fs = {k: generate_fs_map(s, config=REGRESSION_MAPS, threads=threads) for k, s in shapes.items()}
    cases = [CalibrationCase(f"{k}/fs", m, group=k, kind="fs") for k, m in fs.items()]
    for k, (src, target) in (scaled_to or {}).items():
        cases.append(CalibrationCase(f"{k}/scaled", scale_map(fs[src], target), group=k, kind="scaled"))
    return cases


def _rows(case, sizes: RegressionSizes, rng) -> dict:
    from graspsim.calibration.trials import _clears_table, _sim_object
    from graspsim.gripper import GripperSpec
    from graspsim.sim import select_grasps
    from graspsim.sim.scene import resting_pose

    g = case.gmap
    clear = _clears_table(g, resting_pose(_sim_object(case)), GripperSpec.from_dict(g.meta.gripper), 0.0,
                          T_sim_map=case.T_sim_map)
    out = {}
    for name, mask, n in (("hi", clear & (g.grade > 0.7), sizes.hi), ("lo", clear & (g.grade < 0.3), sizes.lo)):
        pool = np.flatnonzero(mask)
        out[name] = pool[select_grasps(g.select(pool), sample=n, rng=rng)] if len(pool) and n else pool[:0]
    if sizes.per_bin and case.kind == "fs":
        out["strat"] = stratified_rows(g.grade, clear, sizes.per_bin, rng)[0]
    return out


def regression_trials(cases, sizes: RegressionSizes = RegressionSizes(), *, seed: int = 0,
                      threads: int | None = None, grade_models=()) -> TrialTable:
    """Trials of every case's hi / lo / strat sets (column ``set``) under the default
    physics and protocol."""
    from graspsim.calibration.trials import CaseSample, SimCondition, case_seed, simulate_samples

    tables = []
    for case in cases:
        rng = np.random.default_rng(case_seed(seed, case.name))
        for name, rows in _rows(case, sizes, rng).items():
            if len(rows) == 0:
                continue
            t = simulate_samples([CaseSample(case, rows, np.ones(len(rows)), len(rows), len(case.gmap))],
                                 SimCondition(), seed=seed, threads=threads, features=(),
                                 grade_models=grade_models)
            tables.append(t.with_columns(set=np.full(len(t), name)))
    return TrialTable.concat(tables)


def regression_rates(table: TrialTable, scores: dict) -> dict:
    """{"rates": {case: {set: {k, n}}}, "auc": {score: pooled AUC of the strat set}} over
    feasible trials."""
    f = table.select(table.feasible)
    rates: dict = {}
    for case, s in sorted(set(zip(f["case"], f["set"]))):
        m = (f["case"] == case) & (f["set"] == s)
        rates.setdefault(str(case), {})[str(s)] = {"k": int(f["success"][m].sum()), "n": int(m.sum())}
    st = f.select(f["set"] == "strat")
    auc = {k: roc_auc(st[c], st["success"]) for k, c in scores.items()} if len(st) else {}
    return {"rates": rates, "auc": auc}


def rate_floor(k_ref: int, n_ref: int, n: int, q: float = 0.001) -> int:
    """Fewest successes in n trials compatible with a golden k_ref / n_ref."""
    lo, _ = wilson_interval(k_ref, n_ref)
    return int(binom.ppf(q, n, float(lo)))


def rate_ceiling(k_ref: int, n_ref: int, n: int, q: float = 0.999) -> int:
    """Most successes in n trials compatible with a golden k_ref / n_ref."""
    _, hi = wilson_interval(k_ref, n_ref)
    return int(binom.ppf(q, n, float(hi)))


def auc_floor(auc_ref: float, se: float, z: float = 3.3) -> float:
    return float(auc_ref - z * se)


def adapted_glue_case(db_root, *, seed: int = 3):
    """The glue-bottle analog (``graspsim.analogs``) seen as a cloud, planned by the
    run-time planner against a coarse FS database in ``db_root``, as a case simulated
    against the true compound standing as it stood in the cloud."""
    from graspsim.analogs import glue_bottle
    from graspsim.calibration.trials import CalibrationCase
    from graspsim.errors import IdentificationError
    from graspsim.maps.database import MapDatabase
    from graspsim.planner import plan
    from graspsim.primitives import synthetic_cloud
    from graspsim.sim import object_from_shape
    from graspsim.transforms import invert_transform, make_transform

    truth = glue_bottle()
    T_cloud_true = make_transform(np.eye(3), [0.5, 0.1, 0.0])
    cloud = synthetic_cloud(truth, np.random.default_rng(seed), resolution=0.002, noise=0.0005,
                            T_world_obj=T_cloud_true)
    res = plan(cloud.points, db=MapDatabase(db_root, config=REGRESSION_MAPS),
               rng=np.random.default_rng(seed))
    if res.status.value != "complete" or len(res.parts) != 2:
        raise IdentificationError(f"the glue bottle was planned as {res.status.value} with "
                                  f"{len(res.parts)} parts, not two cylinders")
    return CalibrationCase("glue_bottle/adapted", res.map, group="glue_bottle", kind="adapted",
                           sim_object=object_from_shape(truth),
                           T_sim_map=invert_transform(T_cloud_true) @ res.T_cloud_obj)
