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

    python experiments/e15_planner_comparison.py --publish
    python experiments/e15_planner_comparison.py --quick --out results/e15-quick
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, database_record, experiment_database, map_config, md_table, opt, start, write_text

from graspsim.tabletop.clutter import ClutterConfig, run_benchmark, scene_settings, summarize
from graspsim.tabletop.clutter_stats import benchmark_seeds, per_seed
from graspsim.tabletop.planners import BUILTIN, load_planner

log = logging.getLogger("e15")


@dataclass(frozen=True)
class Config:
    planners: tuple[str, ...] = opt(("graspsim", "antipodal"), "planners", choices=("graspsim", *BUILTIN))
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    objects: int = opt(5, "objects per scene")
    scenes: int = opt(4, "scenes per seed")
    seeds: int = opt(3, "seeds (derived from --seed)")
    seed: int = opt(0, "run seed")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    QUICK: ClassVar[dict] = {"kinds": ("packed",), "objects": 2, "scenes": 1, "seeds": 2, "quick_maps": True}


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=NAMED, quiet=("graspsim.sim.batch",))
    db = experiment_database(cfg.db, out, map_config(cfg.quick_maps))
    start_db = database_record(db)
    rows = []
    for kind in cfg.kinds:
        for name in cfg.planners:
            planner = None if name == "graspsim" else load_planner(name)
            config = ClutterConfig(scene=scene_settings(kind), planner=planner, planner_name=name)
            by_seed = {}
            for sd in benchmark_seeds(cfg.seed, cfg.seeds):
                log.info("%s, %s: seed %d", kind, name, sd)
                by_seed[sd] = run_benchmark(cfg.objects, kind, cfg.scenes, sd, db=db, config=config)
            pooled = summarize([r for rs in by_seed.values() for r in rs])
            rows.append({"kind": kind, "planner": name, **per_seed(by_seed),
                         "pooled": {k: pooled[k] for k in ("attempts", "successes", "placed", "removed",
                                                           "failure_causes", "stops")},
                         "planning_median_s": pooled["planning_s"]["median"]})
    data = {"config": cfg, "gripper": db.gripper.name, "results": rows,
            "database": {"start": start_db, "end": database_record(db)}}
    md = run.write(out, data, readme_section)
    write_text(out / "summary.md", md)
    print(md)
    return 0


def readme_section(s: dict) -> str:
    """The README's E15 paragraph and table (see ``experiments/report.py``)."""
    c = s["config"]
    L = [f"`{s['command']}` (gripper `{s['gripper']}`; {c['objects']} objects per scene, {c['scenes']} scenes "
         f"per seed, {c['seeds']} seeds; the same scenes for every planner; no execution error; GSR = grasps that "
         "lifted their target / grasps, DR = objects removed / placed, per seed, then mean ± std over seeds):", ""]
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
