"""Identification stability study: do a cloud's map and grasps survive perturbations far
below the sensor's noise?

Identification is a randomised search (MLESAC samples, thresholds, splits) over a
discrete space of decompositions, so a cloud near a decision's edge can come out as
another decomposition when its points move by micrometres -- and with it the map, down
to no accepted grasp at all (E09 at ``0a08889``: the duck's and random_017's full
clouds, whose resting pose moved by micrometres when the contacts changed). This study
measures how often that happens. E09's clouds of every mesh in ``--objects-dir`` (the
same resting pose, yaw, sensor noise and camera, from E09's seed) are adapted in robust
mode through the public path (:func:`graspsim.planning.adapt.adapt_cloud`, ``graspsim
adapt CLOUD --table auto [--viewpoint X Y Z]``), once as E09 draws them and
``--jitters`` more times with every point moved by a further Gaussian of
``--jitter-um`` micrometres (sigma per axis; the sensor's is 1 mm). Per cloud: how many
of the variants give a usable map (at least one accepted grasp), how many distinct
decompositions (the multiset of primitive kinds) they come out as, and the median
number of accepted grasps. The held-out third (E09's rule) is reported apart.
``--restarts`` sets ``graspsim adapt --restarts`` (``PlannerConfig.restarts``: a cloud whose
map holds no accepted grasp is identified again); ``--restarts 0`` measures the
identification alone.

    python experiments/study_identification_stability.py --publish
    python experiments/study_identification_stability.py --restarts 0 --publish
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import database_note, database_record, experiment_database, load_sentence, map_config, opt, run_study

log = logging.getLogger("study_identification_stability")


@dataclass(frozen=True)
class Config:
    objects_dir: str = opt("../shared/objects", "folder of .stl meshes [m] (E09's)")
    objects: tuple[str, ...] = opt((), "meshes to use, relative to --objects-dir (default: every .stl in it)")
    views: tuple[str, ...] = opt(("full", "single"), "E09's clouds to perturb", choices=("full", "single"))
    jitters: int = opt(7, "perturbed variants per cloud, besides the cloud itself")
    jitter_um: float = opt(3.0, "sigma of the perturbation per axis [micrometres]")
    seed: int = opt(9, "E09's run seed (its clouds and the planner's seed)")
    restarts: int | None = opt(None, "graspsim adapt --restarts: identifications more when a map holds no accepted "
                               "grasp (PlannerConfig.restarts; default: the planner's)")
    db: str = opt("results/e09-fsdb", "FS database folder (made and filled with the paper's shapes if missing; "
                  "parts out of every stored map's range are built into it)")

    def __post_init__(self) -> None:
        if self.jitters < 1 or not self.jitter_um > 0:
            raise ValueError("--jitters >= 1 and --jitter-um > 0")


def _decomposition(res) -> str:
    return "+".join(sorted(p.shape.value for p in res.identification.parts)) or "-"


def run(cfg: Config) -> dict:
    import e09_everyday_objects as e09

    from graspsim.planning.adapt import adapt_cloud, adapt_config
    from graspsim.seeding import rng_for

    e09cfg = e09.Config(objects_dir=cfg.objects_dir, objects=cfg.objects, seed=cfg.seed)
    db = experiment_database(cfg.db, None, map_config(False))
    start = database_record(db)
    rows = []
    for name in e09.object_names(e09cfg):
        _, _, _, cl = e09.object_views(name, e09cfg)
        for view in cfg.views:
            pts = cl[view]
            viewpoint = cl["camera"] if view == "single" else None
            rng = rng_for(cfg.seed, "jitter", name, view)
            variants = []
            for k in range(cfg.jitters + 1):
                p = pts if k == 0 else pts + rng.normal(0.0, cfg.jitter_um * 1e-6, pts.shape)
                t0 = time.perf_counter()
                res = adapt_cloud(p, db=db, config=adapt_config(mode="robust", table="auto", restarts=cfg.restarts),
                                  seed=cfg.seed, viewpoint=viewpoint)
                ident = res.map.meta.extra.get("identification") or {}
                variants.append({"status": res.status.value, "parts": _decomposition(res),
                                 "accepted": int(res.map.accepted.sum()) if len(res.map) else 0,
                                 "attempts": int(ident.get("attempts", 1)) if len(res.map) else None,
                                 "seconds": time.perf_counter() - t0})
            usable = sum(v["accepted"] > 0 for v in variants)
            rows.append({"object": name, "view": view, "held_out": e09.held_out(name), "variants": variants,
                         "restarted": sum((v["attempts"] or 0) > 1 for v in variants),
                         "usable": usable, "distinct": len({v["parts"] for v in variants}),
                         "median_accepted": float(np.median([v["accepted"] for v in variants]))})
            log.info("%-26s %-6s usable %d/%d, %d decompositions", name, view, usable, len(variants),
                     rows[-1]["distinct"])
    return {"rows": rows, "pooled": _pooled(rows), "database": {"start": start, "end": database_record(db)}}


def _pooled(rows: list[dict]) -> dict:
    out = {}
    for split in ("development", "held_out"):
        for view in ("full", "single"):
            sel = [r for r in rows if r["view"] == view and r["held_out"] == (split == "held_out")]
            if not sel:
                continue
            n = sum(len(r["variants"]) for r in sel)
            secs = [v["seconds"] for r in sel for v in r["variants"]]
            out[f"{split}/{view}"] = {
                "clouds": len(sel), "variants": n, "usable": sum(r["usable"] for r in sel),
                "restarted": sum(r["restarted"] for r in sel), "median_s": float(np.median(secs)),
                "max_s": float(np.max(secs)),
                "always_usable": sum(r["usable"] == len(r["variants"]) for r in sel),
                "never_usable": sum(r["usable"] == 0 for r in sel),
                "one_decomposition": sum(r["distinct"] == 1 for r in sel),
                "unstable": sorted(r["object"] for r in sel if 0 < r["usable"] < len(r["variants"]))}
    return out


def readme_section(s: dict) -> str:
    c = s["config"]
    L = [f"`{s['command']}`: E09's clouds (seed {c['seed']}: the resting pose, yaw, 1 mm sensor noise and camera) "
         f"of every mesh, {', '.join(c['views'])}, each adapted in robust mode as E09 adapts it (`graspsim adapt "
         f"CLOUD --table auto`, single views with their viewpoint) once as drawn and {c['jitters']} more times "
         f"with every point moved by a further Gaussian of {c['jitter_um']:g} µm per axis"
         + (f", `--restarts {c['restarts']}`" if c.get("restarts") is not None else ", the planner's default "
            "restarts") + ". *usable*: variants with at least one accepted grasp; *always* / *never*: clouds whose "
         "every / no variant is usable; *one decomposition*: clouds whose variants all come out as the same primitive "
         "kinds; *identified again*: variants whose first identification's map held no accepted grasp "
         "(`PlannerConfig.restarts`); seconds: `adapt_cloud`'s wall time per variant, median and most.", "",
         "| meshes | view | clouds | usable variants | always usable | never usable | one decomposition | "
         "usable only sometimes | identified again | seconds |", "|---|---|---|---|---|---|---|---|---|---|"]
    for key, p in s["pooled"].items():
        split, view = key.split("/")
        L.append(f"| {split.replace('_', '-')} | {view} | {p['clouds']} | {p['usable']}/{p['variants']} | "
                 f"{p['always_usable']} | {p['never_usable']} | {p['one_decomposition']} | "
                 f"{', '.join(Path(o).stem for o in p['unstable']) or '-'} | {p['restarted']} | "
                 f"{p['median_s']:.2f} / {p['max_s']:.1f} |")
    L += ["", load_sentence(s) + database_note(s)]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    return run_study(Config, __file__, run, readme_section, argv, __doc__)


if __name__ == "__main__":
    raise SystemExit(main())
