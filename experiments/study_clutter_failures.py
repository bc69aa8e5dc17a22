"""Diagnosis of clutter-removal failures (issue 17): what each grasp was planned on, and
where the gripper started in collision.

Runs E10's protocol (``graspsim.tabletop.clutter.ClutterEpisode``: the same scenes, seeds,
camera, sensor noise and database as ``e10_clutter_removal.py``, scene ``i`` of a
condition) on the scenes listed, executing the best grasp each time, and records per
grasp: the object the chosen segment mostly shows (ground truth), whether the segment
was planned afresh or its plan reused, the parts it was identified as, the share of
the segment's points lying more than 3 / 6 / 10 mm outside every identified part
(observed volume the parts leave out), the grasp's robust score and clearance to the
observed points, the gripper's lowest point above the table (z = 0) at the planned and
at the executed pose (with execution error they differ: a low-profile grasp's fingertips
pass 0.5 mm above the table), the outcome, and for a start collision which gripper part
overlapped what and how deep (``SceneSim.overlaps`` at the executed pose).

    python experiments/study_clutter_failures.py --kind pile --scenes 5 9 16 30 33 36 --db results/e10-fsdb
    python experiments/study_clutter_failures.py --kind pile --noise default --scenes 0 2 6 14 40 --db results/e10-fsdb
    python experiments/study_clutter_failures.py --quick --out results/study_clutter_failures-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start

log = logging.getLogger("study_clutter_failures")


@dataclass(frozen=True)
class Config:
    kind: str = opt("pile", "scene kind", choices=("pile", "packed"))
    objects: int = opt(5, "objects per scene")
    noise: str = opt("none", "execution error: none, default (3 mm / 2 deg)", choices=("none", "default"))
    scenes: tuple[int, ...] = opt((5, 9, 16, 30, 33, 36), "E10 scene indices")
    object_set: str = opt("mixed", "objects drawn from this set")
    seed: int = opt(0, "run seed (E10's)")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder, read only (default: OUT/fsdb, built fresh)")
    QUICK: ClassVar[dict] = {"kind": "packed", "objects": 2, "scenes": (0,), "object_set": "primitives",
                             "quick_maps": True}


def outside_shares(points: np.ndarray, ident) -> list[float]:
    """Share of ``points`` (N, 3) more than 3, 6, 10 mm outside every identified part."""
    if ident is None or not ident.parts or not len(points):
        return []
    d = np.full(len(points), np.inf)
    for p in ident.parts:
        T = np.linalg.inv(p.T_world_obj)
        d = np.minimum(d, p.primitive().sdf(points @ T[:3, :3].T + T[:3, 3]))
    return [float(np.mean(d > t)) for t in (0.003, 0.006, 0.010)]


def lowest(gripper, T_world_wrist: np.ndarray, opening: float) -> float:
    """The gripper's lowest point [m] above the table z = 0 at a wrist pose, jaws at ``opening``."""
    T = np.asarray(T_world_wrist, float)
    return float(gripper.lowest_along(T[2, :3][None], T[2, 3:4], np.array([opening]))[0])


def episode(i: int, cfg: Config, db) -> tuple[list[dict], list[dict]]:
    """Scene ``i``'s episode: one row per executed grasp, and one per object left on the
    table with why (``ClutterEpisode.left_reasons``: no_grasp, not_tried, ...)."""
    from e10_clutter_removal import looks

    from graspsim.sim.noise import ExecutionNoise
    from graspsim.tabletop.clutter import ClutterConfig, benchmark_episode, scene_settings

    ep = benchmark_episode(cfg.objects, cfg.kind, cfg.seed, i, db=db, object_set=cfg.object_set,
                           config=ClutterConfig(scene=scene_settings(cfg.kind),
                                                execution=ExecutionNoise() if cfg.noise == "default" else None))
    scene = ep.scene
    rows = []
    try:
        for look, g, sp, mem in looks(ep):
            a = ep.execute(look, g)
            o = a.outcome
            executed = np.asarray(o.get("T_world_wrist", g.T_world_wrist), float)
            where = ep.sim.overlaps(executed, o["opening"]) if o["collided"] else {}
            rows.append({"scene": i, "object": None if a.target is None else scene.objects[a.target].name,
                         "segment": sp.segments[g.segment].status,
                         "parts": [str(p.primitive()) for p in (mem.ident.parts if mem.ident else ())],
                         "outside_3_6_10mm": outside_shares(mem.points, mem.ident), "score": g.score,
                         "clearance_mm": 1000.0 * g.clearance, "cause": a.cause,
                         "lowest_planned_mm": round(1000.0 * lowest(db.gripper, g.T_world_wrist, g.opening), 2),
                         "lowest_executed_mm": round(1000.0 * lowest(db.gripper, executed, o["opening"]), 2),
                         "overlaps_mm": {f"{name}->{what}": round(1000.0 * v, 1)
                                         for (name, what), v in where.items() if v > 0.001}})
            log.info("%s", json.dumps(rows[-1]))
        left = [{"scene": i, "object": scene.objects[k].name, "why": why} for k, why in ep.left_reasons().items()]
    finally:
        ep.close()
    return rows, left


def run(cfg: Config, db) -> dict:
    done = [episode(i, cfg, db) for i in cfg.scenes]
    rows = [r for e in done for r in e[0]]
    left = [x for e in done for x in e[1]]
    why: dict[str, dict[str, int]] = {}
    for x in left:
        why.setdefault(x["object"], {}).setdefault(x["why"], 0)
        why[x["object"]][x["why"]] += 1
    removed = sum(r["cause"] in ("success", "success_other_object") for r in rows)
    causes: dict[str, int] = {}
    for r in rows:
        causes[r["cause"]] = causes.get(r["cause"], 0) + 1
    return {"grasps": len(rows), "lifted_target": causes.get("success", 0), "removed": removed,
            "placed": cfg.objects * len(cfg.scenes), "causes": causes, "rows": rows, "left": left,
            "left_by_object": why,
            "denominators": "grasps: executed in the listed scenes; placed: objects x scenes"}


def readme_section(s: dict) -> str:
    """The failures, one row each."""
    L = [f"`{s['command']}`: {s['lifted_target']}/{s['grasps']} grasps lifted their target, "
         f"{s['removed']}/{s['placed']} objects removed; left on the table: "
         + ("; ".join(f"{o} {', '.join(f'{w} {n}' for w, n in ws.items())}" for o, ws in s["left_by_object"].items())
            or "none") + ".", "",
         "| scene | object | segment | identified as | outside > 3/6/10 mm | score | lowest planned / executed [mm] "
         "| cause | overlap [mm] |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in s["rows"]:
        if r["cause"] != "success":
            out = "/".join(f"{100 * v:.0f} %" for v in r["outside_3_6_10mm"])
            L.append(f"| {r['scene']} | {r['object']} | {r['segment']} | {', '.join(r['parts'])} | {out} | "
                     f"{r['score']:.2f} | {r['lowest_planned_mm']:.1f} / {r['lowest_executed_mm']:.1f} | "
                     f"{r['cause']} | {r['overlaps_mm']} |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    from e10_clutter_removal import read_only_database

    cfg, out, record = start(Config, __file__, argv, __doc__)
    db = read_only_database(cfg, out)
    record.write(out, {"config": cfg, **run(cfg, db)}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
