"""Gripper design analysis with graspability maps (the paper's abstract: maps "are
suitable ... as grasp databases for gripper design analysis").

A design is a :class:`~graspsim.grippers.spec.GripperSpec`; :func:`vary` changes one design
parameter of a base gripper (finger length, pad length, stroke), and :func:`evaluate`
measures a gripper on a set of objects:

* from its FS map of each object: SR and VR of the accepted grasps (grade above the
  threshold; VR over one voxel box for every gripper compared, grown by the longest
  reach among them, so a longer finger is not penalised by a larger box), and the
  share of collision-free grasps that are accepted;
* in simulation: lift-and-place trials of accepted grasps drawn uniformly over the
  object's surface among those that clear the table with the object at rest, the
  gripper built from the same spec (or a vendored model where the simulator has one).

:func:`sweep` runs one parameter's values over the objects. Every draw comes from
``seed`` through :mod:`graspsim.seeding` (one stream per gripper x object).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from graspsim.errors import GraspsimError, InvalidParameterError, NoFeasibleGraspError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.metrics import map_rates
from graspsim.seeding import rng_for

__all__ = ["PARAMS", "DesignConfig", "vary", "param_value", "evaluate", "sweep", "common_reach",
           "adapted_vs_own", "resolve_design"]

#: design parameter -> what it changes in a GripperSpec
PARAMS: dict[str, str] = {
    "finger_length": "finger_size[2], the finger's length below the jaw [m]",
    "pad_length": "pad_length, the contact region from the fingertip [m]",
    "stroke": "stroke_per_jaw [m] (the housing grows if it could not carry the jaws)",
}


def param_value(spec: GripperSpec, param: str) -> float:
    """The value of design parameter ``param`` in ``spec`` [m]."""
    _check_param(param)
    return {"finger_length": spec.finger_size[2], "pad_length": spec.pad_length,
            "stroke": spec.stroke_per_jaw}[param]


def _check_param(param: str) -> None:
    if param not in PARAMS:
        raise InvalidParameterError(f"unknown design parameter {param!r}; valid: {sorted(PARAMS)}")


def vary(base: GripperSpec, param: str, value: float) -> GripperSpec:
    """``base`` with design parameter ``param`` set to ``value`` [m], named after it.
    A longer stroke lengthens the housing just enough to carry the jaws at full opening
    (a real gripper of that stroke is longer); nothing else changes. A variant is
    simulated with the model built from its spec (a vendored model is of the base
    gripper only). GripperError if the variant is not a valid gripper (e.g. a pad
    longer than the finger)."""
    _check_param(param)
    v = float(value)
    name = f"{base.name}[{param}={1000 * v:g}mm]"
    base = replace(base, model=None)
    if param == "finger_length":
        f = base.finger_size
        return replace(base, name=name, finger_size=(f[0], f[1], v))
    if param == "pad_length":
        return replace(base, name=name, pad_length=v)
    need = 2.0 * (base.closed_gap / 2 + v + base.jaw_size[0])
    h = base.housing_size
    return replace(base, name=name, stroke_per_jaw=v, housing_size=(max(h[0], need), h[1], h[2]))


@dataclass(frozen=True)
class DesignConfig:
    """map_config: FS map resolution (a coarser one than the library's default keeps a
        sweep of dozens of maps to minutes; every design of a sweep uses the same).
    sim_grasps: accepted grasps simulated per gripper x object (0: none).
    threads: map and simulation threads (None: all cores). seed: the run's seed."""

    map_config: MapConfig = field(default_factory=lambda: MapConfig(
        surface_step=0.0075, rotation_step=math.radians(16.5)))
    sim_grasps: int = 16
    threads: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if self.sim_grasps < 0:
            raise InvalidParameterError(f"sim_grasps must be >= 0, got {self.sim_grasps}")
        if self.threads is not None and self.threads < 1:
            raise InvalidParameterError(f"threads must be >= 1, got {self.threads}")


def common_reach(grippers: Iterable[GripperSpec]) -> GripperSpec:
    """The gripper whose grasp-point-to-wrist reach is longest: its voxel box holds the
    wrists of every gripper given (see :func:`graspsim.maps.metrics.wrist_box`)."""
    return max(grippers, key=lambda g: float(g.tcp_offset(g.depth_lo)))


def evaluate(gripper: GripperSpec, name: str, shape, cfg: DesignConfig, *,
             box_gripper: GripperSpec | None = None) -> dict:
    """One gripper on one object (called ``name``): map and simulation numbers (see the
    module docstring). An object the gripper cannot grasp at all gives zeros."""
    t0 = time.perf_counter()
    try:
        gmap = generate_fs_map(shape, gripper, config=cfg.map_config, threads=cfg.threads)
    except NoFeasibleGraspError:
        gmap = None
    map_s = time.perf_counter() - t0
    row = {"object": name, "kind": getattr(shape, "kind", name), "gripper": gripper.name, "map_s": map_s}
    if gmap is None or not len(gmap):
        return {**row, "grasps": 0, "accepted": 0, "share_accepted": 0.0, "SR": 0.0, "VR": 0.0,
                "hit_pixels": 0, "hit_voxels": 0, "sim": _sim_record(None, 0, 0.0)}
    rates = map_rates(gmap, min_grade=gmap.threshold, box_gripper=box_gripper)
    acc = int(gmap.accepted.sum())
    row.update(grasps=len(gmap), accepted=acc, share_accepted=acc / len(gmap), SR=rates.sr,
               VR=rates.vr, hit_pixels=rates.hit_pixels, pixels=rates.pixels,
               hit_voxels=rates.hit_voxels, voxels=rates.voxels)
    rng = rng_for(cfg.seed, gripper.name, name)
    row["sim"] = simulate_accepted(gmap, cfg.sim_grasps, rng, threads=cfg.threads) if cfg.sim_grasps else \
        _sim_record(None, 0, 0.0)
    return row


def simulate_accepted(gmap, n: int, rng: np.random.Generator, *, threads: int | None = None) -> dict:
    """Lift-and-place trials of ``n`` accepted grasps of ``gmap`` drawn uniformly over
    the surface among those that clear the table (the object at rest on it)."""
    from graspsim.maps.table_clearance import clears_table
    from graspsim.sim import LiftPlace, SimSettings, build_scene, map_object, run_trials
    from graspsim.sim.trial_scene import resting_pose

    t0 = time.perf_counter()
    obj = map_object(gmap)
    gripper = gmap.meta.gripper_spec
    rows = np.flatnonzero(gmap.accepted)
    rows = rows[clears_table(gmap.select(rows), resting_pose(obj), gripper)]
    if not len(rows):
        return _sim_record(None, 0, time.perf_counter() - t0)
    pick = rows[gmap.select(rows).uniform_surface_rows(min(n, len(rows)), rng)]
    scene = build_scene(obj, gripper, SimSettings())
    res = run_trials(scene, gmap.T_obj_wrist[pick], gmap.width[pick].astype(float), LiftPlace(),
                     threads=threads, seed=int(rng.integers(2**31)))
    return _sim_record(res, len(rows), time.perf_counter() - t0)


def _sim_record(res, eligible: int, seconds: float) -> dict:
    if res is None:
        return {"drawn": 0, "feasible": 0, "success": 0, "eligible": eligible, "counts": {},
                "sim_s": seconds}
    counts = res.counts()
    return {"drawn": len(res), "feasible": res.feasible, "success": counts.get("success", 0),
            "eligible": eligible, "counts": counts, "sim_s": seconds}


def sweep(base: GripperSpec, param: str, values: Sequence[float], objects: dict, cfg: DesignConfig, *,
          progress: Callable[[dict], None] | None = None) -> list[dict]:
    """Every value of ``param`` (varied from ``base``) on every object of ``objects``
    (name -> Primitive): rows of :func:`evaluate` with ``param`` and ``value`` added.
    The VR voxel box is the same for every design (the longest reach among them)."""
    if not values:
        raise InvalidParameterError("give at least one value to sweep")
    designs = [vary(base, param, v) for v in values]
    box = common_reach(designs)
    rows = []
    for v, g in zip(values, designs):
        for name, shape in objects.items():
            try:
                row = evaluate(g, name, shape, cfg, box_gripper=box)
            except GraspsimError as err:  # e.g. a memory budget: the design is reported, not lost
                row = {"object": name, "gripper": g.name, "error": str(err)}
            row.update(param=param, value=float(v))
            rows.append(row)
            if progress is not None:
                progress(row)
    return rows



def _found(a, b, tol: float = 1e-6) -> np.ndarray:
    """(len(a),) bool: map ``a``'s grasp is one of map ``b``'s -- the same contacts,
    orientation and wrist position, to ``tol`` [m] (a pose-by-pose comparison, free of
    the voxel grid's edges, on which a box map's wrists lie)."""
    from scipy.spatial import cKDTree

    def rows(m):
        return np.column_stack([m.contacts.reshape(-1, 6), m.wrist_quat, m.wrist_position]).astype(float)

    if not len(a) or not len(b):
        return np.zeros(len(a), bool)
    return cKDTree(rows(b)).query(rows(a), distance_upper_bound=tol)[0] <= tol


def resolve_design(text: str, base: GripperSpec) -> GripperSpec:
    """A gripper named on a command line: ``param=value`` ([m]) varies ``base`` (e.g.
    ``finger_length=0.05``); anything else is a registered gripper name, a model file
    (.xml, .urdf) or a JSON spec (:func:`graspsim.grippers.get_gripper`)."""
    if "=" in text:
        param, _, value = text.partition("=")
        try:
            v = float(value)
        except ValueError:
            raise InvalidParameterError(f"{text!r}: the value after '=' must be a length in metres") from None
        return vary(base, param.strip(), v)
    from graspsim.grippers import get_gripper

    return get_gripper(text)


def adapted_vs_own(fs_a, name: str, target: GripperSpec, *, repeats: int = 3, sim_grasps: int = 0,
                   seed: int = 0, threads: int | None = None) -> dict:
    """``fs_a``, an FS map of a primitive for its gripper A, adapted to ``target``
    (:func:`graspsim.maps.regrip.adapt_to_gripper`) against ``target``'s own FS map
    at the same settings.

    Rates: SRN / VRN [%] of the accepted grasps (grade above the threshold) in both,
    and pose by pose how many of the own map's accepted grasps the adapted map holds
    (``own_found``) and how many adapted ones the own map holds (``adapted_in_own``),
    which the voxel grid's edges cannot blur. Times: one cold adaptation (the object's
    collision samples built inside it, as for an object seen at run time), the median
    wall (and process CPU) time of ``repeats`` warm ones (the samples cached, as for a
    stored map's object) and one cold FS map of the target (threads: numba's default).
    Trials: lift-and-place of ``sim_grasps`` accepted grasps of each map, drawn the
    same way from the same random stream (common random numbers: where the two maps
    hold the same grasps, the same grasps are simulated)."""
    from graspsim.maps.hierarchy import clear_caches
    from graspsim.maps.metrics import relative_rates
    from graspsim.maps.regrip import adapt_to_gripper

    shape, source, cfg = fs_a.meta.shape, fs_a.meta.gripper_spec, fs_a.meta.map_config
    clear_caches()  # cold: the object's collision samples are built inside the timed run
    t0 = time.perf_counter()
    adapt_to_gripper(fs_a, target)
    cold = time.perf_counter() - t0
    times, cpu = [], []
    for _ in range(max(1, repeats)):
        t0, c0 = time.perf_counter(), time.process_time()
        adapted = adapt_to_gripper(fs_a, target)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    clear_caches()
    t0, c0 = time.perf_counter(), time.process_time()
    own = generate_fs_map(shape, target, fs_a.meta.quality_model, cfg, threads=threads)
    own_s, own_cpu = time.perf_counter() - t0, time.process_time() - c0
    row = {"object": name, "kind": getattr(shape, "kind", name), "source": source.name,
           "target": target.name, "adapt_s": float(np.median(times)), "adapt_runs": times,
           "adapt_cpu_s": float(np.median(cpu)), "adapt_cold_s": cold, "own_s": own_s, "own_cpu_s": own_cpu,
           "source_accepted": int(fs_a.accepted.sum()), "adapted": len(adapted),
           "own_accepted": int(own.accepted.sum()), **adapted.meta.gripper_adaptation.to_dict()}
    if row["own_accepted"] and len(adapted):
        own_acc = own.filter(accepted=True)
        rates = relative_rates(adapted, own_acc, min_grade=own.threshold)
        row.update(SRN=rates["SRN"], VRN=rates["VRN"], SR=rates["SR"], VR=rates["VR"],
                   SR_own=rates["SR_ref"], VR_own=rates["VR_ref"],
                   own_found=int(_found(own_acc, adapted).sum()),
                   adapted_in_own=int(_found(adapted.filter(accepted=True), own_acc).sum()))
    if sim_grasps:
        for key, m in (("sim_adapted", adapted), ("sim_own", own)):
            # common random numbers: both maps drawn (and simulated) from the same stream,
            # so maps holding the same grasps give the same draw
            rng = rng_for(seed, "adapted_vs_own", target.name, name)
            row[key] = simulate_accepted(m, sim_grasps, rng, threads=threads) if len(m) else _sim_record(None, 0, 0.0)
    return row
