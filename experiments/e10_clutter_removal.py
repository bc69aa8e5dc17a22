"""Experiment E10: clutter removal on table-top scenes seen by a simulated depth camera.

For each condition -- scene kind (pile: dropped and settled; packed: upright side by side,
>= 1 cm apart), objects per scene, execution error (none, or 3 mm / 2 deg) -- the script
draws scenes (``graspsim.sim.scenes.make_scene``, the "mixed" object set), renders each
with one D435-like depth camera (sensor noise on) and clears it grasp by grasp
(``graspsim.sim.clutter``): segment, plan every object, check grasps against the whole
scene, execute the best, remove the lifted object, render again; until the table is
clear, two grasps in a row failed or no grasp is found. Ablations (without execution
error): no neighbour check; the render's ground-truth segmentation instead of clustering.
Every condition meets the same scenes and the same random draws (paired).

Reports per condition: grasp success rate (GSR = lifts / grasps) and declutter rate
(DR = objects removed / placed) with 95 % Wilson intervals (grasps and objects of one
scene are correlated: the intervals understate the spread between scenes), scenes
cleared, failure causes, planning seconds per grasp, and the share of objects
segmented as one cluster in the first frame. Conditions run in blocks of scenes, and
the summary is rewritten after every block, so a run cut short still reports the
scenes it finished (``complete`` says whether it did).

    python experiments/e10_clutter_removal.py                 # 50 scenes per condition
    python experiments/e10_clutter_removal.py --scenes 5 --publish
    python experiments/e10_clutter_removal.py --quick --out results/e10-quick
"""

from __future__ import annotations

import logging
import shutil
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    RunRecord,
    database_note,
    database_record,
    experiment_database,
    map_config,
    opt,
    parse_config,
    pct,
    rate_ci,
)

from graspsim.errors import SimulationError
from graspsim.maps.database import MapDatabase
from graspsim.perception.scene import SceneConfig
from graspsim.sim.clutter import ClutterConfig, run_benchmark, summarize
from graspsim.sim.noise import ExecutionNoise
from graspsim.stats import wilson_interval

log = logging.getLogger("e10")
ABLATIONS = ("no_neighbours", "ground_truth")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(50, "scenes per condition")
    block: int = opt(2, "scenes per condition between summary updates")
    objects: tuple[int, ...] = opt((5, 10), "objects per scene")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    noise: tuple[str, ...] = opt(("none", "default"), "execution error: none, default (3 mm / 2 deg)",
                                 choices=("none", "default"))
    ablations: tuple[str, ...] = opt(ABLATIONS, "ablations (without execution error)", choices=ABLATIONS)
    ablation_objects: tuple[int, ...] = opt((5,), "objects per scene of the ablations")
    object_set: str = opt("mixed", "objects drawn from this set")
    seed: int = opt(0, "run seed")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    workers: int = opt(1, "processes; results do not depend on it (each condition plans against its own "
                       "linked copy of the database)")
    QUICK: ClassVar[dict] = {"scenes": 1, "block": 1, "objects": (2,), "kinds": ("packed",), "noise": ("none",),
                             "ablations": ("ground_truth",), "ablation_objects": (2,), "quick_maps": True}


def conditions(cfg: Config) -> list[dict]:
    """Every condition: kind, objects, noise label, ablation (None: the full method)."""
    out = [{"kind": k, "objects": n, "noise": z, "ablation": None}
           for k in cfg.kinds for n in cfg.objects for z in cfg.noise]
    out += [{"kind": k, "objects": n, "noise": "none", "ablation": a}
            for a in cfg.ablations for k in cfg.kinds for n in cfg.ablation_objects]
    return out


def _clutter_config(c: dict) -> ClutterConfig:
    return ClutterConfig(scene=SceneConfig(neighbours=c["ablation"] != "no_neighbours"),
                         execution=ExecutionNoise() if c["noise"] == "default" else None,
                         ground_truth=c["ablation"] == "ground_truth")


def _row(c: dict, results: list) -> dict:
    s = summarize(results)
    gsr = wilson_interval(s["successes"], s["attempts"]) if s["attempts"] else None
    dr = wilson_interval(s["removed"], s["placed"]) if s["placed"] else None
    return {**c, **s, "gsr_interval_95": gsr, "cleared_interval_95": dr,
            "episodes": [{"scene": i, **{k: v for k, v in r.to_dict().items() if k != "steps"},
                          "causes": [a.cause for a in r.attempts], "planning": [a.planning for a in r.attempts]}
                         for i, r in enumerate(results)]}


def main(argv=None) -> int:
    cfg, opts = parse_config(Config, __file__, argv, __doc__)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    run = RunRecord(__file__, argv)
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    db = experiment_database(cfg.db, out, map_config(cfg.quick_maps))
    db_start = database_record(db)
    conds = conditions(cfg)
    # each condition grows its own database (maps built for parts on first use), so a
    # condition's results depend neither on the others nor on the process running it
    roots = []
    for i in range(len(conds)):
        shutil.rmtree(out / f"fsdb-{i}", ignore_errors=True)
        roots.append(str(db.linked_copy(out / f"fsdb-{i}").root))
    done: list[list] = [[] for _ in conds]
    skipped: list[list] = [[] for _ in conds]
    pool = ProcessPoolExecutor(cfg.workers, mp_context=get_context("spawn")) if cfg.workers > 1 else None
    try:
        for start in range(0, cfg.scenes, cfg.block):
            n = min(cfg.block, cfg.scenes - start)
            tasks = [(c, cfg, root, start, n) for c, root in zip(conds, roots)]
            blocks = pool.map(_block, tasks) if pool is not None else map(_block, tasks)
            for c, results, lost, (new, miss) in zip(conds, done, skipped, blocks):
                results += new
                lost += miss
                log.info("%s: %d scenes", c, len(results))
            data = {"config": cfg, "complete": start + n >= cfg.scenes, "scenes_done": start + n,
                    "conditions": [{**_row(c, r), "skipped": k} for c, r, k in zip(conds, done, skipped)],
                    "database": {"start": db_start, "end": _grown(db_start, roots)}}
            text = run.write(out, data, readme_section, publish=opts.publish)
    finally:
        if pool is not None:
            pool.shutdown()
    print(text)
    return 0


def _grown(start: dict, roots: list[str]) -> dict:
    """The database record at the end: the start's maps and every map a condition added."""
    maps = set(start["maps"])
    for r in roots:
        maps |= set(database_record(MapDatabase(r))["maps"])
    return {"root": start["root"], "maps": sorted(maps)}


def _block(task) -> tuple[list, list]:
    """Scenes start .. start + n - 1 of a condition, against its database: (results,
    skipped scenes). A scene that cannot be drawn (it does not settle on the table) or
    whose simulation fails is skipped and said so; the same scene is then skipped in
    every condition of its kind and size that fails the same way."""
    c, cfg, root, start, n = task
    db = MapDatabase(root, config=map_config(cfg.quick_maps))
    out, skipped = [], []
    for i in range(start, start + n):
        try:
            out += run_benchmark(c["objects"], c["kind"], 1, cfg.seed, db=db, config=_clutter_config(c),
                                 object_set=cfg.object_set, first=i)
        except SimulationError as err:
            log.warning("%s scene %d skipped: %s", c, i, err)
            skipped.append({"scene": i, "reason": str(err)})
    return out, skipped


def _label(c: dict) -> str:
    if c["ablation"] == "no_neighbours":
        return "no neighbour check"
    if c["ablation"] == "ground_truth":
        return "ground-truth segmentation"
    return "with execution error" if c["noise"] == "default" else "no execution error"


def readme_section(s: dict) -> str:
    """The README's E10 block (see ``experiments/report.py``)."""
    rows = s["conditions"]
    sizes = sorted({r["scenes"] for r in rows})
    L = [f"`{s['command']}`: {'/'.join(map(str, sizes))} scenes per condition"
         + ("" if s.get("complete") else " (the run was cut short: the scenes finished so far)")
         + f", objects from the \"{s['config']['object_set']}\" set, one D435-like depth camera with sensor noise; "
         "grasps until the table is clear, two failures in a row, or no grasp found. GSR = lifts / grasps, "
         "DR = objects removed / placed (95 % Wilson intervals; grasps of one scene are correlated, so the "
         "intervals understate the spread between scenes).", "",
         "| scene | objects | condition | scenes | GSR | DR | cleared scenes | one cluster (first frame) | "
         "planning per grasp (median) | failure causes |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        causes = ", ".join(f"{k} {v}" for k, v in r["failure_causes"].items()) or "-"
        seg = r["segmentation"]
        med = r["planning_s"]["median"]
        L.append(f"| {r['kind']} | {r['objects']} | {_label(r)} | {r['scenes']} | "
                 f"{rate_ci(r['successes'], r['attempts'], r['gsr_interval_95'])} | "
                 f"{rate_ci(r['removed'], r['placed'], r['cleared_interval_95'])} | {r['scenes_cleared']} | "
                 f"{pct(seg['share'], 0)} % ({seg['one_cluster']}/{seg['objects_seen']}) | "
                 f"{'n/a' if med is None else f'{med:.2f} s'} | {causes} |")
    lost = [(r, k) for r in rows for k in r.get("skipped", [])]
    if lost:
        L += ["", "Skipped (not counted above): " + "; ".join(
            f"{r['kind']} {r['objects']} {_label(r)}, scene {k['scene']}: {k['reason']}" for r, k in lost) + "."]
    L += ["", "Where the planning time goes (median seconds per grasp, `plan_scene`'s stages; the planning "
          "column above also counts the back-projection): table fit, segmentation, identification of every "
          "segment, maps and robust scores of every segment (including FS maps built for parts no stored map "
          "covers, on first use):", "",
          "| scene | objects | condition | table | segmentation | identification | maps + scores | total |",
          "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        st = r["planning_s"].get("stages_median") or {}
        cells = " | ".join("n/a" if k not in st else f"{st[k]:.2f}" for k in ("table", "segment", "identify",
                                                                            "plan", "total"))
        L.append(f"| {r['kind']} | {r['objects']} | {_label(r)} | {cells} |")
    m = s["machine"]
    L += ["", f"Planning = depth frame to ranked grasps for the whole scene (table, segmentation, identification "
          f"of every segment, maps, robust scores against the scene), measured at load "
          f"{m['load_avg_start'][0] if m.get('load_avg_start') else 'n/a'} on {m['cpus']} cores."
          + database_note(s)]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
