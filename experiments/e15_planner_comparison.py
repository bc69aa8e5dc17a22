"""Experiment E15: graspsim's planner and a geometric baseline on the same clutter scenes.

Both planners clear the same table-top scenes (``graspsim scene``'s protocol,
:mod:`graspsim.tabletop.clutter`, written down in :mod:`graspsim.tabletop.clutter_stats`): one
D435-like depth camera with its noise, one grasp per step, what it lifted removed; an
episode ends when the table is clear, after two failed grasps in a row, when the planner
proposes nothing, or after 2 x objects + 2 grasps. A start pose in collision is a failed
grasp. ``graspsim`` is graspsim's scene planner (FS maps of the paper's primitives, the
robust score against the whole scene); ``antipodal`` is the baseline shipped in
:mod:`graspsim.tabletop.planners`, run through the planner interface a third-party planner
uses (``graspsim scene --planner antipodal``). Reported as the field does: GSR (grasps
that lifted their target / grasps) and DR (objects removed / placed) per seed, each seed
its own ``--scenes`` scenes (the same scenes for both planners), then mean ± std over seeds.
Objects from ``--object-set`` (by default the benchmark's: the shipped household meshes, as
``graspsim scene``); the database is E10's (its size grid of maps stored before the first
scene, read only during the run), so the planners meet what E10's planner meets.

    python experiments/e15_planner_comparison.py --seeds 5 --scenes 20 --workers 2 --publish
    python experiments/e15_planner_comparison.py --quick --out results/e15-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, database_record, experiment_database, map_config, md_table, opt, start, write_text
from _scenes import build_grid, resident_run_database

from graspsim.tabletop.clutter import ClutterConfig, run_benchmark, scene_settings, summarize
from graspsim.tabletop.clutter_stats import benchmark_seeds, per_seed
from graspsim.tabletop.mesh_objects import BENCHMARK_SET
from graspsim.tabletop.planners import BUILTIN, load_planner
from graspsim.tabletop.scene_objects import check_object_set, prepare_objects

log = logging.getLogger("e15")


@dataclass(frozen=True)
class Config:
    planners: tuple[str, ...] = opt(("graspsim", "antipodal"), "planners", choices=("graspsim", *BUILTIN))
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    objects: int = opt(5, "objects per scene")
    object_set: str = opt(BENCHMARK_SET, "objects drawn from this set (graspsim scene --object-set's names)")
    scenes: int = opt(4, "scenes per seed")
    seeds: int = opt(3, "seeds (derived from --seed)")
    seed: int = opt(0, "run seed")
    workers: int = opt(1, "processes, one seed of one planner and kind a task; results do not depend on it (the "
                          "database is read only during the run: maps of sizes it lacks are built in memory)")
    grid: bool = opt(True, "store E10's size grid of FS maps in the database before the first scene")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    QUICK: ClassVar[dict] = {"kinds": ("packed",), "objects": 2, "scenes": 1, "seeds": 2, "quick_maps": True,
                             "object_set": "primitives", "grid": False}

    def __post_init__(self) -> None:
        check_object_set(self.object_set)
        if self.workers < 1:
            raise ValueError("--workers must be >= 1")


def _seed(task) -> list:
    """One seed's ``--scenes`` episodes of one planner and kind, against the run's database
    (read only; this process's resident copy)."""
    kind, name, sd, cfg, root = task
    db = resident_run_database(root, cfg.quick_maps)
    planner = None if name == "graspsim" else load_planner(name)
    config = ClutterConfig(scene=scene_settings(kind), planner=planner, planner_name=name)
    return run_benchmark(cfg.objects, kind, cfg.scenes, sd, db=db, config=config, object_set=cfg.object_set)


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=NAMED, quiet=("graspsim.sim.batch",))
    db = experiment_database(cfg.db, out, map_config(cfg.quick_maps))
    empty = build_grid(db) if cfg.grid else []  # the maps the run plans from, before the first scene
    prepare_objects(cfg.object_set, db.gripper, progress=True)  # every mesh's convex parts, cached on disk
    start_db = {**database_record(db), "grid_without_grasps": empty}
    seeds = benchmark_seeds(cfg.seed, cfg.seeds)
    combos = [(kind, name) for kind in cfg.kinds for name in cfg.planners]
    tasks = [(kind, name, sd, cfg, str(db.root)) for kind, name in combos for sd in seeds]
    pool = get_context("spawn").Pool(cfg.workers) if cfg.workers > 1 else None
    results = []
    try:
        for (kind, name, sd, _, _), r in zip(tasks, pool.imap(_seed, tasks) if pool is not None else map(_seed, tasks)):
            results.append(r)
            log.info("%s, %s: seed %d done, %d of %d tasks, %d of its %d grasps lifted", kind, name, sd,
                     len(results), len(tasks), sum(a.success for x in r for a in x.attempts),
                     sum(len(x.attempts) for x in r))
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    rows = []
    for j, (kind, name) in enumerate(combos):
        by_seed = dict(zip(seeds, results[j * len(seeds):(j + 1) * len(seeds)]))
        pooled = summarize([r for rs in by_seed.values() for r in rs])
        rows.append({"kind": kind, "planner": name, **per_seed(by_seed),
                     "pooled": {k: pooled[k] for k in ("attempts", "successes", "placed", "removed",
                                                       "failure_causes", "stops", "per_source")},
                     "planning_median_s": pooled["planning_s"]["median"]})
    data = {"config": cfg, "gripper": db.gripper.name, "results": rows,
            "database": {"start": start_db, "end": database_record(db)}}
    md = run.write(out, data, readme_section)
    write_text(out / "summary.md", md)
    print(md)
    return 0


def headline(s: dict) -> str:
    """The README's E15 line (see ``experiments/report.py``): GSR and DR (mean over seeds) per
    scene kind, each planner's, on the same scenes."""
    c = s["config"]
    parts = []
    for kind in c["kinds"]:
        rows = [r for r in s["results"] if r["kind"] == kind]
        parts.append(f"{kind}: " + "; ".join(f"{r['planner']} GSR {r['gsr_text']}, DR {r['dr_text']}" for r in rows))
    return (f"The same scenes cleared by each planner ({c['seeds']} seeds x {c['scenes']} scenes of {c['objects']} "
            f"objects from the \"{c.get('object_set', 'mixed')}\" set; GSR and DR mean ± std over seeds): "
            + "; ".join(parts) + ".")


def readme_section(s: dict) -> str:
    """The README's E15 paragraph and table (see ``experiments/report.py``)."""
    c = s["config"]
    objects = c.get("object_set", "mixed")  # runs before the option drew from the "mixed" set
    L = [f"`{s['command']}` (gripper `{s['gripper']}`; {c['objects']} objects per scene from the \"{objects}\" "
         f"set, {c['scenes']} scenes per seed, {c['seeds']} seeds; the same scenes for every planner; no execution "
         "error; GSR = grasps that lifted their target / grasps, DR = objects removed / placed, per seed, then "
         "mean ± std over seeds):", ""]
    head = ["scenes", "planner", "GSR mean ± std", "DR mean ± std", "GSR per seed", "DR per seed",
            "grasps (lifted)", "failures", "planning per grasp (median)"]
    body = []
    for r in s["results"]:
        p = r["pooled"]
        per = r["per_seed"]
        fails = ", ".join(f"{k} {v}" for k, v in p["failure_causes"].items()) or "none"
        plan = "–" if r["planning_median_s"] is None else f"{r['planning_median_s']:.2f} s"
        body.append([r["kind"], r["planner"], r["gsr_text"], r["dr_text"],
                     " / ".join("–" if x["gsr"] is None else f"{100 * x['gsr']:.0f}" for x in per),
                     " / ".join(f"{100 * x['dr']:.0f}" for x in per), f"{p['attempts']} ({p['successes']})",
                     fails, plan])
    return "\n".join(L + [md_table(head, body), ""])


if __name__ == "__main__":
    raise SystemExit(main())
