"""Occlusion study: how often a grasp whose fingers reach into unseen space starts in
collision, and the exponent of the robust score's occlusion term fitted to it.

A single depth view shows the faces turned to the camera; behind them, along the rays, is
unknown space. The robust score multiplies a grasp's expected success by (1 - f) ** k, f
the fraction of the finger volume in that unseen space (``RobustConfig.occlusion_power``
= k; :mod:`graspsim.maps.occlusion`). This study runs E10's conditions on the tuning
meshes only (``household-tuning``: the held-out third is never used to set anything),
5-object piles and packed scenes, no execution error, E10's seeds, camera, sensor noise
and database, with the occlusion term at ``--occlusion-power`` (1: the plain fraction,
the term before calibration). Of every executed grasp it records f -- measured on the
frame the grasp was planned from (the whole frame's points, seen from the camera; the
planner measures it against the segment and its neighbours' points) at the grasp's pose
and opening -- and whether the grasp started in collision (with its target, a neighbour
or both; the table has its own check), then fits k by maximum likelihood to P(no start
collision | f) = (1 - f) ** k, with a 95 % profile-likelihood interval.

    python experiments/study_occlusion.py --db results/e10-fsdb --publish
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import load_sentence, opt, resident_run_database, run_study, task_results

log = logging.getLogger("study_occlusion")

#: bands of the occluded finger fraction f for the table
BANDS = ((0.0, 0.0), (0.0, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 1.0))


@dataclass(frozen=True)
class Config:
    seeds: int = opt(5, "seeds: E10's first ones (derived from --seed as E10 derives them)")
    scenes: int = opt(4, "scenes per seed and kind")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    seed: int = opt(0, "E10's seed")
    object_sets: tuple[str, ...] = opt(("household-tuning",), "objects drawn from these sets (never a held-out set)")
    occlusion_power: float = opt(1.0, "the occlusion term's exponent while the scenes are cleared (1: the plain "
                                      "fraction)")
    db: str = opt("", "the FS map database (E10's --db; empty: E10's default folder)")
    workers: int = opt(1, "processes; results do not depend on it")

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.scenes < 1 or self.occlusion_power < 0 or self.workers < 1:
            raise ValueError("--seeds, --scenes and --workers >= 1, --occlusion-power >= 0")
        if not self.object_sets or any(o.endswith("heldout") for o in self.object_sets):
            raise ValueError("the exponent is fitted on tuning meshes only, never on a held-out set")


def attempts(task) -> list[dict]:
    """(f, cause, target name) of every grasp executed in scene ``i`` of seed index ``k``
    of ``kind`` scenes of ``object_set``."""
    object_set, kind, k, i, cfg, root = task
    import e10_clutter_removal as e10

    from graspsim.maps.occlusion import ViewDepth, finger_occlusion
    from graspsim.tabletop.clutter import benchmark_episode, grasp_target

    db = resident_run_database(root, e10.Config().quick_maps)
    # E10's seeds: derived from --seed as E10 derives its five (one seed would be --seed itself)
    e10cfg = e10.Config(seed=cfg.seed, seeds=max(cfg.seeds, e10.Config().seeds), scenes=cfg.scenes)
    clutter = e10._clutter_config({"kind": kind, "noise": "none", "ablation": None})
    planner = clutter.scene.planner
    clutter = replace(clutter, scene=replace(clutter.scene, planner=replace(
        planner, robust=replace(planner.robust, occlusion_power=cfg.occlusion_power))))
    out = []
    sd = e10.seed_of(e10cfg, k)
    ep = benchmark_episode(5, kind, sd, i, db=db, config=clutter, object_set=object_set)
    try:
        for look, g, _, _ in e10.looks(ep):
            eye = ep.camera.T_world_camera[:3, 3]
            T = np.asarray(g.T_world_wrist, float)
            f = float(finger_occlusion(ViewDepth(look.view.world(), eye), T[None, :3, :3], T[None, :3, 3],
                                       np.array([g.opening]), db.gripper)[0])
            target = grasp_target(look, g, db.gripper)
            a = ep.execute(look, g)
            name = None if target is None else ep.scene.objects[target].name
            out.append({"object_set": object_set, "kind": kind, "seed": sd, "scene": i, "f": f, "cause": a.cause,
                        "target": name, "score": a.score})
    finally:
        ep.close()
    return out


def fit_power(f: np.ndarray, collided: np.ndarray) -> tuple[float, float, float]:
    """Maximum-likelihood k of P(no collision | f) = (1 - f) ** k and its 95 % profile
    interval (log-likelihood within 1.92 of the maximum), on a grid of k in [0, 30]."""
    ks = np.linspace(0.0, 30.0, 3001)
    q = np.log1p(-np.clip(f, 0.0, 1.0 - 1e-9))  # log(1 - f) <= 0
    with np.errstate(divide="ignore"):
        ll = np.array([np.sum(np.log(-np.expm1(k * q[collided]))) + k * np.sum(q[~collided]) for k in ks])
    best = int(np.argmax(ll))
    inside = ks[ll >= ll[best] - 1.92]
    return float(ks[best]), float(inside.min()), float(inside.max())


def run(cfg: Config) -> dict:
    import e10_clutter_removal as e10

    root = cfg.db or str(Path(e10.__file__).resolve().parent.parent / "results" / "e10-fsdb")
    tasks = [(o, kind, k, i, cfg, root) for o in cfg.object_sets for kind in cfg.kinds for k in range(cfg.seeds)
             for i in range(cfg.scenes)]
    rows = []
    for j, got in enumerate(task_results(attempts, tasks, cfg.workers)):
        rows += got
        log.info("%d of %d scenes: %d grasps so far", j + 1, len(tasks), len(rows))
    f = np.array([r["f"] for r in rows])
    hit = np.array([r["cause"].startswith("start_collision") and r["cause"] != "start_collision_table"
                    for r in rows])
    k, lo, hi = fit_power(f, hit) if hit.any() and (~hit).any() else (float("nan"),) * 3
    bands = []
    for a, b in BANDS:
        m = (f == 0) if b == 0 else (f > a) & (f <= b)
        bands.append({"band": [a, b], "grasps": int(m.sum()), "start_collisions": int(hit[m].sum()),
                      "model_k1": float(np.mean(f[m])) if m.any() else None,  # 1 - (1 - f) ** 1
                      "model_fit": float(np.mean(1 - (1 - f[m]) ** k)) if m.any() and np.isfinite(k) else None})
    return {"attempts": rows, "bands": bands, "fit": {"k": k, "k_95": [lo, hi], "grasps": len(rows),
                                                     "start_collisions": int(hit.sum())}}


def readme_section(s: dict) -> str:
    c, fit = s["config"], s["fit"]
    sets = ", ".join(f'"{o}"' for o in c.get("object_sets", [c.get("object_set")]))  # one set before 2026-11-30
    L = [f"`{s['command']}`: E10's conditions on the tuning meshes ({sets}; the held-out third "
         f"not used), {', '.join(c['kinds'])} of 5 objects, no execution error, {c['seeds']} seeds x "
         f"{c['scenes']} scenes each, the occlusion term's exponent at {c['occlusion_power']:g} while the scenes "
         "were cleared. *f*: the fraction of the finger volume in space the camera did not see (behind the observed "
         "surfaces along the rays), at each executed grasp's pose and opening, measured on the frame it was "
         "planned from; *start collisions*: grasps that started in collision with their target, a neighbour or "
         "both; *(1 - f) ** k*: the chance of a start collision the occlusion term gives the band's grasps "
         "(mean), with k = 1 and with the fitted k.", "",
         "| f | grasps | start collisions | rate | k = 1 | fitted k |", "|---|---|---|---|---|---|"]
    for b in s["bands"]:
        a, z = b["band"]
        label = "0" if z == 0 else f"({a:g}, {z:g}]"
        n, h = b["grasps"], b["start_collisions"]
        rate = f"{100 * h / n:.0f} %" if n else "-"
        m1 = "-" if b["model_k1"] is None else f"{100 * b['model_k1']:.0f} %"
        mk = "-" if b["model_fit"] is None else f"{100 * b['model_fit']:.0f} %"
        L.append(f"| {label} | {n} | {h} | {rate} | {m1} | {mk} |")
    if fit["k"] is None:  # no start collision, or nothing else: nothing to fit
        L += ["", f"No exponent fitted: {fit['start_collisions']} start collisions in {fit['grasps']} grasps."]
    else:
        L += ["", f"Maximum-likelihood k of P(no start collision | f) = (1 - f) ** k: **{fit['k']:.1f}** (95 % "
              f"profile interval {fit['k_95'][0]:.1f} to {fit['k_95'][1]:.1f}) over {fit['grasps']} grasps, "
              f"{fit['start_collisions']} of them start collisions."]
    L += ["", load_sentence(s)]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    return run_study(Config, __file__, run, readme_section, argv, __doc__)


if __name__ == "__main__":
    raise SystemExit(main())
