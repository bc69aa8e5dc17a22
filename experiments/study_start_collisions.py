"""Diagnosis of grasps that start in collision (``start_collision_target`` /
``start_collision_neighbour``) in E10's episodes.

Replays E10's episodes as ``study_drops.py`` does (``graspsim.tabletop.clutter.ClutterEpisode``
with E10's settings: the same scenes, seeds, camera, sensor noise, execution error and
database; ``SEED_INDEX:SCENE`` is scene ``SCENE`` (within its seed) of seed
``benchmark_seeds(--seed, --seeds)[SEED_INDEX]``, as ``e10_clutter_removal.py --seeds K``
draws it) and, for every executed grasp that starts in collision, records at the pose
executed (MuJoCo's collision detection at the grasp's start state, nothing simulated; a
start collision leaves the scene as it was):

* every gripper part (geom) that overlaps an object, which object, how deep, where
  (the deepest contact's point), on which side of the object seen from the camera;
* whether the camera saw the object's surface there: the distance from that point to
  the nearest observed point of the object hit (ground-truth labels), and how far behind
  the first surface the camera saw along the camera ray through the point;
* the point's signed distance to the parts the planner identified on the grasp's
  segment (negative: inside the fit), and the fit itself: the parts, the segment's
  points' share more than 3 / 6 / 10 mm outside every part, their median |distance|;
* the object's pose: its height, footprint and lowest point, the tilt of its mesh frame's
  z axis from vertical;
* the planner's robust score, grade, clearance to the observed points, opening.

    python experiments/study_start_collisions.py --kind packed --seeds 5 --cases 1:6 2:7 --db /work/runs/e10-fsdb

Found on E10's household-tuning episodes at impratio 100 (the 75 episodes with a start
collision and a milk carton or mug, all four conditions; every cause reproduced): of the
22 milk grasps that started in their target, 20 were the carton standing in a packed scene,
a pad's lower end (once the housing) 1 to 18 mm in it where the camera had not seen it
(18 to 42 mm from its nearest seen point, mostly behind a neighbour), 11 to 33 mm past the
parts fitted to its seen faces (slabs 1 to 21 mm thick for a 44 mm carton; the seen points
matched to a median 0.5 to 1.4 mm), the unseen margin the full 20 mm; 3 of them repeated
the grasp that had just failed. The mug's 8: its handle hidden behind the body that a
cylinder was fitted to (2), the handle seen alone and fitted as a 6 mm rod (3), a lying or
tilted mug (2), one graze under execution error.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start
from e10_clutter_removal import E10Cases

from graspsim._gl import import_mujoco

mujoco = import_mujoco()  # MUJOCO_GL chosen first (headless rendering)

log = logging.getLogger("study_start_collisions")


@dataclass(frozen=True)
class Config(E10Cases):
    cases: tuple[str, ...] = opt(("0:2",), "cases SEED_INDEX:SCENE[:GRASPS] (scene index within its seed; "
                                           "GRASPS: stop after that many executed grasps)")
    workers: int = opt(1, "planning processes (SceneConfig.workers; the result does not depend on it)")
    QUICK: ClassVar[dict] = {"kind": "packed", "objects": 2, "seeds": 1, "cases": ("0:0",), "object_set": "primitives",
                             "quick_maps": True}


def _parts_sdf(ident, points: np.ndarray) -> np.ndarray:
    """Signed distance [m] of ``points`` (N, 3) to the union of the identified parts."""
    d = np.full(len(points), np.inf)
    if ident is None:
        return d
    for p in ident.parts:
        T = np.linalg.inv(p.T_world_obj)
        d = np.minimum(d, p.primitive().sdf(points @ T[:3, :3].T + T[:3, 3]))
    return d


def _object_shape(sim, k: int) -> dict:
    """Object ``k``'s height, world-axis footprint and lowest point now, and its frame's tilt."""
    m, d = sim.model, sim.data
    body = sim.body[k]
    verts = []
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != body or m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        mid = m.geom_dataid[g]
        v = m.mesh_vert[m.mesh_vertadr[mid]:m.mesh_vertadr[mid] + m.mesh_vertnum[mid]]
        verts.append(v @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g])
    R = d.xmat[body].reshape(3, 3)
    out = {"frame_z_tilt_deg": round(math.degrees(math.acos(np.clip(R[2, 2], -1, 1))), 1)}
    if verts:
        v = np.concatenate(verts)
        out.update(height_mm=round(1000 * float(np.ptp(v[:, 2])), 1),
                   footprint_xy_mm=[round(1000 * float(x), 1) for x in np.ptp(v[:, :2], axis=0)],
                   bottom_mm=round(1000 * float(v[:, 2].min()), 1))
    return out


def contacts(sim, T: np.ndarray, opening: float) -> list[dict]:
    """Every gripper part's overlap with an object at the start state of a grasp at ``T``."""
    m = sim.model
    state = sim._start_state(np.asarray(T, float), float(opening))
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    grip = np.zeros(m.ngeom, bool)
    grip[sim.gripper_geoms] = True
    best: dict = {}
    for c in d.contact[:d.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        if grip[g1] == grip[g2]:
            continue
        mine, other = (g1, g2) if grip[g1] else (g2, g1)
        if other == sim.table_geom:
            what = "table"
        else:
            what = int(sim.geom_object[other])
            if what == -1:
                continue
        key = (m.geom(mine).name, what)
        depth = -float(c.dist)
        if key not in best or depth > best[key]["depth"]:
            best[key] = {"part": key[0], "what": what, "depth": depth, "pos": np.array(c.pos)}
    return sorted(best.values(), key=lambda r: -r["depth"])


def _seen(view, eye: np.ndarray, p: np.ndarray, k: int) -> dict:
    """Whether the camera saw object ``k``'s surface near point ``p``."""
    pts = view.world()
    lab = view.labels
    mine = pts[lab == k] if lab is not None else pts[:0]
    near = float(np.min(np.linalg.norm(mine - p, axis=1))) if len(mine) else float("inf")
    u = (p - eye) / np.linalg.norm(p - eye)
    r = pts - eye
    rng = np.linalg.norm(r, axis=1)
    ang = np.degrees(np.arccos(np.clip((r @ u) / np.maximum(rng, 1e-9), -1, 1)))
    ray = ang < 0.25  # about two pixels of the D435-like camera
    out = {"nearest_seen_point_of_object_mm": round(1000 * near, 1)}
    if ray.any():
        j = np.flatnonzero(ray)[np.argmin(rng[ray])]
        out["behind_first_seen_surface_mm"] = round(1000 * (float(np.linalg.norm(p - eye)) - float(rng[j])), 1)
        out["first_surface_is"] = None if lab is None else int(lab[j])
    return out


def episode(k: int, i: int, stop_after: int | None, cfg: Config, db) -> list[dict]:
    from e10_clutter_removal import _clutter_config, looks
    from study_clutter_failures import outside_shares

    from graspsim.tabletop.clutter import benchmark_episode
    from graspsim.tabletop.clutter_stats import benchmark_seeds

    sd = benchmark_seeds(cfg.seed, cfg.seeds)[k]
    c = {"kind": cfg.kind, "noise": cfg.noise, "ablation": None}
    config = _clutter_config(c, None)
    config = replace(config, scene=replace(config.scene, workers=cfg.workers))
    ep = benchmark_episode(cfg.objects, cfg.kind, sd, i, db=db, config=config, object_set=cfg.object_set)
    scene = ep.scene
    eye = ep.camera.T_world_camera[:3, 3]
    names = [o.name for o in scene.objects]
    rows = []
    try:
        for look, g, sp, mem in looks(ep, stop_after):
            a = ep.execute(look, g)
            rows.append({"case": f"{k}:{i}", "grasp": len(ep.attempts) - 1, "cause": a.cause,
                         "target": None if a.target is None else names[a.target]})
            if not a.cause.startswith("start_collision"):
                continue
            o = a.outcome
            T = np.asarray(o.get("T_world_wrist", g.T_world_wrist), float)
            opening = float(o.get("opening", g.opening))
            pts = np.asarray(mem.points, float)
            ident = mem.ident
            sdf = np.abs(_parts_sdf(ident, pts)) if len(pts) else np.array([np.inf])
            hits = []
            for h in contacts(ep.sim, T, opening):
                if h["depth"] <= 0.0005:
                    continue
                p, w = h["pos"], h["what"]
                row = {"part": h["part"], "object": w if w == "table" else names[w],
                       "role": "table" if w == "table" else "target" if w == a.target else "neighbour",
                       "depth_mm": round(1000 * h["depth"], 1),
                       "in_fit_mm": round(1000 * float(_parts_sdf(ident, p[None])[0]), 1)}
                if w != "table":
                    cen = ep.sim.data.xipos[ep.sim.body[w]]
                    los = (cen - eye) / np.linalg.norm(cen - eye)
                    row["side_along_sight_mm"] = round(1000 * float((p - cen) @ los), 1)  # > 0: far side
                    row["pos_in_wrist_mm"] = [round(1000 * float(x), 1)
                                              for x in np.linalg.inv(T)[:3, :3] @ p + np.linalg.inv(T)[:3, 3]]
                    row.update(_seen(look.view, eye, p, w))
                    row["pose"] = _object_shape(ep.sim, w)
                hits.append(row)
            ax = T[:3, 0]
            rows[-1].update({"score": round(g.score, 3), "grade": round(g.grade, 3),
                             "clearance_mm": round(1000 * g.clearance, 1), "opening_mm": round(1000 * opening, 1),
                             "parts": [str(q.primitive()) for q in (ident.parts if ident else ())],
                             "segment_points": len(pts), "outside_3_6_10mm": outside_shares(pts, ident),
                             "fit_median_mm": round(1000 * float(np.median(sdf)), 2),
                             "approach_z": round(float(T[2, 2]), 2), "axis_z": round(float(ax[2]), 2),
                             "segment_status": sp.segments[g.segment].status, "hits": hits,
                             "target_pose": None if a.target is None else _object_shape(ep.sim, a.target)})
            log.info("%s", json.dumps(rows[-1]))
    finally:
        ep.close()
    return rows


def main(argv=None) -> int:
    from e10_clutter_removal import replay_cases

    cfg, out, record = start(Config, __file__, argv, __doc__)
    return replay_cases(cfg, out, record, lambda n, db: episode(n[0], n[1], n[2] if len(n) > 2 else None, cfg, db),
                        shown="hits")

if __name__ == "__main__":
    raise SystemExit(main())
