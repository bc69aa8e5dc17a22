"""Experiment E08: baselines for ``graspsim/GraspPose-v0`` (propose a wrist pose).

Policies propose a grasp for the same episodes (``reset(seed=s)`` replays an episode:
object, pose, cloud and execution error):

* random: an action drawn uniformly from the action box;
* top-down: the classic heuristic -- approach straight down over the observed cloud's
  centroid, close across its narrowest horizontal direction (principal axes of the
  points' x, y), the pads' middle 2 cm below the top, opened to the cloud's width there;
* planner: graspsim's run-time planner on the observed (fixed-size) cloud, with the
  table known (z = 0), proposing its highest-grade grasp (when the planner finds none:
  the stand-in below);
* planner, robust: the same plan's best grasp by the robust ranking (the planner's
  default: expected success under 3 mm / 2 deg wrist error, clearance to the observed
  cloud; ``graspsim.maps.robust``) -- the stand-in when no grasp scores above 0;
* planner, robust, opening: the same, scoring each grasp also with the jaws opened
  wider (``--open-mm``, extra gap per side) and executing the best grasp at the opening
  its score assumed (the planner's default scores 0/3/6/10 mm already, so with the
  default ``--open-mm`` this row repeats the one above);
* ablations of the robust score (``--ablations``): ``no_cloud`` (perturbations checked
  against the identified primitives and the table only), ``nominal`` (no pose error:
  clearance at the nominal pose only), ``sigma_half`` and ``sigma_double`` (the
  perturbations at half and twice the error);
* planner, clearance C mm (``--clearance``): the highest-grade grasp whose gripper,
  with the jaws opened C mm wider on each side than the pre-grasp opening (and executed
  so), stays C mm clear of the identified primitives -- room for the fingers to miss
  (the stand-in when none of the ``--clearance-rows`` best does, or the opening would
  exceed the gripper's).

The stand-in, wherever the planner offers no grasp (identification failed, or nothing
scored): the best top-down candidate scored against the observed cloud and the table
with the planner's robust score (``graspsim.envs.top_down.robust_top_down``), or *no
grasp* (nothing executed, a failure) when no top-down candidate clears what was seen.

Each proposal is executed under every ``--noise`` condition: ``default`` (the
environment's execution error, 3 mm / 2 deg), ``none``, or ``MM:DEG`` sigmas; the
episodes are the same (their objects and clouds do not depend on the error). Success
rates with 95 % Wilson intervals, outcomes, rates per object kind, the same rates on
the episodes where the planner found a grasp (no fallback), and decision times. Writes
summary.json, table.md, results.json and config.json to ``--out``.

    python experiments/e08_pose_baselines.py
    python experiments/e08_pose_baselines.py --quick --out results/e08-quick

Flags: one per field of :class:`Config` (the experiment harness, ``_common.py``);
``--publish`` copies the summary to ``experiments/reported/``. Episodes are seeded by the
seed rule (``graspsim.seeding``): episode k resets with ``derived_seed(seed, "episode", k)``;
its plan draws from ``rng_for(s, "plan")`` and the random policy's action from
``rng_for(s, "random")`` (s the episode's seed), streams apart from the episode's own.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import (
    database_note,
    database_record,
    derived_seed,
    experiment_database,
    map_config,
    noise_sigmas,
    opt,
    rate_ci,
    rng_for,
    start,
    write_json,
)

from graspsim.envs.baselines import planner_pose
from graspsim.envs.top_down import robust_top_down, top_down_pose
from graspsim.geometry.table import TablePlane
from graspsim.maps.collide import boxes_clear_sdf
from graspsim.maps.database import MapDatabase
from graspsim.maps.robust import ABLATION_LABELS, ABLATIONS, RobustConfig, cloud_in_object, score_map
from graspsim.planning.planner import PlannerConfig, plan
from graspsim.stats import mcnemar, wilson_interval
from graspsim.transforms import invert_transform

log = logging.getLogger("e08")


@dataclass(frozen=True)
class Config:
    episodes: int = opt(300, "episodes")
    objects: str = opt("all", "object set")
    seed: int = opt(20181108, "run seed")
    noise: tuple[str, ...] = opt(("default", "none"), "execution error conditions: default (3 mm / 2 deg), "
                                                      "none, or MM:DEG")
    clearance_mm: tuple[float, ...] = opt((3.0, 10.0), "planner variants asking for this clearance from the "
                                                       "identified shape [mm]")
    clearance_rows: int = opt(2000, "best grasps searched for a clear one")
    open_mm: tuple[float, ...] = opt((0.0, 3.0, 6.0, 10.0), "extra jaw openings per side [mm] the robust "
                                                           "ranking may choose from (planner_robust_open)")
    ablations: tuple[str, ...] = opt(tuple(ABLATIONS), "robust-score ablations run as extra planner policies",
                                     choices=tuple(ABLATIONS))
    db: str | None = opt(None, "FS database folder (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "a coarse FS database (10 mm, 22 deg: CI)")
    QUICK: ClassVar[dict] = {"episodes": 6, "coarse_db": True}

    def __post_init__(self) -> None:
        for label in self.noise:
            noise_sigmas(label)  # ValueError naming the bad label
        if len(set(self.noise)) < len(self.noise):
            raise ValueError(f"--noise conditions must be distinct, got {self.noise}")
        if any(not (c > 0 and math.isfinite(c)) for c in self.clearance_mm):
            raise ValueError(f"--clearance-mm values must be > 0 mm, got {self.clearance_mm}")
        if self.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {self.episodes}")

    @property
    def policies(self) -> tuple[str, ...]:
        return (("random", "top_down", "planner", "planner_robust", "planner_robust_open")
                + tuple(_clear_name(c) for c in self.clearance_mm)
                + tuple(f"planner_robust_{a}" for a in self.ablations))


def _clear_name(mm: float) -> str:
    return f"planner_clear_{mm:g}mm"


class _Inflated:
    """A shape grown by ``margin`` [m] (only its signed distance is needed)."""

    def __init__(self, shape, margin: float):
        self.shape, self.margin = shape, margin

    def sdf(self, points: np.ndarray) -> np.ndarray:
        return self.shape.sdf(points) - self.margin


def clear_row(res, gripper, clearance: float, max_rows: int, chunk: int = 250) -> int | None:
    """Row of the plan's map (sorted best first) of the highest-grade grasp whose gripper,
    its jaws opened ``clearance`` [m] wider on each side than the pre-grasp opening, stays
    ``clearance`` clear of every identified part; None if none of the ``max_rows`` best
    does."""
    m = res.map
    for i0 in range(0, min(len(m), max_rows), chunk):
        idx = np.arange(i0, min(i0 + chunk, len(m), max_rows))
        T = m.T_obj_wrist[idx]
        opening = m.width[idx] + 2.0 * (gripper.approach_clearance + clearance)
        ok = opening <= gripper.max_opening
        opening = np.minimum(opening, gripper.max_opening)
        for part in res.parts:
            T_part = invert_transform(part.T_obj_part) @ T
            ok &= boxes_clear_sdf(_Inflated(part.primitive, clearance), gripper, T_part, opening)
        if ok.any():
            return int(idx[np.argmax(ok)])
    return None


def planner_poses(env, cloud: np.ndarray, db: MapDatabase, seed: int, cfg: Config) -> dict:
    """{policy: (T_world_wrist, width) or None, and seconds} of the planner policies,
    from one plan of the cloud."""
    t0 = time.perf_counter()
    res = plan(cloud.astype(float), db=db, rng=rng_for(seed, "plan"),
               config=PlannerConfig(table=TablePlane(height=0.0)))
    t_plan = time.perf_counter() - t0
    out = {"planner_robust": (planner_pose(res, "robust"), t_plan)}
    cloud_obj = cloud_in_object(cloud, res.T_cloud_obj)
    t1 = time.perf_counter()
    wide = RobustConfig(openings=tuple(mm / 1000.0 for mm in cfg.open_mm))
    out["planner_robust_open"] = (planner_pose(replace(res, map=score_map(res.map, cloud_obj, wide)), "robust"),
                                  t_plan + time.perf_counter() - t1)
    for name in cfg.ablations:
        t1 = time.perf_counter()
        variant = replace(res, map=score_map(res.map, cloud_obj, replace(RobustConfig(), **ABLATIONS[name])))
        out[f"planner_robust_{name}"] = (planner_pose(variant, "robust"), t_plan + time.perf_counter() - t1)
    for c in (0.0,) + tuple(cfg.clearance_mm):
        t1 = time.perf_counter()
        paper = replace(res, map=res.map.ranked("paper"))
        i = (0 if len(res.map) else None) if c == 0 else (
            clear_row(paper, env.gripper, c / 1000.0, cfg.clearance_rows) if len(res.map) else None)
        # the action's width: the jaws open to width + 2 x approach clearance, so + 2c more
        pose = None if i is None else (res.T_cloud_obj @ paper.map.T_obj_wrist[i],
                                       float(paper.map.width[i]) + 2.0 * c / 1000.0)
        out["planner" if c == 0 else _clear_name(c)] = (pose, t_plan + time.perf_counter() - t1)
    return out


def run(cfg: Config, out: Path) -> dict:
    import gymnasium as gym

    map_cfg = map_config(cfg.coarse_db)
    db = experiment_database(cfg.db, out, map_cfg)
    db_start = database_record(db)
    envs = {}
    for label in cfg.noise:
        pos, deg = noise_sigmas(label)
        envs[label] = gym.make("graspsim/GraspPose-v0", objects=cfg.objects, position_noise=pos,
                               rotation_noise=math.radians(deg)).unwrapped
    env0 = envs[cfg.noise[0]]
    rows = []
    for k in range(cfg.episodes):
        s = derived_seed(cfg.seed, "episode", k)
        obs, info = env0.reset(seed=s)
        row = {"seed": s, "kind": info["object"]["kind"], "cloud_points": int(len(obs["cloud"]))}
        decisions = planner_poses(env0, obs["cloud"], db, s, cfg)
        t0 = time.perf_counter()
        decisions["top_down"] = (top_down_pose(obs["cloud"], env0.gripper), time.perf_counter() - t0)
        t0 = time.perf_counter()
        stand_in = robust_top_down(obs["cloud"], env0.gripper)  # None: no top-down grasp clears the cloud
        t_stand_in = time.perf_counter() - t0
        actions = {"random": rng_for(s, "random").uniform(-1, 1, 10).astype(np.float32)}
        for name in cfg.policies[1:]:
            pose, seconds = decisions[name]
            fallback = pose is None
            if fallback:
                pose, seconds = stand_in, seconds + t_stand_in
            actions[name] = None if pose is None else env0.action_from_pose(*pose)
            row[name] = {"seconds": seconds, "fallback": fallback, "no_grasp": pose is None}
        row["random"] = {"seconds": 0.0, "fallback": False, "no_grasp": False}
        for label, env in envs.items():
            for name in cfg.policies:
                o, _ = env.reset(seed=s)
                if not np.array_equal(o["cloud"], obs["cloud"]):
                    raise RuntimeError("the noise conditions drew different episodes")  # pragma: no cover
                if actions[name] is None:  # reported as no grasp: nothing executed, a failure
                    row[name][label] = {"reward": 0.0, "outcome": "no_grasp"}
                    continue
                _, reward, _, _, step_info = env.step(actions[name])
                row[name][label] = {"reward": reward, "outcome": step_info["outcome"]}
        rows.append(row)
        if (k + 1) % 25 == 0:
            log.info("%d / %d episodes", k + 1, cfg.episodes)
    return {"rows": rows, "database": {"start": db_start, "end": database_record(db)}}


def _rates(rows: list[dict], name: str, label: str) -> dict:
    r = np.array([row[name][label]["reward"] for row in rows])
    ok = int(r.sum())
    lo, hi = wilson_interval(ok, len(r))
    return {"success": ok, "episodes": len(r), "rate": ok / len(r) if len(r) else None, "interval_95": [lo, hi],
            "outcomes": dict(Counter(row[name][label]["outcome"] for row in rows))}


def summarise(rows: list[dict], cfg: Config) -> dict:
    kinds = sorted({row["kind"] for row in rows})
    found = [row for row in rows if not row["planner"]["fallback"]]
    found_all = [row for row in found if not any(row[_clear_name(c)]["fallback"] for c in cfg.clearance_mm)]
    out = {"episodes": len(rows), "cloud_points": sorted({row["cloud_points"] for row in rows}),
           "planner_found": len(found), "planner_found_all_clearances": len(found_all),
           "policies": {}}
    for name in cfg.policies:
        out["policies"][name] = {
            "seconds_mean": float(np.mean([row[name]["seconds"] for row in rows])),
            "fallbacks": int(sum(row[name]["fallback"] for row in rows)),
            "no_grasps": int(sum(row[name].get("no_grasp", False) for row in rows)),
            **{label: {"all": _rates(rows, name, label), "planner_found": _rates(found, name, label),
                       "planner_found_all_clearances": _rates(found_all, name, label),
                       "by_kind": {k: _rates([r for r in rows if r["kind"] == k], name, label)["rate"]
                                   for k in kinds}}
               for label in cfg.noise}}
    out["paired"] = {label: {other: mcnemar(_successes(rows, "planner_robust", label), _successes(rows, other, label))
                             for other in PAIRED_WITH} for label in cfg.noise}
    return out


PAIRED_WITH = ("top_down", "planner")  # the robust ranking's paired comparisons


def _successes(rows: list[dict], name: str, label: str) -> np.ndarray:
    return np.array([row[name][label]["reward"] > 0 for row in rows])


def write_table(summary: dict, cfg: Config) -> str:
    L = ["# E08 grasp-proposal baselines (GraspPose-v0)", "",
         f"{cfg.episodes} episodes, objects `{cfg.objects}`, the same episodes for every policy and noise "
         f"condition; the planner found a grasp in {summary['planner_found']}.", ""]
    for label in cfg.noise:
        pol = summary["policies"]
        L += [f"## execution error: {label}", "",
              "| policy | success | on the planner's episodes | decision time [ms] | fallbacks |",
              "|---|---|---|---|---|"]
        for name, s in pol.items():
            a, f = s[label]["all"], s[label]["planner_found"]
            L.append(f"| {name} | {rate_ci(a['success'], a['episodes'], a['interval_95'])} | "
                     f"{rate_ci(f['success'], f['episodes'])} | {1000 * s['seconds_mean']:.1f} | {s['fallbacks']} |")
        outcomes = sorted({o for s in pol.values() for o in s[label]["all"]["outcomes"]})
        L += ["", "| policy | " + " | ".join(outcomes) + " |", "|---|" + "---|" * len(outcomes)]
        for name, s in pol.items():
            L.append(f"| {name} | " + " | ".join(str(s[label]["all"]["outcomes"].get(o, 0)) for o in outcomes) + " |")
        kinds = sorted(next(iter(pol.values()))[label]["by_kind"])
        L += ["", "| policy | " + " | ".join(kinds) + " |", "|---|" + "---|" * len(kinds)]
        for name, s in pol.items():
            L.append(f"| {name} | " + " | ".join(f"{100 * s[label]['by_kind'][k]:.0f} %" for k in kinds) + " |")
        L.append("")
    return "\n".join(L)


def main(argv=None) -> int:
    cfg, out, run_record = start(Config, __file__, argv, __doc__)
    res = run(cfg, out)
    summary = summarise(res["rows"], cfg)
    table = write_table(summary, cfg)
    (out / "table.md").write_text(table)
    data = {"config": cfg, "noise_sigmas": {k: noise_sigmas(k) for k in cfg.noise}, "summary": summary,
            "database": res["database"]}
    run_record.write(out, data, readme_section)
    write_json(out / "results.json", {**run_record.summary(data), "episodes": res["rows"]})
    print(table)
    print(f"wall {run_record.clock.wall:.0f} s; results in {out}")
    return 0


NAMES = {"random": "random action", "top_down": "top-down heuristic",
         "planner": "planner, highest paper grade", "planner_robust": "planner, robust ranking (the default)",
         "planner_robust_open": "planner, robust ranking choosing the jaw opening too"}


def _name(p: str) -> str:
    if p in NAMES:
        return NAMES[p]
    if p.startswith("planner_robust_"):
        return "planner, robust ranking: " + ABLATION_LABELS[p[len("planner_robust_"):]]
    return (f"planner, highest grade with {p.rsplit('_', 1)[1].replace('mm', ' mm')} of "
            f"clearance from the shape")


def readme_section(s: dict) -> str:
    """The README's E08 paragraph and table (see ``experiments/report.py``)."""
    cfg, r = s["config"], s["summary"]
    labels = cfg["noise"]

    def err(label):
        pos, deg = s["noise_sigmas"][label]
        return "no execution error" if pos == 0 and deg == 0 else f"{1000 * pos:g} mm / {deg:g}° error"

    L = [f"`{s['command']}`: {r['episodes']} episodes (objects `{cfg['objects']}`), the same for every policy "
         f"and execution error; the planner works on the observed "
         f"{'/'.join(map(str, r['cloud_points']))}-point cloud with the table known and "
         f"found a grasp in {r['planner_found']} episodes (in the others the best top-down candidate by the robust "
         f"score against the observed cloud stands in, or no grasp where none clears it)."
         + database_note(s), ""]
    head = ["policy"] + [f"success, {err(x)}" for x in labels] + \
        [f"on the planner's {r['planner_found']} episodes, {err(x)}" for x in labels] + \
        [f"START_COLLISION, {err(x)}" for x in labels] + ["planner found none (stand-in)"]
    L += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, p in r["policies"].items():
        cells = [rate_ci(p[x]["all"]["success"], p[x]["all"]["episodes"], p[x]["all"]["interval_95"]) for x in labels]
        cells += [rate_ci(p[x]["planner_found"]["success"], p[x]["planner_found"]["episodes"]) for x in labels]
        cells += [str(p[x]["all"]["outcomes"].get("start_collision", 0)) for x in labels]
        no = p.get("no_grasps", 0)
        stand_in = f"{p['fallbacks']}" + (f" ({no} no grasp)" if no else "")
        cells.append("–" if name in ("random", "top_down") else stand_in)
        L.append(f"| {_name(name)} | " + " | ".join(cells) + " |")
    if cfg["clearance_mm"]:
        n = r["planner_found_all_clearances"]
        x = labels[0]
        parts = [f"{_name(name)} {rate_ci(p[x]['planner_found_all_clearances']['success'], n)}"
                 for name, p in r["policies"].items() if name != "random"]
        L += ["", f"On the {n} episodes where the planner found a grasp at every clearance ({err(x)}): "
              + "; ".join(parts) + "."]
    for x, pairs in r.get("paired", {}).items():  # runs before this comparison have none
        L += ["", f"The robust ranking vs the other policies on the same episodes, {err(x)}: " + "; ".join(
            f"vs the {_name(o).removeprefix('planner, ')}: robust alone succeeds in {m['only_first']}, "
            f"the other alone in {m['only_second']} (exact McNemar p = {m['p_exact']:.2g})"
            for o, m in pairs.items()) + "."]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
