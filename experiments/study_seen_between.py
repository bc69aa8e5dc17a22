"""Seen-points study: how many of its object's seen points a grasp that lifts has between
its pads, and how many a grasp that closes on nothing has -- the evidence for the scene
planner's ``PlannerConfig.seen_between`` (:data:`graspsim.planning.observed.SEEN_BETWEEN`)
and ``SceneConfig.sparse_between`` (:data:`graspsim.planning.scene_config.SPARSE_BETWEEN`,
:data:`~graspsim.planning.scene_config.SPARSE_SHARE`).

A grasp planned on a fitted part may close where the camera saw nothing of the object: on
the part's extrapolation alone (a box fitted across a rounded flank, a face seen edge-on).
This study clears E10's scenes of the tuning meshes only (``household-tuning`` and
``random-tuning``: the held-out third is never used to set anything), 5-object piles and
packed scenes, no execution error, E10's seeds, camera, sensor noise and database, with
``--seen-between`` as the planner's setting while the scenes are cleared (0, the default
here: off, so the grasps it would refuse are executed and their outcome seen) and
``--sparse-between`` as the scene's (0, the default here: off, so sparse grasps rank by their
score alone; without the flag: the scene planner's default). Every
executed grasp records (``Attempt.between``) the points of its segment in its closing
region at the pose and opening executed (``GripperSpec.points_between``); the table
counts the grasps of each band of that number and what became of them.

    python experiments/study_seen_between.py --db results/e10-fsdb --workers 2 --publish
    python experiments/study_seen_between.py --db results/e10-fsdb --workers 2 --seen-between 5 --sparse-between 30
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import load_sentence, md_table, opt, rate_ci, resident_run_database, start, task_results

log = logging.getLogger("study_seen_between")

#: bands of the points between the pads for the table: [lo, hi] inclusive (None: no upper end)
BANDS = ((0, 0), (1, 4), (5, 9), (10, 29), (30, 49), (50, None))


@dataclass(frozen=True)
class Config:
    seeds: int = opt(5, "seeds: E10's first ones (derived from --seed as E10 derives them)")
    scenes: int = opt(10, "scenes per seed, kind and object set (E10's first ones)")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    object_sets: tuple[str, ...] = opt(("household-tuning", "random-tuning"),
                                       "object sets (tuning sets only, never a held-out set)")
    seen_between: int = opt(0, "the planner's PlannerConfig.seen_between while the scenes are cleared (0: off)")
    sparse_between: int = opt(0, "the scene's SceneConfig.sparse_between while the scenes are cleared (0: off)")
    seed: int = opt(0, "E10's seed")
    db: str = opt("", "the FS map database, read only (E10's --db; empty: E10's default folder)")
    workers: int = opt(1, "processes; results do not depend on it")

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.scenes < 1 or self.workers < 1 or self.seen_between < 0 or self.sparse_between < 0:
            raise ValueError("--seeds, --scenes and --workers must be >= 1, --seen-between and --sparse-between >= 0")
        if any(s.endswith("heldout") for s in self.object_sets) or not self.object_sets:
            raise ValueError("the setting is measured on tuning meshes only, never on a held-out set")


def episode(task) -> dict:
    """Scene ``i`` of seed index ``k`` of ``kind`` and ``object_set`` cleared as E10 clears
    it, with the planner's ``seen_between`` at ``cfg.seen_between`` and the scene's ``sparse_between`` at
    ``cfg.sparse_between``: its executed grasps."""
    object_set, kind, k, i, cfg, root = task
    import e10_clutter_removal as e10

    from graspsim.errors import SimulationError
    from graspsim.tabletop.clutter import run_benchmark

    db = resident_run_database(root)
    e10cfg = e10.Config(seed=cfg.seed, seeds=max(cfg.seeds, e10.Config().seeds), object_sets=(object_set,))
    sd = e10.seed_of(e10cfg, k)
    c = {"object_set": object_set, "kind": kind, "objects": 5, "noise": "none", "ablation": None}
    head = {"object_set": object_set, "kind": kind, "seed": sd, "scene": i}
    try:
        (r,) = run_benchmark(5, kind, 1, sd, db=db, config=e10._clutter_config(c, seen_between=cfg.seen_between,
                                                                          sparse_between=cfg.sparse_between),
                             object_set=object_set, first=i)
    except SimulationError as err:  # a scene that does not settle: skipped, as E10 skips it
        log.warning("%s skipped: %s", head, err)
        return {**head, "skipped": str(err)}
    names = r.names
    return {**head, "skipped": None, "placed": r.placed, "removed": r.removed,
            "grasps": [{"between": a.between, "cause": a.cause, "success": a.success, "score": a.score,
                        "target": None if a.target is None else names[a.target]} for a in r.attempts]}


def bands(grasps: list[dict]) -> list[dict]:
    """The table's rows: per band of points between the pads, the grasps and their outcomes."""
    out = []
    n = np.array([g["between"] for g in grasps], int)
    for lo, hi in BANDS:
        m = (n >= lo) & (n <= (hi if hi is not None else np.iinfo(int).max))
        gs = [g for g, keep in zip(grasps, m) if keep]
        causes = [g["cause"] for g in gs]
        out.append({"band": [lo, hi], "grasps": len(gs), "lifted": sum(g["success"] for g in gs),
                    "no_contact": causes.count("no_contact"),
                    "start_collision": sum(c.startswith("start_collision") for c in causes),
                    "other_failures": sum(not g["success"] and c != "no_contact" and not c.startswith("start_collision")
                                          for g, c in zip(gs, causes))})
    return out


def sparse_split(episodes: list[dict]) -> list[dict]:
    """Per scene kind and pooled: the grasps with at least ``SEEN_BETWEEN`` but fewer than
    ``SPARSE_BETWEEN`` points between the pads (*sparse*) and those with more, the grasps
    and how many lifted their target -- what ``SPARSE_SHARE`` is measured from."""
    from graspsim.planning.observed import SEEN_BETWEEN
    from graspsim.planning.scene_config import SPARSE_BETWEEN

    out = []
    if not episodes:
        return out
    for kind in [*dict.fromkeys(e["kind"] for e in episodes), None]:
        gs = [g for e in episodes if kind in (None, e["kind"]) for g in e["grasps"] if g["between"] >= SEEN_BETWEEN]
        row = {"kind": kind or "both"}
        for name, keep in (("sparse", lambda n: n < SPARSE_BETWEEN), ("other", lambda n: n >= SPARSE_BETWEEN)):
            sel = [g for g in gs if keep(g["between"])]
            row[name] = {"grasps": len(sel), "lifted": sum(g["success"] for g in sel)}
        out.append(row)
    return out


def summarize(episodes: list[dict]) -> dict:
    done = [e for e in episodes if not e["skipped"]]
    grasps = [g for e in done for g in e["grasps"]]
    lifted = [g["between"] for g in grasps if g["success"]]
    rows = []
    for o in dict.fromkeys(e["object_set"] for e in done):
        for kind in dict.fromkeys(e["kind"] for e in done):
            es = [e for e in done if e["object_set"] == o and e["kind"] == kind]
            gs = [g for e in es for g in e["grasps"]]
            rows.append({"object_set": o, "kind": kind, "scenes": len(es), "attempts": len(gs),
                         "successes": sum(g["success"] for g in gs), "removed": sum(e["removed"] for e in es),
                         "placed": sum(e["placed"] for e in es),
                         "no_contact": sum(g["cause"] == "no_contact" for g in gs)})
    return {"bands": bands(grasps), "rows": rows, "grasps": len(grasps),
            "lifted_median_between": float(np.median(lifted)) if lifted else None,
            "skipped": [{k: e[k] for k in ("object_set", "kind", "seed", "scene", "skipped")}
                        for e in episodes if e["skipped"]]}


def readme_section(s: dict) -> str:
    c = s["config"]
    L = [f"`{s['command']}`: E10's conditions on the tuning meshes ({', '.join(c['object_sets'])}; the held-out "
         f"third not used), {', '.join(c['kinds'])} of 5 objects, no execution error, E10's first {c['seeds']} "
         f"seeds x {c['scenes']} scenes each, the planner's `seen_between` at {c['seen_between']} "
         f"and the scene's `sparse_between` at {c.get('sparse_between', 0)} while the scenes "
         "were cleared (0: off). *Between*: the points of the grasp's own segment (the frame it was planned from, "
         "thinned to the planner's 3 mm grid) in its closing region -- between the pads at the opening executed, "
         "across the finger width, along the pad (`Attempt.between`); *lifted*: the grasp lifted its target; "
         "*no contact*: the jaws closed on nothing; *start collision*: with the target, a neighbour or the table.", ""]
    rows = []
    for b in s["bands"]:
        lo, hi = b["band"]
        label = f"{lo}" if hi == lo else (f"{lo}-{hi}" if hi is not None else f">= {lo}")
        rows.append([label, b["grasps"], b["lifted"], b["no_contact"], b["start_collision"], b["other_failures"]])
    L.append(md_table(["between", "grasps", "lifted", "no contact", "start collision", "other failures"], rows))
    L += ["", "Per condition (GSR = grasps that lifted their target / grasps, DR = objects removed / placed, 95 % "
          "Wilson intervals):", ""]
    L.append(md_table(["object set", "kind", "scenes", "GSR", "DR", "no contact"],
                      [[r["object_set"], r["kind"], r["scenes"], rate_ci(r["successes"], r["attempts"]),
                        rate_ci(r["removed"], r["placed"]), r["no_contact"]] for r in s["rows"]]))
    split = sparse_split([e for e in s.get("episodes", ()) if not e["skipped"]])  # from the grasps recorded
    if split:
        from graspsim.planning.observed import SEEN_BETWEEN
        from graspsim.planning.scene_config import SPARSE_BETWEEN

        L += ["", f"Lift rates of the grasps with {SEEN_BETWEEN} to {SPARSE_BETWEEN - 1} points between the pads "
              f"(*sparse*, `SPARSE_BETWEEN`) and of those with {SPARSE_BETWEEN} or more, and their ratio "
              "(`SPARSE_SHARE` is measured from it):", ""]
        srows = []
        for r in split:
            a, b = r["sparse"], r["other"]
            ratio = (a["lifted"] / a["grasps"]) / (b["lifted"] / b["grasps"]) if a["grasps"] and b["lifted"] else None
            srows.append([r["kind"], rate_ci(a["lifted"], a["grasps"]), rate_ci(b["lifted"], b["grasps"]),
                          "-" if ratio is None else f"{ratio:.2f}"])
        L.append(md_table(["kind", "sparse: lifted", "the others: lifted", "ratio"], srows))
    med = s["lifted_median_between"]
    L += ["", f"{s['grasps']} grasps executed; the median of *between* over the grasps that lifted: "
          f"{'-' if med is None else f'{med:g}'}; scenes skipped (not settled): {len(s['skipped'])}. "
          f"{s['config']['workers']} processes. " + load_sentence(s)]
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    import e10_clutter_removal as e10

    cfg, out, record = start(Config, __file__, argv, __doc__)
    root = cfg.db or str(Path(e10.__file__).resolve().parent.parent / "results" / "e10-fsdb")
    if not Path(root, "index.json").is_file():
        raise SystemExit(f"study_seen_between: no FS map database at {root} (run E10 first, or give --db)")
    tasks = [(o, kind, k, i, cfg, root) for o in cfg.object_sets for kind in cfg.kinds for k in range(cfg.seeds)
             for i in range(cfg.scenes)]
    episodes = []
    for e in task_results(episode, tasks, cfg.workers):
        episodes.append(e)
        log.info("%d of %d scenes: %s %s seed %d scene %d", len(episodes), len(tasks), e["object_set"],
                 e["kind"], e["seed"], e["scene"])
    text = record.write(out, {"config": cfg, **summarize(episodes), "episodes": episodes}, readme_section)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
