"""The end-to-end demo: cloud -> identification -> adapted map -> MuJoCo validation.

The paper's case study in one run: a glue-bottle analog is seen as a noisy point cloud,
identified as two cylinders, its adapted graspability map is built from the FS map
database (built on first use into a local cache), and grasps drawn uniformly over the
map (the paper tested 15) are lift-and-placed in MuJoCo against the object's TRUE
geometry. Outputs: the adapted map (.h5), its plot, trial renders and a JSON summary.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.stats import wilson_interval

__all__ = ["DemoConfig", "run_demo"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DemoConfig:
    """out: output folder; cloud: a cloud file to use instead of the synthetic analog
    (then the grasps are simulated against the identified primitives, the truth being
    unknown); db: FS database folder (default: the user cache); quick: a coarse
    database in ``out/db`` and fewer trials (CI); trials: grasps validated (paper: 15);
    renders: trials rendered; noise: execution noise in the trials; seed; gripper: a
    registered name or a spec .json (None: the Festo; see :func:`graspsim.grippers.get_gripper`),
    resolved once, here (:attr:`gripper_spec`); robot: ``"panda"``: the trials are planned
    and executed by the Panda arm standing at ``robot_base`` (x [m], y [m], yaw [rad] from
    the object; None: 0.5 m away, facing it), as ``graspsim trial --robot panda`` does
    (:func:`graspsim.robots.run_arm_trials`; any gripper; not rendered), ``"none"``:
    the floating gripper."""

    out: str = "graspsim-demo"
    cloud: str | None = None
    db: str | None = None
    quick: bool = False
    trials: int = 15
    renders: int = 3
    noise: bool = False
    seed: int = 0
    threads: int | None = None
    gripper: str | None = None
    robot: str = "none"
    robot_base: tuple | None = None

    def __post_init__(self) -> None:
        from graspsim.grippers import get_gripper

        # a bad name or spec: one line, before any work
        object.__setattr__(self, "_gripper_spec", get_gripper(self.gripper))
        if self.robot != "none":
            from graspsim.robots.arm import DEFAULT_BASE, ROBOTS, base_transform

            if self.robot not in ROBOTS:
                raise InvalidParameterError(f"robot {self.robot!r} unknown; valid: {list(ROBOTS)}")
            base_transform(DEFAULT_BASE if self.robot_base is None else self.robot_base)
        if self.trials < 1:
            raise InvalidParameterError(f"trials must be >= 1, got {self.trials}")
        if self.renders < 0:
            raise InvalidParameterError(f"renders must be >= 0, got {self.renders}")

    @property
    def gripper_spec(self):
        """The :class:`~graspsim.grippers.spec.GripperSpec` of ``gripper``."""
        return self._gripper_spec


def _database(cfg: DemoConfig, step: Callable):
    import math

    from graspsim.maps.database import PAPER_SHAPES, MapDatabase
    from graspsim.maps.map_config import MapConfig

    gripper = cfg.gripper_spec
    if cfg.quick:
        db = MapDatabase(cfg.db or Path(cfg.out) / "db", gripper=gripper,
                         config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
    else:
        db = MapDatabase(cfg.db, gripper=gripper)
    missing = [s for s in PAPER_SHAPES.values() if not db.contains(s)]
    if missing:
        step(f"building the FS map database ({len(missing)} maps, first use) in {db.root}")
        db.build(PAPER_SHAPES.values(), threads=cfg.threads)
    return db


def _cloud(cfg: DemoConfig, rng: np.random.Generator):
    """(points, true shape or None, T_world_true or None, source, viewpoint or None): the
    viewpoint is where a cloud file's camera record says it was seen from (the robust
    score's occlusion term needs it); the synthetic analog is sampled all round (None)."""
    from graspsim.primitives import synthetic_cloud
    from graspsim.primitives.case_study import glue_bottle
    from graspsim.transforms import make_transform

    if cfg.cloud is not None:
        from graspsim.perception import read_point_cloud

        loaded = read_point_cloud(cfg.cloud)
        return loaded.points, None, None, str(cfg.cloud), loaded.viewpoint
    truth = glue_bottle()
    angle = rng.uniform(0, 2 * np.pi)
    R = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    T = make_transform(R, [0.55, -0.05, -truth.aabb[0, 2]])  # standing on a table at z = 0
    c = synthetic_cloud(truth, rng, resolution=0.002, noise=0.0008, outliers=0.01, T_world_obj=T)
    return c.points, truth, T, "synthetic glue-bottle analog", None


def run_demo(cfg: DemoConfig, *, step: Callable[[str], None] = lambda s: None) -> dict:
    """Run the demo; ``step(message)`` reports progress. Returns the summary dict (also
    written to ``out/summary.json``)."""
    from graspsim.maps.io import save_map
    from graspsim.maps.robust import executed_width, ranking
    from graspsim.maps.table_clearance import clears_table
    from graspsim.planning.planner import plan
    from graspsim.plots import plot_map
    from graspsim.sim import ExecutionNoise, LiftPlace, TrialOutcome, run_trials

    if cfg.quick:
        cfg = replace(cfg, trials=min(cfg.trials, 6), renders=min(cfg.renders, 1))
    from graspsim._atomic import check_folder

    t0 = time.perf_counter()
    out = check_folder(cfg.out, "demo output folder")  # before the work, not after it
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(cfg.seed)
    db = _database(cfg, step)
    points, truth, T_world_true, source, viewpoint = _cloud(cfg, rng)

    step(f"identifying {len(points)} points and adapting the map")
    t1 = time.perf_counter()
    result = plan(points, db=db, rng=np.random.default_rng(cfg.seed), source=source,
                  viewpoint=viewpoint)
    t_plan = time.perf_counter() - t1
    gmap = result.map
    if len(gmap):  # a failed run writes no map file (summary.json says why)
        save_map(gmap, out / "adapted_map.h5")
        plot_map(gmap, out / "adapted_map.png", min_grade=0.7,
                 title=f"adapted map: {len(gmap)} grasps ({result.status.value})")
    summary = {"config": asdict(cfg), "source": source, "status": result.status.value,
               "viewpoint": None if viewpoint is None else np.asarray(viewpoint).tolist(),
               "parts": [p.to_dict() for p in result.parts], "grasps": len(gmap),
               "accepted": int(gmap.accepted.sum()), "plan_seconds": t_plan,
               "time_to_first_0.95": result.timing.get("first"), "trials": []}
    if not len(gmap):
        step("identification failed: no map, nothing to simulate")
        return _finish(summary, out, t0)

    scene, T_true_obj = _sim_scene(result, truth, T_world_true, db)
    # grasps whose gripper stays clear of the table (2 mm) with the object standing on it,
    # drawn uniformly over the object
    T_sim = T_true_obj @ gmap.T_obj_wrist
    clear = clears_table(gmap, scene.T_world_obj @ T_true_obj, db.gripper, 0.002)
    candidates = np.flatnonzero(gmap.accepted & clear)
    summary["clear_of_table"] = len(candidates)
    # first the grasp a robot would execute (the best by the planner's robust ranking),
    # then grasps drawn uniformly over the object
    best = candidates[ranking(gmap.select(candidates))[:1]]
    rest = candidates[gmap.select(candidates).uniform_surface_rows(cfg.trials, rng)]
    rows = np.concatenate([best, rest[rest != best[0]] if len(best) else rest])[:cfg.trials]
    step(f"simulating {len(rows)} lift-and-place trials in MuJoCo: the best grasp by the robust "
         f"ranking, then grasps drawn from the {len(candidates)} grasps > 0.7 whose gripper stays "
         f"clear of the table (of {summary['accepted']} > 0.7)")
    noise = ExecutionNoise() if cfg.noise else None
    if cfg.robot == "none":
        res = run_trials(scene, T_sim[rows], executed_width(gmap, rows), LiftPlace(), threads=cfg.threads,
                         seed=cfg.seed, noise=noise)
    else:
        res = _arm_trials(cfg, scene, T_sim[rows], executed_width(gmap, rows), noise, step)
        summary.update(robot=cfg.robot, robot_base=res.scene["T_world_base"], plan=res.extra["plan"])
    ok = int(np.sum(res.outcome == TrialOutcome.SUCCESS))
    lo, hi = wilson_interval(ok, res.feasible)
    summary["trials"] = [{"row": int(r), "part": int(gmap.part[r]), "grade": float(gmap.grade[r]),
                          "robust": float(gmap.robust[r]) if np.isfinite(gmap.robust[r]) else None,
                          "outcome": o.label,
                          "lift_height": float(res.metrics.get("lift_height", np.full(len(rows), np.nan))[i]),
                          "hold_slip": float(res.metrics.get("hold_lin", np.full(len(rows), np.nan))[i])}
                         for i, (r, o) in enumerate(zip(rows, res.outcomes))]
    summary.update(counts=res.counts(), success=ok, feasible=res.feasible,
                   success_rate=res.success_rate, interval_95=[lo, hi],
                   trials_per_second=res.trials_per_second)
    if cfg.renders and cfg.robot != "none":
        step("the arm's trials are not rendered (yet)")
    elif cfg.renders:
        summary["renders"] = _render(scene, T_sim[rows], executed_width(gmap, rows), out / "renders",
                                     cfg.renders, step)
    return _finish(summary, out, t0)


def _arm_trials(cfg: DemoConfig, scene, T_obj_wrist, widths, noise, step):
    """The trials planned and executed by the arm (``cfg.robot``) in ``scene``'s place."""
    from graspsim.robots import (
        ArmLiftPlace,
        build_arm_scene,
        build_robot_model,
        capability_map,
        get_arm,
        run_arm_trials,
    )
    from graspsim.robots.arm import DEFAULT_BASE, base_transform

    arm = get_arm(cfg.robot)
    T_base = base_transform(DEFAULT_BASE if cfg.robot_base is None else cfg.robot_base)
    step(f"the {arm.name} arm plans and executes them (reachability first: what it refuses is a failure)")
    arm_scene = build_arm_scene(scene.obj, scene.gripper, scene.settings, arm=arm, base=T_base,
                                T_world_obj=scene.T_world_obj)
    cmap = capability_map(build_robot_model(arm, scene.gripper, T_base), arm, T_base)
    return run_arm_trials(arm_scene, T_obj_wrist, widths, ArmLiftPlace(), threads=cfg.threads, seed=cfg.seed,
                          noise=noise, capability=cmap)


def _sim_scene(result, truth, T_world_true, db):
    """(the scene, T_true_obj): the simulated object is the true geometry when known
    (the map's frame at T_true_obj in it), else the identified one."""
    from graspsim.primitives import shape_from_dict
    from graspsim.sim import SimSettings, build_scene, object_from_shape
    from graspsim.transforms import invert_transform

    if truth is not None:
        T_true_obj, sim_shape = invert_transform(T_world_true) @ result.T_cloud_obj, truth
    else:
        T_true_obj, sim_shape = np.eye(4), shape_from_dict(result.map.meta.object)
    scene = build_scene(object_from_shape(sim_shape), db.gripper, SimSettings(friction=db.quality.friction))
    return scene, T_true_obj


def _render(scene, T, width, folder: Path, n: int, step) -> list[str]:
    from graspsim.sim import render_trial

    step(f"rendering {min(n, len(T))} trials")
    paths = []
    try:
        for i in range(min(n, len(T))):
            paths += [str(p) for p in render_trial(scene, T[i], float(width[i]), folder,
                                                   name=f"trial{i:02d}", gif=(i == 0))]
    except Exception as err:  # noqa: BLE001 - no OpenGL here: the demo still succeeds
        log.warning("rendering skipped: %s", err)
        step(f"rendering skipped ({err.__class__.__name__}: no offscreen OpenGL?)")
    return paths


def _finish(summary: dict, out: Path, t0: float) -> dict:
    from graspsim._atomic import atomic_write_text
    from graspsim._jsonable import to_jsonable
    from graspsim.errors import OutputPathError

    summary["seconds"] = time.perf_counter() - t0
    atomic_write_text(out / "summary.json", json.dumps(to_jsonable(summary), indent=1), OutputPathError)
    return summary
