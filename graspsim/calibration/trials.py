"""Calibration trials: grasps drawn from maps, simulated under chosen conditions.

(Simulating many map *files* resumably on an executor is :mod:`graspsim.apps.campaign`.)

Build once, run many: :func:`draw_samples` picks the grasps of each case (stratified
over the grade among the poses that clear the table), :func:`simulate_samples` runs
them under a :class:`SimCondition` and returns a :class:`TrialTable`. Running the same
samples under several conditions (friction, grip force, mass, execution noise) gives
paired comparisons: the grasps and the noise draws are the same, only the physics moves.
Every case's trials are seeded from (seed, case name), whatever the order of cases.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from graspsim.calibration.conditions import CONDITIONS, FRICTION_LIMITED, SimCondition, conditioned_object
from graspsim.calibration.sampling import stratified_rows
from graspsim.calibration.trial_table import TrialTable
from graspsim.errors import InvalidParameterError
from graspsim.grades.grade_features import FEATURES, map_features
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.seeding import derived_seed
from graspsim.transforms import angle_between

__all__ = ["CalibrationCase", "SimCondition", "FRICTION_LIMITED", "CONDITIONS", "CaseSample", "draw_samples",
           "simulate_samples", "case_seed", "case_clears_table", "table_features", "fs_cases"]

log = logging.getLogger(__name__)

DEFAULT_CONE = math.radians(22.0)  # MapConfig().closing_cone


@dataclass(frozen=True, eq=False)
class CalibrationCase:
    """A map and the object its grasps are tried on.

    name: unique label (e.g. ``"cylinder@1.0/fs"``); group: the object (the unit held
    out in cross-validation; default ``name``); kind: map kind (fs / scaled / adapted);
    sim_object: the simulated object (a :class:`graspsim.sim.SimObject`, e.g. the true
    shape of an object whose map was planned from primitives, standing +z up); None: the
    map's object. T_sim_map: (4, 4) pose of the map's object frame in the simulated
    object's frame (e.g. ``inv(T_cloud_true) @ T_cloud_obj``); None: identity.
    """

    name: str
    gmap: GraspabilityMap
    group: str = ""
    kind: str = "fs"
    sim_object: object | None = None
    T_sim_map: np.ndarray | None = None

    @property
    def T_obj_wrist(self) -> np.ndarray:
        """(N, 4, 4) the map's wrist poses in the simulated object's frame."""
        T = self.gmap.T_obj_wrist
        return T if self.T_sim_map is None else np.asarray(self.T_sim_map, float) @ T

    @property
    def object_group(self) -> str:
        return self.group or self.name


@dataclass(frozen=True, eq=False)
class CaseSample:
    """Rows of a case's map to simulate and their inverse inclusion probabilities;
    eligible: rows of the map that clear the table; total: rows of the map."""

    case: CalibrationCase
    rows: np.ndarray
    weights: np.ndarray
    eligible: int
    total: int


def case_seed(seed: int, name: str) -> int:
    """A case's own seed, independent of the order of cases."""
    return derived_seed(seed, name)


def _sim_object(case: CalibrationCase):
    from graspsim.sim.mapsim import map_object

    return case.sim_object if case.sim_object is not None else map_object(case.gmap)


def draw_samples(cases: Sequence[CalibrationCase], per_bin: int, *, seed: int = 0,
                 edges=np.linspace(0.0, 1.0, 11), score: str = "grade",
                 min_clearance: float = 0.0) -> list[CaseSample]:
    """Up to ``per_bin`` grasps per grade bin of each case, among the poses whose
    gripper stays ``min_clearance`` [m] above the table with the object at rest."""
    names = [c.name for c in cases]
    if len(set(names)) != len(names):
        raise InvalidParameterError(f"case names must be unique, got {names}")
    out = []
    for case in cases:
        gmap = case.gmap
        clear = case_clears_table(case, min_clearance)
        rng = np.random.default_rng(case_seed(seed, case.name))
        rows, w = stratified_rows(getattr(gmap, score), clear, per_bin, rng, edges)
        out.append(CaseSample(case, rows, w, int(clear.sum()), len(gmap)))
        log.info("%s: %d of %d rows clear the table; %d drawn", case.name, int(clear.sum()),
                 len(gmap), len(rows))
    return out


def case_clears_table(case: CalibrationCase, min_clearance: float = 0.0) -> np.ndarray:
    """(N,) bool over the case's map: the pose keeps the map's gripper ``min_clearance``
    [m] above the simulator's table (z = 0) with the simulated object at rest (the
    map's frame at ``resting_pose @ T_sim_map``)."""
    from graspsim.maps.table_clearance import clears_table
    from graspsim.sim.trial_scene import resting_pose

    T = resting_pose(_sim_object(case))
    if case.T_sim_map is not None:
        T = T @ np.asarray(case.T_sim_map, float)
    return clears_table(case.gmap, T, case.gmap.meta.gripper_spec, min_clearance)


def _map_columns(gmap: GraspabilityMap, rows: np.ndarray) -> dict[str, np.ndarray]:
    c = gmap.contacts[rows].astype(float)
    n = gmap.normals[rows].astype(float)
    a1 = angle_between(-n[:, 0], c[:, 1] - c[:, 0])
    cols = {k: getattr(gmap, k)[rows].astype(float)
            for k in ("grade", "fc_angle", "q_fc", "stability_distance", "q_st", "width")}
    cols["in_default_cone"] = a1 <= DEFAULT_CONE + 1e-4
    # the grasp geometry, so features can be recomputed from the table alone
    cols.update(contacts=c, normals=n, wrist_position=gmap.wrist_position[rows].astype(float),
                wrist_quat=gmap.wrist_quat[rows].astype(float))
    return cols


@dataclass(frozen=True, eq=False)
class _CaseJob:
    """One case of :func:`simulate_samples`, as an executor task."""

    sample: CaseSample
    condition: SimCondition
    protocol: object
    seed: int
    threads: int | None
    features: tuple[str, ...]
    grade_models: tuple


def _simulate_case(job: _CaseJob) -> TrialTable:
    """Simulate one case's samples (runs in this process or an executor's worker)."""
    from graspsim.sim import SimSettings, build_scene, contact_model, run_trials

    smp, condition, protocol = job.sample, job.condition, job.protocol
    settings = contact_model(condition.contacts, SimSettings(friction=condition.friction,
                                                             grip_force=condition.grip_force))
    noise = condition.noise if condition.noisy else None
    case, rows = smp.case, smp.rows
    obj = conditioned_object(_sim_object(case), condition)
    gripper = case.gmap.meta.gripper_spec
    scene = build_scene(obj, gripper, settings, table=protocol.table, gravity=protocol.gravity)
    res = run_trials(scene, case.T_obj_wrist[rows], case.gmap.width[rows], protocol,
                     threads=job.threads, seed=case_seed(job.seed, case.name), noise=noise)
    n = len(rows)
    cols = {"case": np.full(n, case.name), "group": np.full(n, case.object_group),
            "kind": np.full(n, case.kind), "condition": np.full(n, condition.name),
            "row": rows.astype(np.int64), "weight": smp.weights.astype(float),
            "outcome": res.outcome.astype(np.int8), "success": res.outcome == 0,
            **_map_columns(case.gmap, rows)}
    if job.features:
        cols.update({f"f_{k}": v for k, v in map_features(case.gmap, job.features, rows).items()})
    for model in job.grade_models:
        cols[f"grade_{model.name}"] = np.asarray(model.grade_rows(case.gmap, rows), float)
    cols.update({f"m_{k}": np.asarray(v, float) for k, v in res.metrics.items()})
    log.info("%s [%s]: %s", case.name, condition.name, res.counts())
    return TrialTable(cols)


def simulate_samples(samples: Sequence[CaseSample], condition: SimCondition = SimCondition(), *,
                     protocol=None, seed: int = 0, threads: int | None = None,
                     features: tuple[str, ...] = FEATURES, grade_models: Sequence = (),
                     on_case: Callable[[str, int], None] | None = None,
                     executor=None) -> TrialTable:
    """Simulate every sample under ``condition`` (default protocol: lift_place).

    grade_models: extra grades (objects with ``name`` and ``grade_rows(gmap, rows)``)
    stored as ``grade_<name>`` columns. on_case(name, n): called after each case.
    executor: a ``graspsim.executors`` executor to run the cases in parallel (local
    processes or Ray); every case is seeded by its name, so results are the same.
    """
    from graspsim._gl import import_mujoco
    from graspsim.executors import SerialExecutor
    from graspsim.sim import LiftPlace

    mujoco = import_mujoco()

    protocol = protocol or LiftPlace()
    todo = [smp for smp in samples if len(smp.rows)]
    jobs = [_CaseJob(smp, condition, protocol, seed, threads, tuple(features), tuple(grade_models))
            for smp in todo]
    tables: list = [None] * len(jobs)
    for i, table in (executor or SerialExecutor()).imap(_simulate_case, jobs):
        tables[i] = table
        if on_case is not None:
            on_case(todo[i].case.name, len(todo[i].rows))
    meta = {"condition": condition.to_dict(), "protocol": protocol.to_dict(), "seed": int(seed),
            "mujoco_version": mujoco.__version__, "features": list(features),
            "cases": [{"name": s.case.name, "group": s.case.object_group, "kind": s.case.kind,
                       "object": s.case.gmap.meta.object, "gripper": s.case.gmap.meta.gripper,
                       "quality": s.case.gmap.meta.quality, "drawn": int(len(s.rows)),
                       "eligible": s.eligible, "total": s.total} for s in samples]}
    return TrialTable.concat(tables, meta=meta)


def table_features(table: TrialTable, names: tuple[str, ...] = FEATURES,
                   config=None) -> dict[str, np.ndarray]:
    """Grade features {name: (N,)} of a table's trials, recomputed from its stored grasp
    geometry and the cases' object, gripper and quality records (no maps needed)."""
    from graspsim.grades.grade_features import FeatureConfig, grasp_features, object_context
    from graspsim.transforms import quat_to_matrix

    config = config or FeatureConfig()
    out = {k: np.full(len(table), np.nan) for k in names}
    cases = {c["name"]: c for c in table.meta.get("cases", [])}
    for name in np.unique(table["case"]):
        if name not in cases:
            raise InvalidParameterError(f"the table's meta has no record of case {name!r}")
        rec = cases[name]
        sel = np.flatnonzero(table["case"] == name)
        ctx = object_context(rec["object"], rec["quality"].get("d_ref"), config)
        f = grasp_features(ctx, GripperSpec.from_dict(rec["gripper"]), table["contacts"][sel],
                           table["normals"][sel], quat_to_matrix(table["wrist_quat"][sel]),
                           table["wrist_position"][sel], names, config)
        for k, v in f.items():
            out[k][sel] = v
    return out


def fs_cases(shapes: dict, *, config=None, quality=None, gripper=None, kind: str = "fs",
             threads: int | None = None) -> list:
    """One :class:`CalibrationCase` per named shape with its FS map (a compound gets
    the combined map of its parts' FS maps, as the planner builds it)."""
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.combine import combine_maps
    from graspsim.maps.generate import generate_fs_map
    from graspsim.primitives import Compound

    gripper = gripper or HGPL_25_60_A
    cases = []
    for name, shape in shapes.items():
        t = time.perf_counter()
        if isinstance(shape, Compound):
            parts = [generate_fs_map(p, gripper, quality, config, threads=threads) for p in shape.parts]
            gmap = combine_maps(parts, shape, quality=quality, config=config)
            k = "combined"
        else:
            gmap = generate_fs_map(shape, gripper, quality, config, threads=threads)
            k = kind
        log.info("map of %s: %d grasps in %.1f s", name, len(gmap), time.perf_counter() - t)
        cases.append(CalibrationCase(f"{name}/{k}", gmap, group=name, kind=k))
    return cases
