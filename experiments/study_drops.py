"""Diagnosis of grasps that close on their object and then lose it (``dropped`` / ``slipped``).

Replays E10's episodes (``graspsim.tabletop.clutter.ClutterEpisode`` with E10's settings:
the same scenes, seeds, camera, sensor noise and database; seed index ``k``'s scene ``i``
as ``e10_clutter_removal.py --seeds K`` draws it) and, for every executed grasp whose cause
is one of ``--causes``, simulates that grasp again from the state it started in, step by
step (MuJoCo's Python stepping: the same model, controls and initial state as the rollout,
so the same trajectory), and records from the simulation:

* where each pad touches the object at the end of the close (force-weighted contact point),
  the normal force per pad, the angle between each pad's contact normal and the closing
  axis (the friction cone's half angle is atan(mu)), the pads' sliding / torsional friction;
* the object's mass, the horizontal offset of its true centre of mass from the pads'
  contact line (gravity's torque about that line, which only the pads' torsional friction
  and the contact patch's extent resist), the same for the segment's centroid (what the
  planner could know), and the torque ratio m g d / (2 mu_t N);
* when the pads lost the object (phase and time), how far it had turned about the closing
  axis and slid in the hand by then;
* what the planner scored it (robust score, grade, clearance) and, of the other
  candidates of that look, how many ranked above / how many within 0.05 of its score and
  their contact lines' distances to the segment centroid.

``--impratio 10`` replays runs made before ``SimSettings.impratio`` became 100 (their
episodes reproduce exactly); ``--scene-impratio`` draws and settles the scenes at another
setting than the grasps are simulated at (the same scenes, only the grasps' physics
changed); ``--causes none`` records each grasp's cause without replaying any.

    python experiments/study_drops.py --kind pile --seeds 5 --cases 4:14 0:14 --impratio 10 --db /work/runs/e10-fsdb
    python experiments/study_drops.py --kind pile --seeds 4 --cases 0:0 0:1 --scene-impratio 10 --causes none
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

log = logging.getLogger("study_drops")
G = 9.81


@dataclass(frozen=True)
class Config(E10Cases):
    cases: tuple[str, ...] = opt(("0:14",), "cases SEED_INDEX:SCENE (scene index within its seed)")
    causes: tuple[str, ...] = opt(("dropped", "slipped"), "causes replayed in detail (none: no replay, each "
                                                          "grasp's cause recorded)")
    impratio: float | None = opt(None, "the episodes' MuJoCo impratio, scene settling included (None: SimSettings' "
                                 "default; 10 replays runs made before it became 100)")
    scene_impratio: float | None = opt(None, "the impratio the scenes are drawn and settled with (None: "
                                       "--impratio's): the same scenes as a run made at another setting, only "
                                       "the grasps' physics changed")
    variants: tuple[str, ...] = opt(("noslip10", "impratio100", "timestep_0.5ms"),
                                    "simulation variants each replayed grasp is simulated again under")
    QUICK: ClassVar[dict] = {"kind": "packed", "objects": 2, "seeds": 1, "cases": ("0:0",), "object_set": "primitives",
                             "quick_maps": True, "causes": ("success", "dropped", "slipped", "no_contact"),
                             "variants": ("impratio100",)}


def _line_distance(p: np.ndarray, a: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Distance of point ``p`` from the line through ``a`` along unit ``u``, horizontal part
    (gravity's lever) and full."""
    r = p - a
    perp = r - (r @ u) * u
    return perp


# simulation variants the same grasp is replayed under (is the simulation at fault?)
VARIANTS = {"noslip10": {"noslip_iterations": 10}, "impratio100": {"impratio": 100.0},
            "timestep_0.5ms": {"timestep": 0.0005}}


def pad_contacts(sim, d, target: int) -> dict:
    """Per pad ("neg", "pos"): force-weighted point, unit normal (pointing into the pad's side
    from the object), normal force [N], tangential force [N], count, at data ``d``."""
    m = sim.model
    out = {}
    pads = {s: m.geom(f"finger_{s}").id for s in ("neg", "pos")}
    f6 = np.zeros(6)
    for side, gid in pads.items():
        pts, nrm, fn, ft = [], [], [], []
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if gid not in (g1, g2):
                continue
            other = g2 if g1 == gid else g1
            if sim.geom_object[other] != target:
                continue
            mujoco.mj_contactForce(m, d, i, f6)
            n = np.array(c.frame[:3])  # from geom1 to geom2
            if g1 == gid:
                n = -n  # from the object to the pad
            pts.append(np.array(c.pos))
            nrm.append(n)
            fn.append(f6[0])
            ft.append(float(np.hypot(f6[1], f6[2])))
        if pts:
            w = np.maximum(np.array(fn), 1e-9)
            nv = (np.array(nrm) * w[:, None]).sum(0)
            out[side] = {"point": (np.array(pts) * w[:, None]).sum(0) / w.sum(), "normal": nv / np.linalg.norm(nv),
                         "fn": float(np.sum(fn)), "ft": float(np.sum(ft)), "n": len(pts),
                         "spread": float(np.ptp(np.array(pts), axis=0).max()) if len(pts) > 1 else 0.0}
    return out


def replay(sim, state_pre: np.ndarray, T: np.ndarray, opening: float, target: int, seg_centroid,
           variants=tuple(VARIANTS)) -> dict:
    """Simulate the grasp again from ``state_pre`` (the scene before it), step by step."""
    from graspsim.sim.protocols import LiftPlace  # noqa: F401  (the scene's protocol)
    from graspsim.transforms import quat_to_matrix

    m, p = sim.model, sim.protocol
    d = sim.data
    whole = mujoco.mjtState.mjSTATE_INTEGRATION  # warm start included: the episode goes on exactly as without
    keep = np.empty(mujoco.mj_stateSize(m, whole))
    mujoco.mj_getState(m, d, keep, whole)
    mujoco.mj_setState(m, d, state_pre, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(m, d)
    state0 = sim._start_state(T, opening)
    mujoco.mj_setState(m, d, keep, whole)
    ph = p.steps(m.opt.timestep)
    c1, l1, h1 = ph["close"][1], ph["lift"][1], ph["hold"][1]
    control = p.controls(sim, T[None], np.array([opening]))[0, :h1 + 1]
    dd = mujoco.MjData(m)
    mujoco.mj_setState(m, dd, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    dd.qacc_warmstart[:] = 0.0
    body = sim.body[target]
    x_axis = T[:3, 0]
    mass = float(m.body_mass[body])
    rec = {"mass_kg": mass}
    rel0 = None
    lost = None
    traj = []
    for k in range(h1 + 1):
        mujoco.mj_setState(m, dd, control[k], p.control_spec)
        mujoco.mj_step(m, dd)
        pc = pad_contacts(sim, dd, target)
        wrist_R = quat_to_matrix(dd.qpos[sim.qadr_wrist + 3:sim.qadr_wrist + 7])
        wrist_p = dd.qpos[sim.qadr_wrist:sim.qadr_wrist + 3].copy()
        obj_R = dd.xmat[body].reshape(3, 3).copy()
        rel = wrist_R.T @ obj_R
        if k == c1:
            rel0, p0 = rel, wrist_R.T @ (dd.xipos[body] - wrist_p)
            com = dd.xipos[body].copy()
            rec["close"] = _at_close(pc, com, x_axis, mass, seg_centroid, sim)
        if k > c1 and rel0 is not None:
            dR = rel @ rel0.T
            ang = math.degrees(math.acos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
            pk = wrist_R.T @ (dd.xipos[body] - wrist_p)
            if k % 25 == 0:
                traj.append({"t": round(float(dd.time), 3), "turn_deg": round(ang, 1),
                             "slide_mm": round(1000 * float(np.linalg.norm(pk - p0)), 1),
                             "pads": {s: round(v["fn"], 1) for s, v in pc.items()}})
            if lost is None and len(pc) < 2:
                phase = "lift" if k <= l1 else "hold"
                lost = {"step": k, "phase": phase, "t_after_close": round((k - c1) * m.opt.timestep, 3),
                        "turn_deg": round(ang, 1), "slide_mm": round(1000 * float(np.linalg.norm(pk - p0)), 1),
                        "pads_left": sorted(pc)}
    rec["lost"] = lost
    rec["traj"] = traj
    rec["variants"] = {name: _held_with(sim, state0, control, target, h1, VARIANTS[name]) for name in variants}
    return rec


def _held_with(sim, state0, control, target, h1, opts) -> dict:
    """Whether both pads still touch ``target`` after the hold, with MuJoCo options ``opts``
    changed for this replay only (a finer timestep runs proportionally more steps)."""
    m = sim.model
    old = {k: getattr(m.opt, k) for k in opts}
    try:
        for k, v in opts.items():
            setattr(m.opt, k, v)
        sub = max(1, round(old.get("timestep", m.opt.timestep) / m.opt.timestep))
        dd = mujoco.MjData(m)
        mujoco.mj_setState(m, dd, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        z0 = float(dd.qpos[sim.qadr[target] + 2])
        for k in range(h1 + 1):
            mujoco.mj_setState(m, dd, control[k], sim.protocol.control_spec)
            for _ in range(sub):
                mujoco.mj_step(m, dd)
        pc = pad_contacts(sim, dd, target)
        return {"held": len(pc) == 2, "rise_mm": round(1000 * (float(dd.qpos[sim.qadr[target] + 2]) - z0), 1)}
    finally:
        for k, v in old.items():
            setattr(m.opt, k, v)


def _at_close(pc: dict, com: np.ndarray, x_axis: np.ndarray, mass: float, seg_centroid, sim) -> dict:
    s = sim.settings
    out = {"pads": {k: {"fn_N": round(v["fn"], 1), "ft_N": round(v["ft"], 1), "n": v["n"],
                        "spread_mm": round(1000 * v["spread"], 1),
                        "normal_vs_axis_deg": round(math.degrees(math.acos(min(1.0, abs(float(v["normal"] @ x_axis))))),
                                                    1)}
                    for k, v in pc.items()},
           "friction_cone_deg": round(math.degrees(math.atan(s.friction)), 1)}
    if len(pc) == 2:
        a, b = pc["neg"]["point"], pc["pos"]["point"]
        u = (b - a) / max(np.linalg.norm(b - a), 1e-9)
        mid = 0.5 * (a + b)
        perp = _line_distance(com, mid, u)
        horiz = perp - (perp @ np.array([0, 0, 1.0])) * np.array([0, 0, 1.0])
        fn = min(pc["neg"]["fn"], pc["pos"]["fn"])
        tau_g = mass * G * float(np.linalg.norm(np.cross(u, np.cross(perp, np.array([0, 0, 1.0]))) @ u * u)) if False \
            else mass * G * float(abs(np.cross(perp, np.array([0, 0, -1.0])) @ u))
        tau_f = 2 * s.torsional_friction * fn
        out.update({"contact_line_tilt_deg": round(math.degrees(math.acos(min(1.0, abs(float(u @ x_axis))))), 1),
                    "com_from_line_mm": round(1000 * float(np.linalg.norm(perp)), 1),
                    "com_from_line_horizontal_mm": round(1000 * float(np.linalg.norm(horiz)), 1),
                    "com_along_line_from_mid_mm": round(1000 * float((com - mid) @ u), 1),
                    "gravity_torque_Nm": round(tau_g, 4), "torsional_capacity_Nm": round(tau_f, 4),
                    "torque_ratio": round(tau_g / max(tau_f, 1e-9), 3)})
        if seg_centroid is not None:
            sp = _line_distance(seg_centroid, mid, u)
            out["centroid_from_line_mm"] = round(1000 * float(np.linalg.norm(sp)), 1)
            out["centroid_vs_com_mm"] = round(1000 * float(np.linalg.norm(seg_centroid - com)), 1)
    return out


def _line_of(g, gripper) -> tuple[np.ndarray, np.ndarray]:
    """A grasp's nominal contact point (the TCP) and closing axis in the world."""
    T = np.asarray(g.T_world_wrist, float)
    return T[:3, :3] @ gripper.nominal_tcp + T[:3, 3], T[:3, 0]


def episode(k: int, i: int, cfg: Config, db) -> list[dict]:
    from e10_clutter_removal import _clutter_config, looks

    from graspsim.sim import SimSettings
    from graspsim.tabletop.clutter import benchmark_episode
    from graspsim.tabletop.clutter_stats import benchmark_seeds
    from graspsim.tabletop.planners import grasp_target

    sd = benchmark_seeds(cfg.seed, cfg.seeds)[k]
    c = {"kind": cfg.kind, "noise": cfg.noise, "ablation": None}
    settings = SimSettings() if cfg.impratio is None else SimSettings(impratio=cfg.impratio)
    drawn = settings if cfg.scene_impratio is None else SimSettings(impratio=cfg.scene_impratio)
    # the scene drawn and settled at `drawn`; the grasps simulated at `settings`
    ep = benchmark_episode(cfg.objects, cfg.kind, sd, i, db=db, config=replace(_clutter_config(c, None), sim=drawn),
                           object_set=cfg.object_set)
    if settings != drawn:
        ep.sim.close()
        ep.sim = ep.scene.sim(gripper=db.gripper, settings=settings)
    scene = ep.scene
    rows = []
    try:
        for look, g, _, mem in looks(ep):
            pre = np.empty(ep.sim.nstate)
            mujoco.mj_getState(ep.sim.model, ep.sim.data, pre, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            cen = np.asarray(mem.points, float).mean(0) if len(mem.points) else None
            target = grasp_target(look, g, db.gripper)
            det = None
            replaying = target is not None and set(cfg.causes) != {"none"}
            if cfg.noise == "none" and replaying:  # the pose executed is the planned one: replay it
                det = replay(ep.sim, pre, np.asarray(g.T_world_wrist, float), float(g.opening), target, cen,
                             cfg.variants)  # before a picked object leaves the scene
            a = ep.execute(look, g)
            if a.cause not in cfg.causes or a.target is None:
                rows.append({"case": f"{k}:{i}", "cause": a.cause,
                             "object": None if a.target is None else scene.objects[a.target].name})
                continue
            o = a.outcome
            if det is None:  # with execution error: the pose the arm missed by; a failure leaves the object in
                det = replay(ep.sim, pre, np.asarray(o["T_world_wrist"], float), float(o["opening"]), a.target, cen,
                             cfg.variants)
            tcp, ax = _line_of(g, db.gripper)
            alts = []
            for h in look.candidates[:20]:
                if h.segment != g.segment:
                    continue
                t2, a2 = _line_of(h, db.gripper)
                alts.append({"score": round(h.score, 3), "grade": round(h.grade, 3),
                             "centroid_from_line_mm": None if cen is None else
                             round(1000 * float(np.linalg.norm(_line_distance(cen, t2, a2))), 1),
                             "chosen": h is g})
            row = {"case": f"{k}:{i}", "object": scene.objects[a.target].name, "cause": a.cause,
                   "score": round(g.score, 3), "grade": round(g.grade, 3), "clearance_mm": round(1000 * g.clearance, 1),
                   "parts": [str(q.primitive()) for q in (mem.ident.parts if mem.ident else ())],
                   "tcp_from_centroid_line_mm": None if cen is None else
                   round(1000 * float(np.linalg.norm(_line_distance(cen, tcp, ax))), 1),
                   "approach_z": round(float(np.asarray(g.T_world_wrist)[2, 2]), 2),
                   "axis_z": round(float(ax[2]), 2), "replay": det, "same_segment_candidates": alts}
            rows.append(row)
            log.info("%s", json.dumps(row))
    finally:
        ep.close()
    return rows


def main(argv=None) -> int:
    from e10_clutter_removal import replay_cases

    cfg, out, record = start(Config, __file__, argv, __doc__)
    return replay_cases(cfg, out, record, lambda n, db: episode(n[0], n[1], cfg, db), shown="replay")

if __name__ == "__main__":
    raise SystemExit(main())
