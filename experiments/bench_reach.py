"""Benchmark: reachability of a map's grasps by the Panda arm (issue 39's goals: the
first cut >= 10 000 poses/s on this 2-core machine; exact IK for a map's 100 best
<= 0.2 s).

For each primitive: its FS map for ``--gripper`` (a model-file gripper, the Franka hand
by default) at the scripts' map settings, the object resting on the table over the
origin, the Panda at its default base (0.5 m away, facing it). Timed, in this process,
through the public API a user calls (``graspsim.robots``):

* the capability map: built cold into a fresh cache folder under ``--out`` (the first
  run on a machine), then read back (every later run);
* the first cut: ``CapabilityMap.lookup`` of every wrist pose of the map, repeated until
  at least ``--min-poses`` poses were looked up (poses/s);
* exact IK for the map's ``--best`` best grasps (the robust ranking): the wrist pose and
  its pre-grasp 10 cm back (``ArmKinematics.ik``, seeded by the map), and the whole
  reachability check of a trial (``check_reach``: IK at the grasp, the pre-grasp and
  every 1 cm of the approach line, joint limits, self / table / object collisions), each
  the median of ``--repeat`` passes;
* the first cut against the exact check on those best grasps (how often the map calls
  a grasp the arm reaches unreachable: it should not).

A scene frame planned with reachability (issue 39's goal: <= 1 s): ``--scenes`` piles of
``--scene-objects`` objects of ``--object-set`` (seeds from ``--scene-seed``), cleared by
the Panda at its default base as ``graspsim scene --robot panda`` clears them
(``ClutterEpisode`` with ``ClutterConfig.robot``: every look renders a depth frame, plans
it with ``plan_scene``, puts every ranked grasp through the arm's first cut and the best
it lets through through the exact check and motion plan until one passes; that one is
executed). Timed per look, in this process: the planning (depth frame to ranked grasps)
plus the reachability (first cut and exact checks), the render not counted. The maps the
scenes' first frames need are built beforehand in a child process (as a user's first run
would; the capability map too), so the process's first frame is cold (segment workers
started, maps read from disk) and later ones warm; a later frame whose planning still
built a map (a part of a new size) is counted apart, not in the medians. Reported: the
process's first frame, the median of the other scenes' first frames, and the median of
the later frames of the episodes (the previous frame's plan reused where a segment did
not change), each with the load average.

    python experiments/bench_reach.py [--publish]
    python experiments/bench_reach.py --quick --out results/bench_reach-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import shutil
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import load_average, map_config, opt, start

log = logging.getLogger("bench_reach")

KINDS = ("box", "cylinder", "sphere", "cone", "half_toroid")
GOAL_POSES_S = 10_000
GOAL_BEST_S = 0.2
GOAL_FRAME_S = 1.0


@dataclass(frozen=True)
class Config:
    kinds: tuple[str, ...] = opt(("box", "cylinder"), "the paper's primitives", choices=KINDS)
    gripper: str = opt("franka_hand", "the gripper on the arm's flange (a model file, or simulated from its spec)")
    best: int = opt(100, "the map's best grasps given exact IK")
    repeat: int = opt(3, "timed passes of the exact IK (median)")
    min_poses: int = opt(200_000, "poses looked up per map for the first cut's rate")
    samples: int = opt(500_000, "joint samples of the capability map")
    coarse: bool = opt(True, "coarse FS maps (1 cm surface step, 22 deg rotations): the poses, not the map, are timed")
    scenes: int = opt(5, "piles cleared by the arm for the scene-frame timing (0: none)")
    scene_objects: int = opt(5, "objects per pile")
    scene_seed: int = opt(0, "the piles' seed (run_benchmark's scene rule)")
    object_set: str = opt("household-tuning", "the piles' object set")
    db: str = opt("", "the scene planner's map database folder (default: a private <out>/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse maps for the scene planner's database (1 cm, 22 deg): for smoke runs")
    QUICK: ClassVar[dict] = {"kinds": ("box",), "best": 10, "repeat": 1, "min_poses": 20_000, "samples": 50_000,
                             "scenes": 2, "scene_objects": 2, "object_set": "primitives", "coarse_db": True}

    def __post_init__(self) -> None:
        if self.best < 1 or self.repeat < 1 or self.min_poses < 1 or self.samples < 1:
            raise ValueError("--best, --repeat, --min-poses and --samples must be >= 1")
        if self.scenes < 0 or self.scene_objects < 1:
            raise ValueError("--scenes must be >= 0 and --scene-objects >= 1")


def _timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def measure(kind: str, gripper, cfg: Config, cache: Path) -> dict:
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.robust import executed_width, ranking
    from graspsim.robots import PANDA, CapabilityConfig, base_transform, build_arm_scene, capability_map, check_reach
    from graspsim.sim import object_from_shape

    shape = PAPER_SHAPES[kind]
    gmap = generate_fs_map(shape, gripper, config=map_config(cfg.coarse))
    scene = build_arm_scene(object_from_shape(shape), gripper)
    kin = scene.kinematics()
    T_world = scene.T_world_obj @ gmap.T_obj_wrist
    B = base_transform()
    from graspsim.robots import build_robot_model

    robot = build_robot_model(PANDA, gripper)
    ccfg = CapabilityConfig(samples=cfg.samples)
    cache = cache / kind  # a fresh cache per primitive: every build is timed cold (a rerun's is removed)
    shutil.rmtree(cache, ignore_errors=True)
    cmap, build_s, _ = _timed(lambda: capability_map(robot, PANDA, B, ccfg, cache_dir=cache))
    _, load_s, _ = _timed(lambda: capability_map(robot, PANDA, B, ccfg, cache_dir=cache))
    reps = max(1, -(-cfg.min_poses // len(T_world)))
    poses = np.concatenate([T_world] * reps)
    (reach, _), look_s, look_cpu = _timed(lambda: cmap.lookup(poses))
    ok_all, seeds_all = cmap.lookup(T_world)
    order = ranking(gmap, "robust")[:cfg.best]
    best = T_world[order]
    seeds = seeds_all[order]
    openings = gripper.pregrasp_opening(executed_width(gmap.select(order)))
    pre = best.copy()
    pre[:, :3, 3] -= 0.10 * best[:, :3, 2]

    def ik_pair():
        out = []
        for T, P, s in zip(best, pre, seeds):
            r = kin.ik(T, None if np.isnan(s).any() else s)
            out.append(r.ok and kin.ik(P, r.q).ok)
        return out

    def full_check():
        out = []
        for T, s, w in zip(best, seeds, openings):
            jaws = (scene.drive.qadr, scene.drive.joint_positions([w])[0])
            out.append(check_reach(kin, T, jaws=jaws, seeds=() if np.isnan(s).any() else (s,)).reach.label)
        return out

    pair = [_timed(ik_pair) for _ in range(cfg.repeat)]
    full = [_timed(full_check) for _ in range(cfg.repeat)]
    verdicts = full[-1][0]
    exact_ok = np.array([v == "reachable" for v in verdicts])
    map_ok = ok_all[order]
    row = {"kind": kind, "grasps": len(gmap), "best": len(order), "capability_build_s": build_s,
           "capability_load_s": load_s, "capability_cells_marked": cmap.fraction(),
           "lookup_poses": len(poses), "lookup_s": look_s, "lookup_cpu_s": look_cpu,
           "poses_per_s": len(poses) / look_s, "map_reachable_share": float(ok_all.mean()),
           "ik_pair_s": statistics.median(p[1] for p in pair), "ik_pair_cpu_s": statistics.median(p[2] for p in pair),
           "ik_pair_solved": int(sum(pair[-1][0])),
           "check_s": statistics.median(f[1] for f in full), "check_cpu_s": statistics.median(f[2] for f in full),
           "verdicts": {v: verdicts.count(v) for v in sorted(set(verdicts))},
           "map_no_exact_yes": int(np.sum(~map_ok & exact_ok)), "map_yes_exact_no": int(np.sum(map_ok & ~exact_ok)),
           "load": load_average()[0]}
    log.info("%-10s %6d grasps: lookup %.0f poses/s; %d best: IK pairs %.3f s, full check %.3f s; %s", kind,
             len(gmap), row["poses_per_s"], len(order), row["ik_pair_s"], row["check_s"], row["verdicts"])
    return row


def _scene(cfg: Config, db, i: int):
    from graspsim.seeding import derived_seed
    from graspsim.tabletop.table_scene import make_scene

    return make_scene(cfg.scene_objects, "pile", derived_seed(cfg.scene_seed, "scene", i), object_set=cfg.object_set,
                      gripper=db.gripper)


def _episode(cfg: Config, db, i: int, cache: Path):
    from graspsim.seeding import rng_for
    from graspsim.tabletop.clutter import ClutterConfig, ClutterEpisode, ClutterRobot, scene_settings

    config = ClutterConfig(scene=scene_settings("pile"), robot=ClutterRobot(cache_dir=cache))
    return ClutterEpisode(_scene(cfg, db, i), db=db, rng=rng_for(cfg.scene_seed, "clutter", i), config=config)


def _scene_database(cfg: Config, gripper, out: Path):
    from _common import experiment_database

    return experiment_database(cfg.db, out, map_config(cfg.coarse_db), gripper=gripper)


def _prepare_scenes(cfg: Config, gripper_name: str, root: str, cache: str) -> None:
    """(A child process) the first look of every pile, untimed: the maps its parts need
    built into the database and the arm's capability map into ``cache``."""
    from graspsim.grippers import get_gripper
    from graspsim.maps.database import MapDatabase
    from graspsim.tabletop.scene_objects import prepare_objects

    gripper = get_gripper(gripper_name)
    prepare_objects(cfg.object_set, gripper)
    db = MapDatabase(Path(root), config=map_config(cfg.coarse_db), gripper=gripper)
    for i in range(cfg.scenes):
        ep = _episode(cfg, db, i, Path(cache))
        try:
            ep.observe()
        finally:
            ep.close()


def measure_frames(cfg: Config, gripper, out: Path) -> dict:
    """Every look of the piles' clearing by the arm, timed (module doc)."""
    import multiprocessing

    from _common import database_record

    db = _scene_database(cfg, gripper, out)
    start_db = database_record(db)
    cache = out / "reach-cache" / "scene"
    child = multiprocessing.get_context("spawn").Process(
        target=_prepare_scenes, args=(cfg, gripper.name, str(db.root), str(cache)))
    child.start()
    child.join()
    if child.exitcode != 0:
        raise SystemExit(f"preparing the piles' maps failed (exit {child.exitcode})")
    prepared = database_record(db)
    frames = []
    for i in range(cfg.scenes):
        ep = _episode(cfg, db, i, cache)
        try:
            look_no = 0
            while ep.stop is None:
                maps = len(db.entries())
                t0 = time.perf_counter()
                look = ep.observe()
                wall = time.perf_counter() - t0
                last = ep.last
                reach_s = (last.reach or {}).get("seconds", 0.0)
                frames.append({"scene": i, "look": look_no, "planning_s": last.planning, "reach_s": reach_s,
                               "frame_s": last.planning + reach_s, "observe_s": wall,
                               "grasps": len(last.plan.grasps), "segments": last.plan.perception.n_segments,
                               "reach": None if last.reach is None else
                               {k: v for k, v in last.reach.items() if k != "seconds"},
                               "built_maps": len(db.entries()) > maps, "load": load_average()[0]})
                log.info("pile %d look %d: planning %.3f s + reachability %.3f s (%d grasps, %d segments)%s", i,
                         look_no, last.planning, reach_s, len(last.plan.grasps), last.plan.perception.n_segments,
                         " (built maps)" if frames[-1]["built_maps"] else "")
                look_no += 1
                if look is None:
                    break
                ep.execute(look, look.best)
        finally:
            ep.close()

    def group(rows):
        rows = [r for r in rows if not r["built_maps"]]
        if not rows:
            return None
        return {"of": len(rows), **{f"median_{k}": statistics.median(r[k] for r in rows)
                                    for k in ("frame_s", "planning_s", "reach_s", "load")},
                "max_frame_s": max(r["frame_s"] for r in rows)}

    firsts = [f for f in frames if f["look"] == 0]
    return {"object_set": cfg.object_set, "objects": cfg.scene_objects, "scenes": cfg.scenes, "frames": frames,
            "first": frames[0] if frames else None, "first_frames": group(firsts[1:]),
            "later_frames": group([f for f in frames if f["look"] > 0]),
            "built_maps": sum(f["built_maps"] for f in frames[1:]),
            "database": {"start": start_db, "prepared": prepared, "end": database_record(db)}}


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    from graspsim.grippers import get_gripper

    gripper = get_gripper(cfg.gripper)
    cache = Path(out) / "reach-cache"
    rows = [measure(k, gripper, cfg, cache) for k in cfg.kinds]
    frames = measure_frames(cfg, gripper, Path(out)) if cfg.scenes else None
    data = {"config": cfg, "gripper": gripper.name, "goal_poses_s": GOAL_POSES_S, "goal_best_s": GOAL_BEST_S,
            "goal_frame_s": GOAL_FRAME_S, "rows": rows, "scene_frames": frames,
            "slowest_lookup_poses_s": min(r["poses_per_s"] for r in rows),
            "slowest_ik_pair_s": max(r["ik_pair_s"] for r in rows), "slowest_check_s": max(r["check_s"] for r in rows),
            "denominators": f"per primitive: every wrist pose of its FS map (repeated to >= {cfg.min_poses} "
                            f"lookups); the {cfg.best} best by the robust ranking for exact IK, median of "
                            f"{cfg.repeat} passes"}
    print(run.write(out, data, readme_section))
    return 0


def readme_section(s: dict) -> str:
    """The README's paragraph for this benchmark (see ``experiments/report.py``)."""
    m = s["machine"]
    c = s["config"]
    L = [f"`{s['command']}` (issue 39's goals: reachability first cut >= {s['goal_poses_s']:,} poses/s; exact IK "
         f"for a map's 100 best <= {s['goal_best_s']:g} s): the Panda at its default base, the {s['gripper']} on "
         f"its flange, FS maps of the primitives resting on the table. First cut: the capability map "
         f"({c['samples']:,} joint samples) looked up for every map pose; exact: mink IK of the {c['best']} best "
         "grasps and their pre-grasps (seeded by the map), and the full check of a trial (the approach line every "
         "1 cm, limits, collisions).", "",
         "| primitive | grasps | map build s | map load s | lookup poses/s | IK pairs s | solved | full check s "
         "| verdicts | map no / exact yes |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in s["rows"]:
        L.append(f"| {r['kind']} | {r['grasps']} | {r['capability_build_s']:.1f} | {r['capability_load_s']:.2f} | "
                 f"{r['poses_per_s']:,.0f} | {r['ik_pair_s']:.3f} | {r['ik_pair_solved']}/{r['best']} | "
                 f"{r['check_s']:.3f} | {r['verdicts']} | {r['map_no_exact_yes']} |")
    L += frame_lines(s)
    L += ["", f"Load average {m['load_avg_start'][0]:.1f} at the start, {m['load_avg_end'][0]:.1f} at the end, on "
          f"{m['cpus']} cores; commit `{s['provenance']['commit']}`."]
    return "\n".join(L) + "\n"


def frame_lines(s: dict) -> list[str]:
    """The scene-frame part's table ([] when it did not run)."""
    f = s.get("scene_frames")
    if not f or not f["frames"]:
        return []

    def cells(g, what):
        if g is None:
            return f"| {what} | - | - | - | - | - |"
        return (f"| {what} ({g['of']}) | {g['median_frame_s']:.2f} | {g['median_planning_s']:.2f} | "
                f"{g['median_reach_s']:.2f} | {g['max_frame_s']:.2f} | {g['median_load']:.1f} |")

    first = f["first"]
    n = len(f["frames"])
    L = ["", f"A scene frame planned with reachability (goal <= {s['goal_frame_s']:g} s): {f['scenes']} piles of "
         f"{f['objects']} {f['object_set']} objects cleared by the Panda at its default base as `graspsim scene "
         "--robot panda` clears them, every look timed in one process: planning (depth frame to ranked grasps, "
         "`plan_scene`) plus reachability (the first cut of every ranked grasp, the exact check and motion plan of "
         f"the best it lets through until one passes); {n} looks. The maps of the piles' first frames were built "
         "beforehand in another process; looks that still built a map are left out of the medians "
         f"({f['built_maps']}).", "",
         "| frames | median s (planning + reachability) | planning s | reachability s | slowest s | load |",
         "|---|---|---|---|---|---|",
         f"| the process's first | {first['frame_s']:.2f} | {first['planning_s']:.2f} | {first['reach_s']:.2f} | "
         f"{first['frame_s']:.2f} | {first['load']:.1f} |",
         cells(f["first_frames"], "the other piles' first"), cells(f["later_frames"], "later looks of the episodes")]
    return L


if __name__ == "__main__":
    raise SystemExit(main())
