"""Experiment E08: baselines for ``graspsim/GraspPose-v0`` (propose a wrist pose).

Three policies propose a grasp for the same episodes (``reset(seed=s)`` replays an
episode: object, pose, cloud and execution error):

* random: an action drawn uniformly from the action box;
* top-down: the classic heuristic -- approach straight down over the observed cloud's
  centroid, close across its narrowest horizontal direction (principal axes of the
  points' x, y), the pads' middle 2 cm below the top, opened to the cloud's width there;
* planner: graspsim's run-time planner on the observed (fixed-size) cloud, with the
  table known (z = 0), proposing its highest-grade grasp (the top-down pose when the
  planner finds none).

Success rates with 95 % Wilson intervals, outcomes, rates per object kind, and the
policies' decision times. Writes table.md, results.json and config.json to ``--out``.

    python experiments/e08_pose_baselines.py --out results/e08
    python experiments/e08_pose_baselines.py --quick --out results/e08-quick
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import provenance, write_config, write_json  # noqa: E402

import graspsim  # noqa: E402, F401  (registers the environments)
from graspsim.maps.database import PAPER_SHAPES, MapDatabase  # noqa: E402
from graspsim.maps.generate import MapConfig  # noqa: E402
from graspsim.planner import PlannerConfig, TablePlane, plan  # noqa: E402
from graspsim.stats import wilson_interval  # noqa: E402
from graspsim.transforms import frame_from_axes, make_transform  # noqa: E402

log = logging.getLogger("e08")
POLICIES = ("random", "top_down", "planner")


@dataclass(frozen=True)
class Config:
    episodes: int = 300
    objects: str = "all"
    seed: int = 20181108
    db: str = ""
    quick: bool = False


def top_down_pose(env, cloud: np.ndarray) -> tuple[np.ndarray, float]:
    """(T_world_wrist, width): straight down over the centroid, closing across the
    cloud's narrowest horizontal direction."""
    g = env.gripper
    p = cloud.astype(float)
    c = p[:, :2].mean(axis=0)
    w, v = np.linalg.eigh(np.cov((p[:, :2] - c).T))
    x = np.array([v[0, 0], v[1, 0], 0.0])  # the smaller eigenvalue's axis
    z = np.array([0.0, 0.0, -1.0])
    top = float(p[:, 2].max())
    half_pad = 0.5 * g.pad_length
    tcp_z = max(top - half_pad, half_pad + 0.003)  # fingertips stay above the table
    band = p[np.abs(p[:, 2] - tcp_z) < half_pad]
    s = (band if len(band) else p)[:, :2] @ x[:2]
    width = float(np.clip(np.ptp(s), g.min_opening, g.max_opening - 2 * g.approach_clearance))
    centre = c + (0.5 * (s.max() + s.min()) - c @ x[:2]) * x[:2]
    R = frame_from_axes(x, z)
    tcp = np.array([centre[0], centre[1], tcp_z])
    return make_transform(R, tcp - g.tcp_offset(half_pad) * z), width  # the env's TCP: mid-pad


def planner_pose(env, cloud: np.ndarray, db: MapDatabase, seed: int) -> tuple[np.ndarray, float] | None:
    res = plan(cloud.astype(float), db=db, rng=np.random.default_rng(seed),
               config=PlannerConfig(table=TablePlane(height=0.0)))
    if not len(res.map):
        return None
    i = int(np.argmax(res.map.grade))
    return res.T_cloud_obj @ res.map.T_obj_wrist[i], float(res.map.width[i])


def run(cfg: Config) -> dict:
    import gymnasium as gym

    map_cfg = MapConfig(surface_step=0.01, rotation_step=math.radians(22)) if cfg.quick else MapConfig()
    db = MapDatabase(cfg.db or None, config=map_cfg)
    db.build(PAPER_SHAPES.values())
    env = gym.make("graspsim/GraspPose-v0", objects=cfg.objects).unwrapped
    seeds = np.random.SeedSequence(cfg.seed).generate_state(cfg.episodes)
    rows = []
    for k, s in enumerate(seeds):
        s = int(s)
        row = {"seed": s}
        for name in POLICIES:
            obs, info = env.reset(seed=s)
            row["kind"] = info["object"]["kind"]
            t0 = time.perf_counter()
            fallback = False
            if name == "random":
                action = np.random.default_rng([s, 1]).uniform(-1, 1, 10).astype(np.float32)
            else:
                pose = planner_pose(env, obs["cloud"], db, s) if name == "planner" else None
                if pose is None:
                    fallback = name == "planner"
                    pose = top_down_pose(env, obs["cloud"])
                action = env.action_from_pose(*pose)
            t_decide = time.perf_counter() - t0
            _, reward, _, _, step_info = env.step(action)
            row[name] = {"reward": reward, "outcome": step_info["outcome"], "seconds": t_decide,
                         "fallback": fallback}
        rows.append(row)
        if (k + 1) % 50 == 0:
            log.info("%d / %d episodes", k + 1, cfg.episodes)
    return {"rows": rows}


def summarise(rows: list[dict]) -> dict:
    out = {}
    for name in POLICIES:
        r = np.array([row[name]["reward"] for row in rows])
        ok = int(r.sum())
        lo, hi = wilson_interval(ok, len(r))
        kinds = sorted({row["kind"] for row in rows})
        out[name] = {"success": ok, "episodes": len(r), "rate": ok / len(r), "interval_95": [lo, hi],
                     "outcomes": dict(Counter(row[name]["outcome"] for row in rows)),
                     "seconds_mean": float(np.mean([row[name]["seconds"] for row in rows])),
                     "fallbacks": int(sum(row[name]["fallback"] for row in rows)),
                     "by_kind": {k: float(np.mean([row[name]["reward"] for row in rows if row["kind"] == k]))
                                 for k in kinds}}
    return out


def write_table(summary: dict, cfg: Config) -> str:
    L = ["# E08 grasp-proposal baselines (GraspPose-v0)", "",
         f"{cfg.episodes} episodes, objects `{cfg.objects}`, the same episodes for every policy "
         "(execution error 3 mm / 2 deg as the environment's default).", "",
         "| policy | success | 95 % Wilson | decision time [ms] | planner fallbacks |", "|---|---|---|---|---|"]
    for name, s in summary.items():
        L.append(f"| {name} | {100 * s['rate']:.1f} % ({s['success']}/{s['episodes']}) | "
                 f"{100 * s['interval_95'][0]:.1f} - {100 * s['interval_95'][1]:.1f} % | "
                 f"{1000 * s['seconds_mean']:.1f} | {s['fallbacks'] if name == 'planner' else '-'} |")
    outcomes = sorted({o for s in summary.values() for o in s["outcomes"]})
    L += ["", "### outcomes", "", "| policy | " + " | ".join(outcomes) + " |",
          "|---|" + "---|" * len(outcomes)]
    for name, s in summary.items():
        L.append(f"| {name} | " + " | ".join(str(s["outcomes"].get(o, 0)) for o in outcomes) + " |")
    kinds = sorted(next(iter(summary.values()))["by_kind"])
    L += ["", "### success by object kind", "", "| policy | " + " | ".join(kinds) + " |",
          "|---|" + "---|" * len(kinds)]
    for name, s in summary.items():
        L.append(f"| {name} | " + " | ".join(f"{100 * s['by_kind'][k]:.0f} %" for k in kinds) + " |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="results/e08", help="output folder")
    p.add_argument("--episodes", type=int, default=Config.episodes)
    p.add_argument("--objects", default=Config.objects, help="object set (default all)")
    p.add_argument("--seed", type=int, default=Config.seed)
    p.add_argument("--db", default="", help="FS database folder (default: the library's; quick: OUT/fsdb)")
    p.add_argument("--quick", action="store_true", help="a few episodes on a coarse database (CI)")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = Config(episodes=a.episodes, objects=a.objects, seed=a.seed, db=a.db)
    if a.quick:
        cfg = replace(cfg, episodes=min(a.episodes, 6), quick=True, db=a.db or str(out / "fsdb"))
    write_config(out / "config.json", cfg)
    t0 = time.perf_counter()
    res = run(cfg)
    summary = summarise(res["rows"])
    table = write_table(summary, cfg)
    (out / "table.md").write_text(table)
    write_json(out / "results.json", {"config": cfg, "provenance": provenance(), "summary": summary,
                                      "episodes": res["rows"], "wall_s": time.perf_counter() - t0})
    print(table)
    print(f"wall {time.perf_counter() - t0:.0f} s; results in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
