"""Success-rate regression checks: fixed grasp sets, tried where grades matter, against
bands from a golden run of the current code.

**Cases.** Coarse FS maps (1 cm, 22 deg, closing directions to 44 deg) of the five paper
primitives, two maps scaled from them (``cylinder@1.25``, ``box@0.8``; every grasp kept,
not only the accepted ones, so that low grades exist) and the glue-bottle analog planned
from a synthetic cloud against a coarse database whose acceptance threshold is 0 (so the
planner keeps its low grades too), simulated against the true compound.

**Sets.** Per case, among the poses that clear the table, grasps drawn uniformly over
the object's surface from two grade ranges (:class:`RegressionSpec`):

* ``hi``: grade > ``hi_min`` (0.7, the paper's acceptance; the cone 0.5: no table-clear
  grasp of the coarse cone map grades above 0.57 -- its best grasps close on the base
  it stands on);
* ``lo``: grade < ``lo_max`` (0.5; the sphere 0.3: its grasps graded 0.3-0.5 hold 0.5 kg
  as often as not, its grasps below 0.3 never do).

**Condition.** ``friction_limited`` (:mod:`graspsim.calibration.conditions`): 8 N per
jaw, each object at the case's mass -- 0.5 kg, except the cone (0.25 kg) and the
half-toroid (0.2 kg), of which no grasp holds 0.5 kg at 8 N (the cone's sides slope 11
deg, so the squeeze pushes it down; the half-toroid is gripped >= 1.5 cm from its centre
of mass), and the glue bottle (0.6 kg: at 0.5 kg two in three of its low grades still
hold; at 0.7 kg nothing does). The cone's paper grade separates its outcomes at no mass
(its hi and lo sets hold alike); 0.25 kg puts both near one half, where its floor and
ceiling can both trip. At the default 250 N per jaw these light objects are held whatever the grade,
and a band there cannot see a grade or a physics change. The masses come from
``python experiments/golden_regression.py --scan-masses``.

**Counting.** Successes out of the grasps *requested*: START_COLLISION and every other
outcome are failures, and a set whose grade range holds no table-clear pose counts all
its grasps failed -- a regression that makes poses infeasible or empties a grade range
cannot shrink its own floor. Grasps are drawn independently and alike (a surface cell
uniformly, then a grasp in it, with replacement: :func:`surface_draws`), so the golden
run's 300 and the test's 30 sample one population.

**Rule.** The golden run draws many grasps (K successes of N) with another seed. Were
nothing changed, a test's count k of n follows the posterior predictive of the golden
rate, BetaBinomial(n, K + 1/2, N - K + 1/2) (Jeffreys prior). A ``hi`` floor is its
alpha-quantile (P(k < floor) <= alpha), a ``lo`` ceiling its (1 - alpha)-quantile
(P(k > ceiling) <= alpha), with alpha = 1e-3 / (number of checks): were the test's
grasps a fresh sample, an unchanged code would trip any check with probability below
1e-3 (Bonferroni). The simulation is deterministic, so on one platform an unchanged
code gives the same counts every run. Every floor must be > 0 and every ceiling < n
(:func:`band_problems`): a band that no outcome can trip is refused.

**What the bands catch** is recorded in :data:`CATCHES` and shown by the mutations of
:mod:`graspsim.calibration.mutations` (tests/test_regression_mutations.py;
tests/data/regression_mutations.json has every mutation on every case).

**Limits.** The rates are MuJoCo's. An independent engine (PyBullet, same geometry,
masses, forces and friction; a one-off cross-check, not in this repository) agreed with MuJoCo on nearly all
high-grade grasps in a friction-limited condition but on far fewer low-grade ones (MuJoCo
the stricter on edge and corner contacts): the ceilings pin MuJoCo's behaviour, not the
world's. There is no AUC check: the calibrated ``pad_contact`` grade was fitted on these
very objects (``calibration.study_shapes.TRAIN_SHAPES`` holds the paper primitives at 0.8, 1
and 1.25 x), so its AUC here would be in-sample -- it is evaluated on held-out objects by
experiments/e05_threshold_calibration.py; the paper grade's discrimination is what the
hi floors and lo ceilings check.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.stats import betabinom

from graspsim.calibration.conditions import SimCondition, condition
from graspsim.calibration.trial_table import TrialTable
from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel
from graspsim.maps.map_config import MapConfig
from graspsim.maps.scaling import ScalingConfig
from graspsim.primitives import Box, Cylinder

__all__ = ["REGRESSION_MAPS", "REGRESSION_SCALED", "RegressionSpec", "SPECS", "RegressionSizes",
           "FAMILY_ALPHA", "CATCHES", "regression_cases", "regression_condition", "pools", "surface_draws",
           "regression_trials",
           "regression_rates", "rate_floor", "rate_ceiling", "regression_bands", "check_bands",
           "band_problems", "adapted_glue_case"]

# coarse maps (1 cm, 22 deg, closing directions to 44 deg): fast, whole grade range
REGRESSION_MAPS = MapConfig(surface_step=0.01, rotation_step=math.radians(22.0),
                            closing_cone=math.radians(44.0))

# familiar objects: maps scaled from a paper primitive's FS map
REGRESSION_SCALED = {"cylinder@1.25": ("cylinder", Cylinder(0.025, 0.25)),
                     "box@0.8": ("box", Box(0.048, 0.048, 0.048))}
# every grasp scaled and kept (the planner keeps only accepted ones): the lo sets need them
ALL_GRADES = ScalingConfig(source_min_grade=0.0, keep_min_grade=0.0)
# a database that accepts every graded grasp, so the planner's map keeps low grades
KEEP_ALL = QualityModel(threshold=0.0)

FAMILY_ALPHA = 1e-3  # chance that an unchanged code trips any band (Bonferroni over checks)


@dataclass(frozen=True)
class RegressionSpec:
    """How a case is tried: its object's mass [kg] under ``friction_limited`` (8 N per
    jaw) and the grade ranges of its ``hi`` (> hi_min) and ``lo`` (< lo_max) sets."""

    mass: float = 0.5
    hi_min: float = 0.7
    lo_max: float = 0.5


SPECS: dict[str, RegressionSpec] = {
    "box": RegressionSpec(), "cylinder": RegressionSpec(), "sphere": RegressionSpec(lo_max=0.3),
    "cone": RegressionSpec(mass=0.25, hi_min=0.5), "half_toroid": RegressionSpec(mass=0.2),
    "cylinder@1.25": RegressionSpec(), "box@0.8": RegressionSpec(), "glue_bottle": RegressionSpec(mass=0.6),
}

# which breaks each kind of band is meant to catch, and which it cannot
CATCHES = {
    "hi_floor": "breaks that make good grasps fail: a gripper frame off along the approach, "
                "less grip force or pad friction than the condition's, a grade that ranks "
                "unstable grasps high (stability term dropped), or one that no longer "
                "reaches hi_min (normals flipped: the set empties, its grasps count failed); "
                "poses made infeasible (START_COLLISION counts as a failure)",
    "lo_ceiling": "breaks that make poor grasps succeed: more grip force or friction than the "
                  "condition's, the condition's mass not applied, a grade that sends good "
                  "grasps below lo_max (normals flipped)",
    "cannot": "changes within a band's statistical margin (a few grasps in 30); changes "
              "that the friction-limited condition hides (physics that only matter at 250 N "
              "or with execution noise); any change to grasps between lo_max and hi_min; "
              "a grade that is wrong in the same way as MuJoCo (both are checked only "
              "against MuJoCo); the pad_contact grade (its training objects include these, "
              "so it is checked on held-out objects in experiments/e05_threshold_calibration.py)",
}


@dataclass(frozen=True)
class RegressionSizes:
    """Grasps requested per case for the hi and lo sets."""

    hi: int = 30
    lo: int = 30


def regression_cases(groups=None, *, threads: int | None = None, db_root=None) -> list:
    """The regression cases (all, or those of ``groups``: names of :data:`SPECS`):
    FS maps of the paper primitives, maps scaled from them, the adapted glue bottle
    (its coarse database built in ``db_root``, a temporary folder if None)."""
    from graspsim.calibration.trials import CalibrationCase
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.scaling import scale_map

    groups = list(SPECS) if groups is None else list(groups)
    unknown = sorted(set(groups) - set(SPECS))
    if unknown:
        raise InvalidParameterError(f"unknown regression cases {unknown}; valid: {list(SPECS)}")
    need = {k for k in groups if k in PAPER_SHAPES} | {REGRESSION_SCALED[k][0] for k in groups
                                                        if k in REGRESSION_SCALED}
    fs = {k: generate_fs_map(PAPER_SHAPES[k], config=REGRESSION_MAPS, threads=threads) for k in sorted(need)}
    cases = []
    for k in groups:
        if k in PAPER_SHAPES:
            cases.append(CalibrationCase(f"{k}/fs", fs[k], group=k, kind="fs"))
        elif k in REGRESSION_SCALED:
            src, target = REGRESSION_SCALED[k]
            g = scale_map(fs[src], target, scaling=ALL_GRADES, config=REGRESSION_MAPS)
            cases.append(CalibrationCase(f"{k}/scaled", g, group=k, kind="scaled"))
        elif db_root is not None:
            cases.append(adapted_glue_case(db_root))
        else:
            with tempfile.TemporaryDirectory() as tmp:
                cases.append(adapted_glue_case(Path(tmp) / "db"))
    return cases


def regression_condition(case, mass: float | None = None) -> SimCondition:
    """``friction_limited`` with the case's mass (or ``mass`` [kg])."""
    return condition("friction_limited", mass=SPECS[case.object_group].mass if mass is None else mass)


def pools(case) -> dict:
    """{"hi": rows, "lo": rows}: the table-clear poses of each grade range of the case."""
    from graspsim.calibration.trials import case_clears_table

    g, spec = case.gmap, SPECS[case.object_group]
    clear = case_clears_table(case)
    return {"hi": np.flatnonzero(clear & (g.grade > spec.hi_min)),
            "lo": np.flatnonzero(clear & (g.grade < spec.lo_max))}


def surface_draws(gmap, pool: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rows of ``pool`` drawn independently and alike: a surface cell (the map's
    surface step) uniformly among the cells holding a first contact of the pool, then a
    grasp uniformly within it -- with replacement, so every draw has the same
    distribution whatever ``n`` (a golden run of 300 and a test of 30 sample one
    population, as the bands' rule assumes). Empty if the pool is."""
    pool = np.asarray(pool)
    if n <= 0 or len(pool) == 0:
        return pool[:0]
    cell = float(gmap.meta.surface_step)
    key = np.floor(gmap.contacts[pool, 0].astype(float) / cell).astype(np.int64)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(inverse.max() + 2))
    cells = rng.integers(0, inverse.max() + 1, size=n)
    within = (rng.random(n) * (starts[cells + 1] - starts[cells])).astype(np.int64)
    return pool[order[starts[cells] + within]]


def regression_trials(cases, sizes, *, seed: int = 0, threads: int | None = None,
                      mass: float | None = None) -> TrialTable:
    """Trials of every case's hi / lo sets (column ``set``) under the case's
    friction-limited condition. sizes: grasps requested per set, a
    :class:`RegressionSizes` or {case name: {set: n}}, drawn by :func:`surface_draws`.
    ``meta["requested"]``: {case: {set: n}}. mass: every object at this mass [kg]
    instead of its spec's (to scan masses)."""
    from graspsim.calibration.trials import CaseSample, case_seed, simulate_samples

    tables, requested, conditions = [], {}, {}
    for case in cases:
        rng = np.random.default_rng(case_seed(seed, case.name))
        cond = regression_condition(case, mass)
        conditions[case.name] = cond.to_dict()
        for name, pool in pools(case).items():
            n = int(sizes[case.name][name] if isinstance(sizes, dict) else getattr(sizes, name))
            requested.setdefault(case.name, {})[name] = n
            rows = surface_draws(case.gmap, pool, n, rng)
            if len(rows) == 0:
                continue
            t = simulate_samples([CaseSample(case, rows, np.ones(len(rows)), len(pool), len(case.gmap))],
                                 cond, seed=seed, threads=threads, features=())
            tables.append(t.with_columns(set=np.full(len(t), name)))
    table = TrialTable.concat(tables) if tables else TrialTable({})
    return TrialTable(table.columns, {**table.meta, "requested": requested, "conditions": conditions,
                                      "specs": {k: asdict(v) for k, v in SPECS.items()}})


def regression_rates(table: TrialTable) -> dict:
    """{case: {set: {"k": successes, "n": grasps requested, "drawn": simulated,
    "start_collision": START_COLLISION among them}}}; every requested grasp that did not
    succeed (or could not be drawn) is a failure."""
    from graspsim.sim.outcomes import TrialOutcome

    out: dict = {}
    for case, sets in table.meta["requested"].items():
        for s, n in sets.items():
            m = (table["case"] == case) & (table["set"] == s) if len(table) else np.zeros(0, bool)
            out.setdefault(case, {})[s] = {
                "k": int(table["success"][m].sum()) if m.any() else 0, "n": int(n), "drawn": int(m.sum()),
                "start_collision": int(np.sum(table["outcome"][m] == TrialOutcome.START_COLLISION))
                if m.any() else 0}
    return out


def _predictive(k_ref: int, n_ref: int, n: int):
    return betabinom(int(n), k_ref + 0.5, n_ref - k_ref + 0.5)


def rate_floor(k_ref: int, n_ref: int, n: int, alpha: float) -> int:
    """Fewest successes in n trials compatible with a golden k_ref / n_ref: P(k < floor)
    <= alpha under the posterior predictive (see the module docstring)."""
    return int(_predictive(k_ref, n_ref, n).ppf(alpha))


def rate_ceiling(k_ref: int, n_ref: int, n: int, alpha: float) -> int:
    """Most successes in n trials compatible with a golden k_ref / n_ref: P(k > ceiling)
    <= alpha."""
    return int(_predictive(k_ref, n_ref, n).ppf(1.0 - alpha))


def regression_bands(golden: dict, sizes, family_alpha: float = FAMILY_ALPHA) -> dict:
    """{"bands": {case: {"hi": {"n", "floor", "p_false_alarm", ...}, "lo": {"n", "ceiling",
    ...}}}, "alpha_per_check", ...} from golden rates ({case: {set: {"k", "n"}}}) for a test
    of ``sizes`` (a :class:`RegressionSizes` or {case: {set: n}})."""
    checks = [(c, s) for c, sets in golden.items() for s in sets]
    alpha = family_alpha / len(checks)
    out: dict = {}
    for c, s in checks:
        ref = golden[c][s]
        n = int(sizes[c][s] if isinstance(sizes, dict) else getattr(sizes, s))
        dist = _predictive(ref["k"], ref["n"], n)
        if s == "hi":
            b = rate_floor(ref["k"], ref["n"], n, alpha)
            band = {"floor": b, "p_false_alarm": float(dist.cdf(b - 1))}
        else:
            b = rate_ceiling(ref["k"], ref["n"], n, alpha)
            band = {"ceiling": b, "p_false_alarm": float(dist.sf(b))}
        out.setdefault(c, {})[s] = {"n": n, **band, "golden_k": ref["k"], "golden_n": ref["n"]}
    return {"alpha_per_check": alpha, "family_alpha": family_alpha, "checks": len(checks), "bands": out}


def band_problems(bands: dict) -> list[str]:
    """Bands that no outcome could trip: a floor of 0 or a ceiling of n."""
    bad = []
    for c, sets in bands["bands"].items():
        for s, b in sets.items():
            if "floor" in b and b["floor"] <= 0:
                bad.append(f"{c}/{s}: floor {b['floor']} of {b['n']} cannot fail")
            if "ceiling" in b and b["ceiling"] >= b["n"]:
                bad.append(f"{c}/{s}: ceiling {b['ceiling']} of {b['n']} cannot fail")
    return bad


def check_bands(measured: dict, bands: dict) -> list[dict]:
    """One record per band: {"case", "set", "k", "n", "bound", "ok", "margin"} (margin:
    successes to spare before the band trips; negative: tripped by that many)."""
    out = []
    for c, sets in bands["bands"].items():
        for s, b in sets.items():
            got = measured.get(c, {}).get(s, {"k": 0, "n": b["n"]})
            if "floor" in b:
                margin = got["k"] - b["floor"]
            else:
                margin = b["ceiling"] - got["k"]
            out.append({"case": c, "set": s, "k": got["k"], "n": got["n"],
                        "bound": b.get("floor", b.get("ceiling")), "kind": "floor" if "floor" in b else "ceiling",
                        "ok": margin >= 0, "margin": int(margin)})
    return out


def adapted_glue_case(db_root, *, seed: int = 3):
    """The glue-bottle analog (``graspsim.primitives.case_study``) seen as a cloud, planned by the
    run-time planner against a coarse FS database in ``db_root`` that accepts every
    graded grasp, as a case simulated against the true compound standing as it stood in
    the cloud."""
    from graspsim.calibration.trials import CalibrationCase
    from graspsim.errors import IdentificationError
    from graspsim.maps.database import MapDatabase
    from graspsim.planning.planner import PlannerConfig, plan
    from graspsim.primitives import synthetic_cloud
    from graspsim.primitives.case_study import glue_bottle
    from graspsim.seeding import rng_for
    from graspsim.sim import object_from_shape
    from graspsim.transforms import invert_transform, make_transform

    truth = glue_bottle()
    T_cloud_true = make_transform(np.eye(3), [0.5, 0.1, 0.0])
    # the cloud and the plan draw from streams of their own (the seed rule), not two
    # generators on one seed, whose draws would repeat each other
    cloud = synthetic_cloud(truth, rng_for(seed, "glue_bottle", "cloud"), resolution=0.002, noise=0.0005,
                            T_world_obj=T_cloud_true)
    res = plan(cloud.points, db=MapDatabase(db_root, config=REGRESSION_MAPS, quality=KEEP_ALL),
               rng=rng_for(seed, "glue_bottle", "plan"), config=PlannerConfig(scaling=ALL_GRADES))
    if res.status.value != "complete" or len(res.parts) != 2:
        raise IdentificationError(f"the glue bottle was planned as {res.status.value} with "
                                  f"{len(res.parts)} parts, not two cylinders")
    return CalibrationCase("glue_bottle/adapted", res.map, group="glue_bottle", kind="adapted",
                           sim_object=object_from_shape(truth),
                           T_sim_map=invert_transform(T_cloud_true) @ res.T_cloud_obj)
