"""Tolerance study: identification on a downsampled cloud (``IdentifyConfig.fit_points``)
against identification on every point (issue 17: planning a scene <= 0.5 s).

Robust identification fits at most ``fit_points`` points (default 1000; the cloud is
voxel-downsampled first); ``fit_points=None`` fits every point (up to ``max_points``),
as before. For each cloud this script identifies:

* **all**: every point (``fit_points=None``), draws from ``rng_for(seed, "first", cloud)``;
* **all, reseeded**: the same with another stream, ``rng_for(seed, "second", cloud)`` -- how much
  identification changes with its own random draws alone (the reference: MLESAC draws
  few hypotheses, so part kinds differ between seeds on some clouds);
* **bounded** at each ``--limits`` value, drawing from the first stream.

and counts the clouds whose outcome agrees with **all**: the same status and part kinds
(as a multiset); and also every part's dimensions within ``--dims-mm``; and also every
part's fit rate within ``--rate-tol``. The clouds: the segments of the first frame of
``--scenes`` 5-object pile and packed scenes (E10's camera, sensor noise and scene
perception; segments are 3 mm voxel grids), and E09's full and single-view clouds of
every mesh in ``--objects-dir`` (bench_identify's objects; '' skips them). CPU seconds
of identification per condition, summed over the clouds.

    python experiments/study_fit_points.py --objects-dir ../shared/objects
    python experiments/study_fit_points.py --quick --out results/study_fit_points-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import derived_seed, load_sentence, opt, rng_for, run_study

log = logging.getLogger("study_fit_points")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(6, "5-object scenes of each kind (pile, packed) whose first frame's segments are used")
    objects_dir: str = opt("../shared/objects", "E09's meshes ('' : scene segments only)")
    limits: tuple[int, ...] = opt((1000, 600), "fit_points values compared with every point")
    seed: int = opt(17, "run seed")
    dims_mm: float = opt(5.0, "dimension tolerance [mm]")
    rate_tol: float = opt(0.05, "fit rate tolerance")
    QUICK: ClassVar[dict] = {"scenes": 1, "objects_dir": "", "limits": (600,)}

    def __post_init__(self) -> None:
        if self.scenes < 0 or not self.limits or min(self.limits) < 300 or self.dims_mm <= 0 or self.rate_tol <= 0:
            raise ValueError("--scenes >= 0, --limits >= 300 and positive tolerances are needed")


def scene_segments(cfg: Config) -> dict[str, np.ndarray]:
    """The segments (M, 3) [m] of each scene's first frame, as E10 perceives them."""
    from graspsim.geometry.camera import backproject, rig
    from graspsim.planning.scene import perceive_scene
    from graspsim.tabletop.clutter import ClutterConfig
    from graspsim.tabletop.table_scene import make_scene

    clutter, out = ClutterConfig(), {}
    for kind in ("pile", "packed"):
        for i in range(cfg.scenes):
            seed = derived_seed(cfg.seed, kind, i)
            sim = make_scene(5, kind, seed).sim()
            frame = sim.render(rig(1)[0], noise=clutter.depth_noise, rng=rng_for(seed, "depth"))
            sim.close()
            per = perceive_scene(backproject(frame).world(), rng_for(seed, "table"), clutter.scene)
            out.update({f"{kind}{i}/segment{k}": per.segment_points(k) for k in range(per.n_segments)})
    return out


def object_clouds(cfg: Config) -> dict[str, np.ndarray]:
    """E09's full and single-view clouds of every mesh (bench_identify's clouds)."""
    if not cfg.objects_dir:
        return {}
    from e09_everyday_objects import Config as E09Config
    from e09_everyday_objects import object_names, object_views

    e09 = E09Config(objects_dir=cfg.objects_dir)
    out = {}
    for name in object_names(e09):
        cl = object_views(name, e09)[3]
        out.update({f"{Path(name).stem}/{view}": cl[view] for view in ("full", "single")})
    return out


def outcome(points: np.ndarray, rng: np.random.Generator, config) -> dict:
    """What identification made of ``points``: status, parts (kind, dims [m], fit rate), CPU [s]."""
    from graspsim.errors import GraspsimError
    from graspsim.perception.identify import identify

    c0 = time.process_time()
    try:
        r = identify(points, rng=rng, config=config)
    except GraspsimError as err:
        return {"status": f"error: {type(err).__name__}", "parts": [], "cpu": time.process_time() - c0}
    parts = sorted(([p.shape.value, sorted(float(v) for v in p.dims.values()), float(p.fit_rate)] for p in r.parts),
                   key=lambda p: (p[0], p[1]))
    return {"status": r.status.value, "parts": parts, "left": len(r.unidentified), "points": len(points),
            "used": len(points) if r.downsampling is None else r.downsampling.used_points,
            "cpu": time.process_time() - c0}


def agreement(a: dict, b: dict, cfg: Config) -> tuple[bool, bool, bool]:
    """(same status and part kinds, and dims within tolerance, and fit rates within tolerance)."""
    kinds = a["status"] == b["status"] and [p[0] for p in a["parts"]] == [p[0] for p in b["parts"]]
    dims = kinds and all(np.max(np.abs(np.subtract(p[1], q[1])), initial=0.0) <= cfg.dims_mm / 1000.0
                         for p, q in zip(a["parts"], b["parts"]))
    rates = dims and all(abs(p[2] - q[2]) <= cfg.rate_tol for p, q in zip(a["parts"], b["parts"]))
    return kinds, dims, rates


def _changed(res: dict, cond: str, clouds: dict, cfg: Config) -> dict:
    """Agreement on the clouds a bound thins (more points than it; the others are
    identified on the same points from the same stream): the bounded condition's, and
    the reseeded one's on the same clouds."""
    if not cond.startswith("fit_points="):
        return {}
    limit = int(cond.split("=")[1])
    sub = [k for k, p in clouds.items() if len(p) > limit]
    mine = [agreement(res["all"][k], res[cond][k], cfg) for k in sub]
    ref = [agreement(res["all"][k], res["all, reseeded"][k], cfg) for k in sub]
    return {"thinned": len(sub), "thinned_kinds": sum(a[0] for a in mine), "thinned_dims": sum(a[1] for a in mine),
            "reseeded_kinds": sum(a[0] for a in ref), "reseeded_dims": sum(a[1] for a in ref)}


def run(cfg: Config) -> dict:
    from graspsim.perception.identify_config import IdentifyConfig

    groups = {"scene segments": scene_segments(cfg), "E09 clouds": object_clouds(cfg)}
    conds = {"all": (IdentifyConfig(fit_points=None), "first"),
             "all, reseeded": (IdentifyConfig(fit_points=None), "second"),
             **{f"fit_points={n}": (IdentifyConfig(fit_points=n), "first") for n in cfg.limits}}
    rows, table = [], []
    for group, clouds in groups.items():
        if not clouds:
            continue
        res = {c: {k: outcome(p, rng_for(cfg.seed, s, k), ic) for k, p in clouds.items()}
               for c, (ic, s) in conds.items()}
        for c in conds:
            agree = [agreement(res["all"][k], res[c][k], cfg) for k in clouds]
            table.append({"clouds": group, "condition": c, "n": len(clouds),
                          "kinds": sum(a[0] for a in agree), "dims": sum(a[1] for a in agree),
                          "rates": sum(a[2] for a in agree),
                          "cpu_s": float(sum(r["cpu"] for r in res[c].values())),
                          "median_points": float(np.median([r.get("used", 0) for r in res[c].values()])),
                          **_changed(res, c, clouds, cfg)})
            log.info("%-15s %-16s kinds %d/%d dims %d rates %d cpu %.2f s", group, c, table[-1]["kinds"],
                     len(clouds), table[-1]["dims"], table[-1]["rates"], table[-1]["cpu_s"])
        rows += [{"cloud": k, "group": group, **{c: res[c][k] for c in conds}} for k in clouds]
    return {"table": table, "clouds": rows,
            "denominators": "clouds: the segments of the scenes' first frames; E09's meshes x (full, single)"}


def readme_section(s: dict) -> str:
    """The study's table: agreement with identification on every point, and CPU."""
    L = [f"`{s['command']}`: clouds whose identification agrees with the one on every point (same status and "
         f"part kinds; and dimensions within {s['config']['dims_mm']:g} mm; and fit rates within "
         f"{s['config']['rate_tol']:g}); the reseeded row is identification's own spread.", "",
         "| clouds | condition | kinds | + dims | + fit rates | points used (median) | CPU [s] |",
         "|---|---|---|---|---|---|---|"]
    for t in s["table"]:
        L.append(f"| {t['clouds']} | {t['condition']} | {t['kinds']}/{t['n']} | {t['dims']}/{t['n']} | "
                 f"{t['rates']}/{t['n']} | {t['median_points']:.0f} | {t['cpu_s']:.2f} |")
    L += ["", "On the clouds a bound thins (more points than the bound), same status and kinds / and dimensions, "
          "bounded against every point, beside the reseeded identification on the same clouds:", "",
          "| clouds | condition | thinned | bounded kinds / + dims | reseeded kinds / + dims |",
          "|---|---|---|---|---|"]
    for t in s["table"]:
        if "thinned" in t:
            n = t["thinned"]
            L.append(f"| {t['clouds']} | {t['condition']} | {n} | {t['thinned_kinds']}/{n} / {t['thinned_dims']}/{n} | "
                     f"{t['reseeded_kinds']}/{n} / {t['reseeded_dims']}/{n} |")
    L += ["", load_sentence(s)]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    return run_study(Config, __file__, run, readme_section, argv, __doc__)


if __name__ == "__main__":
    raise SystemExit(main())
