"""Experiment E16: grasps executed by a Panda arm against the floating gripper, paired.

Each of the paper's primitives gets its FS map for ``--gripper``, less the poses that
would put the gripper into the table (``graspsim.maps.table_clearance.clears_table``: what a planner
told of the table offers), written to ``<out>/maps``; the object rests on the table over
the origin. An episode places the
Panda's base ``--distance`` from the object at a bearing drawn by the seed rule
(``derived_seed(seed, "episode", kind, e)``), facing it. In every episode the map's
``--top`` best grasps (the robust ranking) are

* executed by the floating gripper (``graspsim.sim.simulate_map``: the grasp as the map
  has it; it does not depend on the base, so one run per object serves all its
  episodes), and
* planned and executed by the arm (``graspsim.robots.simulate_map_arm``, what
  ``graspsim trial --robot panda`` runs): reachability first (never executing what it
  refuses, which counts as a failure), then move, approach, close, lift, place by the
  joint servos.

Reported: how many of each object's best grasps the arm reaches from the episodes'
bases; top-1 success of the floating gripper and of the arm on the same episodes
(McNemar, exact), and of the arm's best *reachable* grasp (the first of the top ones whose
whole plan -- reachability, approach, lift, retreat, the move there -- passed: a ranking
that prefers what the arm reaches); the arm's failure causes. No drawn execution error:
the arm's is its controller's and the contacts'.

Clutter removal by the arm (``--clutter-scenes`` per seed, ``--clutter-seeds`` seeds by
``graspsim.tabletop.clutter_stats.benchmark_seeds``): the same scenes
(``graspsim.tabletop.clutter.run_benchmark``, what ``graspsim scene`` runs) cleared by the
floating gripper and by the Panda at its default base (``ClutterConfig.robot``, what
``graspsim scene --robot panda`` runs), planned against one map database for
``--gripper`` (a private ``<out>/fsdb`` unless ``--db``), at the library's map resolution
unless ``--coarse-clutter``: E10's size grid of maps is stored in it first (``--grid``),
and it is read only during the run (``_common.RunDatabase``: a part no stored map serves
gets its map built in memory), so the arm and the floating gripper plan against the same
stored maps whichever ran first. Reported: GSR and DR of each (pooled, and per seed mean
+- std), per scene paired (objects removed), the failure causes, the episodes' stops
(``unreachable``: grasps were left and the arm reached none) and what the arm's
reachability check refused.

    python experiments/e16_arm_execution.py
    python experiments/e16_arm_execution.py --quick --out results/e16-quick
    python experiments/e16_arm_execution.py --kinds box --episodes 1 --clutter-scenes 3 --clutter-seeds 2
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import derived_seed, map_config, opt, rate_ci, start

log = logging.getLogger("e16")

KINDS = ("box", "cylinder", "sphere", "cone", "half_toroid")


@dataclass(frozen=True)
class Config:
    seed: int = opt(0, "run seed (the episodes' bases)")
    kinds: tuple[str, ...] = opt(KINDS, "the paper's primitives", choices=KINDS)
    episodes: int = opt(6, "base placements per object")
    top: int = opt(10, "the map's best grasps tried per episode")
    distance: float = opt(0.5, "the base's distance from the object [m]")
    gripper: str = opt("franka_hand", "the gripper on the arm's flange (a model file, or simulated from its spec)")
    coarse: bool = opt(True, "coarse FS maps (1 cm surface step, 22 deg rotations)")
    threads: int = opt(2, "simulation threads")
    clutter_scenes: int = opt(3, "clutter-removal scenes per seed, cleared by the arm and by the floating gripper "
                                 "(0: no clutter part)")
    clutter_seeds: int = opt(2, "clutter-removal seeds (benchmark_seeds of --seed)")
    clutter_objects: int = opt(5, "objects per clutter scene")
    clutter_kind: str = opt("pile", "clutter scene kind", choices=("pile", "packed"))
    clutter_object_set: str = opt("household-tuning", "the clutter scenes' object set")
    coarse_clutter: bool = opt(False, "coarse maps for the clutter planner's database (1 cm, 22 deg)")
    db: str = opt("", "the clutter planner's map database folder (default: a private <out>/fsdb, built fresh)")
    grid: bool = opt(True, "store E10's size grid of FS maps in the clutter database before the first scene "
                           "(kept where stored already); the database is read only during the run")
    QUICK: ClassVar[dict] = {"kinds": ("box",), "episodes": 2, "top": 3, "clutter_scenes": 1, "clutter_seeds": 1,
                             "clutter_objects": 2, "clutter_kind": "packed", "clutter_object_set": "primitives",
                             "coarse_clutter": True, "grid": False}

    def __post_init__(self) -> None:
        if self.episodes < 1 or self.top < 1 or self.threads < 1:
            raise ValueError("--episodes, --top and --threads must be >= 1")
        if self.clutter_scenes < 0 or self.clutter_seeds < 1 or self.clutter_objects < 1:
            raise ValueError("--clutter-scenes must be >= 0, --clutter-seeds and --clutter-objects >= 1")
        if not (0.2 <= self.distance <= 1.0):
            raise ValueError("--distance must be within 0.2-1.0 m (the Panda reaches ~0.86 m)")


def _bearing(seed: int, kind: str, e: int) -> float:
    return float(np.random.default_rng(derived_seed(seed, "episode", kind, e)).uniform(-math.pi, math.pi))


def run_kind(kind: str, cfg: Config, gripper, out: Path) -> dict:
    from graspsim.maps import save_map
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.table_clearance import clears_table
    from graspsim.robots import Reach, simulate_map_arm
    from graspsim.sim import TrialOutcome, object_from_shape, resting_pose, simulate_map

    path = out / "maps" / f"{kind}.h5"
    path.parent.mkdir(parents=True, exist_ok=True)
    shape = PAPER_SHAPES[kind]
    fs = generate_fs_map(shape, gripper, config=map_config(cfg.coarse))
    # the grasps a planner told of the table offers (graspsim.maps.table_clearance): the object rests as simulated
    T_table_obj = resting_pose(object_from_shape(shape))  # object -> table (world) coordinates
    save_map(fs.select(np.flatnonzero(clears_table(fs, T_table_obj, gripper))), path)
    floating = simulate_map(path, top=cfg.top, threads=cfg.threads, write=False)
    f_out = floating.results.outcome
    episodes = []
    for e in range(cfg.episodes):
        b = _bearing(cfg.seed, kind, e)
        base = (-cfg.distance * math.cos(b), -cfg.distance * math.sin(b), b)  # facing the object
        arm = simulate_map_arm(path, top=cfg.top, base=base, threads=cfg.threads, write=False,
                               capability_cache=out / "reach-cache")
        assert np.array_equal(arm.index, floating.index)  # the same grasps, in the same order
        a_out = arm.results.outcome
        reach = arm.results.metrics["reach"]
        executed = np.isfinite(arm.results.metrics["lift_height"])  # its whole plan passed (lift, retreat, move)
        accepted = np.flatnonzero(executed)
        first = int(accepted[0]) if len(accepted) else None
        episodes.append({
            "episode": e, "bearing_deg": math.degrees(b), "base": list(base),
            "arm": [TrialOutcome(int(o)).label for o in a_out],
            "reach": [Reach(int(r)).label for r in reach],
            "top1_floating": bool(f_out[0] == TrialOutcome.SUCCESS),
            "top1_arm": bool(a_out[0] == TrialOutcome.SUCCESS),
            "best_reachable_rank": first,
            "best_reachable_arm": bool(first is not None and a_out[first] == TrialOutcome.SUCCESS),
            "executed_unreachable": int(np.sum((reach != Reach.REACHABLE) & executed)),
            "reach_lin_mm": [1e3 * float(x) for x in arm.results.metrics["reach_lin"] if np.isfinite(x)],
        })
        log.info("%-11s episode %d (bearing %+.0f deg): floating %s, arm %s; reachable %d/%d", kind, e,
                 math.degrees(b), TrialOutcome(int(f_out[0])).label, TrialOutcome(int(a_out[0])).label,
                 int(np.sum(reach == Reach.REACHABLE)), len(reach))
    return {"kind": kind, "grasps_tried": len(floating.index), "floating": [TrialOutcome(int(o)).label for o in f_out],
            "episodes": episodes}


def run_clutter_part(cfg: Config, gripper, out: Path) -> dict:
    """The same clutter scenes cleared by the floating gripper and by the arm (module doc)."""
    from _common import RunDatabase, build_grid, database_record, experiment_database, map_config

    from graspsim.tabletop.clutter import ClutterConfig, ClutterRobot, run_benchmark, scene_settings, summarize
    from graspsim.tabletop.clutter_stats import benchmark_seeds, per_seed
    from graspsim.tabletop.scene_objects import prepare_objects

    store = experiment_database(cfg.db, out, map_config(cfg.coarse_clutter), gripper=gripper)
    empty = build_grid(store) if cfg.grid else []  # the maps the run plans from, before the first scene
    db = RunDatabase(store.root, config=store.config, gripper=gripper)
    database = {**database_record(store), "grid_without_grasps": empty}
    prepare_objects(cfg.clutter_object_set, gripper, progress=True)
    robot = ClutterRobot(cache_dir=out / "reach-cache")
    conds = {"floating": None, "arm": robot}
    by = {k: {} for k in conds}
    for sd in benchmark_seeds(cfg.seed, cfg.clutter_seeds):
        for name, arm in conds.items():
            c = ClutterConfig(scene=scene_settings(cfg.clutter_kind), robot=arm)
            by[name][sd] = run_benchmark(cfg.clutter_objects, cfg.clutter_kind, cfg.clutter_scenes, sd, db=db,
                                         config=c, object_set=cfg.clutter_object_set)
            for i, r in enumerate(by[name][sd]):
                log.info("clutter seed %d scene %d, %s: removed %d/%d in %d grasps (%s)", sd, i, name, r.removed,
                         r.placed, len(r.attempts), r.stop)
    refused, looks = Counter(), 0
    for rs in by["arm"].values():
        for r in rs:
            for a in r.attempts:
                looks += 1
                for x in (a.reach or {}).get("refused", []):
                    refused[f"{x['cause']} at {x['stage']}"] += 1
    pairs = [{"seed": sd, "scene": i, "floating": f.removed, "arm": a.removed, "placed": f.placed,
              "floating_stop": f.stop, "arm_stop": a.stop}
             for sd in by["floating"] for i, (f, a) in enumerate(zip(by["floating"][sd], by["arm"][sd]))]
    res = {}
    for name in conds:
        results = [r for rs in by[name].values() for r in rs]
        s = summarize(results)
        s.pop("per_object")
        res[name] = {**s, "seeds": per_seed(by[name]),
                     "episodes": [{"seed": sd, "scene": i, **{k: v for k, v in r.to_dict().items() if k != "steps"},
                                   "causes": [a.cause for a in r.attempts]}
                                  for sd, rs in by[name].items() for i, r in enumerate(rs)]}
    return {"kind": cfg.clutter_kind, "objects": cfg.clutter_objects, "object_set": cfg.clutter_object_set,
            "scenes": cfg.clutter_scenes, "seeds": benchmark_seeds(cfg.seed, cfg.clutter_seeds),
            "robot": robot.to_dict(), "results": res, "paired": pairs,
            "arm_refused": dict(refused), "arm_looks_executed": looks,
            "arm_more": sum(p["arm"] > p["floating"] for p in pairs),
            "floating_more": sum(p["floating"] > p["arm"] for p in pairs),
            "database": {**database, "built_in_memory": sorted(db.built)}}


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    from graspsim.grippers import get_gripper
    from graspsim.stats import mcnemar, wilson_interval

    gripper = get_gripper(cfg.gripper)
    out = Path(out)
    rows = [run_kind(k, cfg, gripper, out) for k in cfg.kinds]
    eps = [e for r in rows for e in r["episodes"]]
    f1 = np.array([e["top1_floating"] for e in eps])
    a1 = np.array([e["top1_arm"] for e in eps])
    ab = np.array([e["best_reachable_arm"] for e in eps])
    n = len(eps)
    causes = Counter(o for e in eps for o in e["arm"][:1] if o != "success")
    reach = Counter(r for e in eps for r in e["reach"])
    per_kind = {r["kind"]: {"reachable_of_top": [sum(x == "reachable" for x in e["reach"]) for e in r["episodes"]],
                            "top": r["grasps_tried"]} for r in rows}
    data = {
        "config": cfg, "gripper": gripper.name, "rows": rows, "episodes": n,
        "top1_floating": {"k": int(f1.sum()), "n": n, "ci": wilson_interval(int(f1.sum()), n)},
        "top1_arm": {"k": int(a1.sum()), "n": n, "ci": wilson_interval(int(a1.sum()), n)},
        "best_reachable_arm": {"k": int(ab.sum()), "n": n, "ci": wilson_interval(int(ab.sum()), n)},
        "mcnemar_top1_arm_vs_floating": mcnemar(a1, f1),
        "mcnemar_best_reachable_vs_floating": mcnemar(ab, f1),
        "top1_arm_failure_causes": dict(causes), "reach_verdicts_top": dict(reach), "per_kind": per_kind,
        "executed_unreachable": sum(e["executed_unreachable"] for e in eps),
        "denominators": f"{n} episodes ({len(rows)} objects x {cfg.episodes} base placements); reach verdicts over "
                        f"the top {cfg.top} grasps of every episode; a grasp the arm did not execute is a failure",
    }
    if cfg.clutter_scenes:
        data["clutter"] = run_clutter_part(cfg, gripper, out)
    print(run.write(out, data, readme_section))
    return 0


def readme_section(s: dict) -> str:
    """The results block (see ``experiments/report.py``)."""
    c = s["config"]
    m = s["machine"]

    def rate(key):
        r = s[key]
        return rate_ci(r["k"], r["n"], r["ci"])

    L = [f"`{s['command']}`: the paper's primitives ({', '.join(c['kinds'])}), FS maps for the {s['gripper']}; "
         f"{c['episodes']} episodes each, the Panda's base {c['distance']:g} m from the object at a seeded bearing; "
         f"the top {c['top']} grasps (robust ranking) executed by the floating gripper and by the arm.", "",
         "| | top-1 success [95 % CI] |", "|---|---|",
         f"| floating gripper | {rate('top1_floating')} |", f"| arm, top-1 | {rate('top1_arm')} |",
         f"| arm, best reachable grasp | {rate('best_reachable_arm')} |", "",
         f"Paired (McNemar, exact): arm top-1 vs floating: only arm {s['mcnemar_top1_arm_vs_floating']['only_first']}, "
         f"only floating {s['mcnemar_top1_arm_vs_floating']['only_second']}, "
         f"p = {s['mcnemar_top1_arm_vs_floating']['p_exact']:.3g}; best reachable vs floating: only arm "
         f"{s['mcnemar_best_reachable_vs_floating']['only_first']}, only floating "
         f"{s['mcnemar_best_reachable_vs_floating']['only_second']}, "
         f"p = {s['mcnemar_best_reachable_vs_floating']['p_exact']:.3g}.", "",
         f"Arm top-1 failures by cause: {s['top1_arm_failure_causes'] or 'none'}. Reachability verdicts over every "
         f"episode's top {c['top']}: {s['reach_verdicts_top']}. Grasps executed that the check called unreachable: "
         f"{s['executed_unreachable']}.", "",
         "| object | reachable of the top, per episode |", "|---|---|"]
    for k, v in s["per_kind"].items():
        L.append(f"| {k} | {', '.join(str(x) for x in v['reachable_of_top'])} (of {v['top']}) |")
    if s.get("clutter"):
        L += ["", *clutter_lines(s["clutter"])]
    L += ["", f"Load average {m['load_avg_start'][0]:.1f} at the start, {m['load_avg_end'][0]:.1f} at the end, on "
          f"{m['cpus']} cores; commit `{s['provenance']['commit']}`."]
    return "\n".join(L) + "\n"


def clutter_lines(c: dict) -> list[str]:
    """The clutter part's block: GSR and DR of the floating gripper and of the arm."""
    def gsr_dr(r):
        g = r["grasp_success_rate"]
        return (f"{r['successes']}/{r['attempts']} ({'n/a' if g is None else f'{100 * g:.1f} %'})",
                f"{r['removed']}/{r['placed']} ({100 * r['cleared_rate']:.1f} %)", r["seeds"]["gsr_text"],
                r["seeds"]["dr_text"])

    L = [f"Clutter removal, {len(c['seeds'])} seed(s) x {c['scenes']} {c['kind']}s of {c['objects']} objects "
         f"({c['object_set']}), the same scenes for both:", "",
         "| | GSR | DR | GSR per seed | DR per seed | stops | failed grasps by cause |",
         "|---|---|---|---|---|---|---|"]
    for name, label in (("floating", "floating gripper"), ("arm", "Panda arm")):
        r = c["results"][name]
        stops = ", ".join(f"{k} {v}" for k, v in r["stops"].items() if v) or "-"
        causes = ", ".join(f"{k} {v}" for k, v in r["failure_causes"].items()) or "-"
        L.append(f"| {label} | " + " | ".join(gsr_dr(r)) + f" | {stops} | {causes} |")
    refused = ", ".join(f"{k} {v}" for k, v in c["arm_refused"].items()) or "none"
    L += ["", f"Per scene, objects removed: the arm more in {c['arm_more']}, the floating gripper more in "
          f"{c['floating_more']} of {len(c['paired'])}. Grasps the arm's check refused before the one it executed "
          f"(over {c['arm_looks_executed']} executed grasps): {refused}."]
    d = c.get("database")
    if d:
        L += ["", f"Both planned against the same database, read only during the run: {len(d['maps'])} stored FS "
              f"maps; {len(d['built_in_memory'])} maps built in memory for parts no stored map serves (not stored)."]
    return L


if __name__ == "__main__":
    raise SystemExit(main())
