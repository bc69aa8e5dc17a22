"""Benchmark: the cost of robust grasp ranking (``graspsim.maps.robust``, issue 16).

Objects of the environments' sets (one per kind, drawn from ``--seed``) stand on a
table; their sensor clouds (5 mm, 1 mm noise, all around) go to the planner with the
table known. Two costs are measured per object:

* scoring: ``score_map`` of the 1000 best-graded grasps of the adapted map (its
  clearance to the cloud, K = 32 perturbations at 3 mm / 2 deg against the cloud, the
  identified primitives and the table, the calibrated success model);
* first robust grasp: ``plan()``'s time from the end of identification to the first
  streamed grasp with a robust score > 0 (``timing["first_robust"] - timing["identify"]``).

Each is measured in fresh processes: the first run on a machine (an empty numba cache:
the kernels compile), the first call of a fresh process with a warm cache, and in-process
medians over ``--repeat`` calls after that first one. Goals (issue 16): scoring <= 50 ms,
first robust grasp <= 20 ms. Wall times depend on what else runs: the load average is
recorded around every process. The planner uses a private FS map database, ``OUT/fsdb``,
built fresh at the default map settings (``--quick``: coarse) before the first process (``--db`` to give one).

    python experiments/bench_robust.py [--repeat 5] [--processes 3] [--publish]
    python experiments/bench_robust.py --quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import experiment_database, load_average, map_config, opt, run_fresh, start, write_json

KINDS = ("box", "cylinder", "sphere", "cone", "bottle", "mug", "hammer")
GOALS_MS = {"score_1000": 50.0, "first_robust": 20.0}


def _scenes(seed: int, kinds: tuple[str, ...]):
    """(kind, world cloud (M, 3)) per kind: the object resting on the table at the origin."""
    from graspsim.envs.object_sets import draw_object
    from graspsim.primitives import synthetic_cloud
    from graspsim.seeding import rng_for
    from graspsim.sim.objects import object_from_shape
    from graspsim.sim.trial_scene import resting_pose

    out = []
    for j, kind in enumerate(kinds):
        rng = rng_for(seed, j)
        drawn = draw_object((kind,), rng, lying=0.0)
        T = resting_pose(object_from_shape(drawn.shape))
        cloud = synthetic_cloud(drawn.shape, rng, resolution=0.005, noise=0.001, T_world_obj=T).points
        out.append((kind, cloud[cloud[:, 2] > 0.003]))
    return out


def measure(seed: int, kinds: list[str], repeat: int, db_root: str) -> dict:
    """In this process: per object, the first call and the medians of ``repeat`` more."""
    from graspsim.geometry.table import TablePlane
    from graspsim.maps.database import MapDatabase
    from graspsim.maps.robust import RobustConfig, cloud_in_object, score_map
    from graspsim.planning.planner import PlannerConfig, plan
    from graspsim.seeding import rng_for

    db = MapDatabase(db_root)
    scenes = _scenes(seed, kinds)
    robust_cfg = PlannerConfig(table=TablePlane(height=0.0))
    paper_cfg = PlannerConfig(table=TablePlane(height=0.0), rank="paper")
    rows = []
    for kind, cloud in scenes:
        firsts, scores = [], []
        for _ in range(repeat + 1):
            load = load_average()[0]
            res = plan(cloud, db=db, rng=rng_for(seed), config=robust_cfg)
            t = res.timing
            firsts.append({"ms": None if t.get("first_robust") is None else 1e3 * (t["first_robust"] - t["identify"]),
                           "cpu_ms": None if t.get("first_robust_cpu") is None else 1e3 * t["first_robust_cpu"],
                           "load": load})
        base = plan(cloud, db=db, rng=rng_for(seed), config=paper_cfg)
        cl = cloud_in_object(cloud, base.T_cloud_obj)
        n = min(1000, len(base.map))
        for _ in range(repeat + 1):
            load = load_average()[0]
            t0, c0 = time.perf_counter(), time.process_time()
            score_map(base.map, cl, RobustConfig(top=1000))
            scores.append({"ms": 1e3 * (time.perf_counter() - t0), "cpu_ms": 1e3 * (time.process_time() - c0),
                           "load": load})

        def med(v, key="ms"):
            x = [r[key] for r in v[1:] if r[key] is not None]
            return statistics.median(x) if x else None

        rows.append({"kind": kind, "cloud_points": len(cloud), "grasps": len(base.map), "scored": n,
                     "parts": len(base.parts), "status": base.status.value,
                     "first_call": {"first_robust_ms": firsts[0]["ms"], "score_1000_ms": scores[0]["ms"],
                                    "score_1000_cpu_ms": scores[0]["cpu_ms"],
                                    "first_robust_cpu_ms": firsts[0]["cpu_ms"]},
                     "in_process": {"first_robust_ms": med(firsts), "score_1000_ms": med(scores),
                                    "score_1000_cpu_ms": med(scores, "cpu_ms"),
                                    "first_robust_cpu_ms": med(firsts, "cpu_ms")},
                     "load": [r["load"] for r in firsts + scores]})
    return {"rows": rows, "load_after": load_average()}


def _child(args: dict, env: dict | None = None) -> dict:
    """:func:`measure` of ``args`` in a fresh process (``env`` added to its environment)."""
    r = run_fresh([sys.executable, __file__, "--child", json.dumps(args)], env)
    if r["exit"]:
        raise RuntimeError(f"benchmark child failed: {r['stderr'][-2000:]}")
    return {**json.loads(r["stdout"].strip().splitlines()[-1]), "wall_s": r["wall_s"],
            "load_before": r["load_before"]}


def _summarise(runs: dict, cfg: Config) -> dict:
    kinds = [r["kind"] for r in runs["warm"][0]["rows"]]
    info = {r["kind"]: {k: r[k] for k in ("cloud_points", "grasps", "scored", "parts", "status")}
            for r in runs["warm"][0]["rows"]}

    def pick(proc, key, where):
        return {r["kind"]: r[where][key] for r in proc["rows"]}

    def stats(key):
        cold = pick(runs["cold"], key, "first_call") if runs.get("cold") else {}
        fresh = [pick(p, key, "first_call") for p in runs["warm"]]
        inproc = [pick(p, key, "in_process") for p in runs["warm"]]
        table = {}
        for k in kinds:
            f = [x[k] for x in fresh if x[k] is not None]
            i = [x[k] for x in inproc if x[k] is not None]
            table[k] = {"first_run": cold.get(k), "fresh_process": statistics.median(f) if f else None,
                        "in_process": statistics.median(i) if i else None}
        vals = [v["in_process"] for k, v in table.items() if v["in_process"] is not None and info[k]["scored"]]
        return {"per_kind": table, "in_process_worst_ms": max(vals) if vals else None,
                "in_process_median_ms": statistics.median(vals) if vals else None,
                "goal_ms": GOALS_MS.get(key.replace("_ms", "")),
                "met_in_process": all(v <= GOALS_MS.get(key.replace("_ms", ""), float("inf")) for v in vals)}

    loads = [x for p in runs["warm"] for r in p["rows"] for x in r["load"]]
    return {
        "config": {"repeat": cfg.repeat, "processes": cfg.processes, "seed": cfg.seed, "kinds": kinds,
                   "cold": cfg.cold, "db": cfg.db},
        "denominators": f"per kind: the first run in one process on an empty numba cache; the first call of "
                        f"{cfg.processes} fresh processes (median); in-process: medians of {cfg.repeat} calls "
                        f"after the first, median over the processes",
        "objects": info, "score_1000": stats("score_1000_ms"), "score_1000_cpu": stats("score_1000_cpu_ms"),
        "first_robust": stats("first_robust_ms"), "first_robust_cpu": stats("first_robust_cpu_ms"),
        "load_during": {"min": min(loads), "max": max(loads)},
    }


def readme_section(s: dict) -> str:
    """The README's robust-ranking cost table."""
    def ms(x):
        return "–" if x is None else f"{x:.0f}" if x >= 10 else f"{x:.1f}"

    L = [f"`{s['command']}`: {s['denominators']}; {s['machine']['cpus']} cores, load average "
         f"{s['load_during']['min']:.1f}–{s['load_during']['max']:.1f} during the measurements.", "",
         "| object | grasps scored | robust scoring of the best 1000 [ms]: first run / fresh process / "
         "in-process (CPU) | first robust grasp after identification [ms]: first run / fresh process / "
         "in-process" + (" (the calling thread's CPU)" if "first_robust_cpu" in s else "") + " |",
         "|---|---|---|---|"]
    for k, o in s["objects"].items():
        a, b = s["score_1000"]["per_kind"][k], s["first_robust"]["per_kind"][k]
        c = s["score_1000_cpu"]["per_kind"][k]
        fc = s["first_robust_cpu"]["per_kind"][k]["in_process"] if "first_robust_cpu" in s else None
        if o["status"] == "failed":
            L.append(f"| {k} | the identification failed: no map | – | – |")
            continue
        L.append(f"| {k} ({o['parts']} part{'s' if o['parts'] > 1 else ''}) | {o['scored']} | "
                 f"{ms(a['first_run'])} / {ms(a['fresh_process'])} / {ms(a['in_process'])} "
                 f"({ms(c['in_process'])}) | "
                 f"{ms(b['first_run'])} / {ms(b['fresh_process'])} / {ms(b['in_process'])}"
                 + ("" if fc is None else f" ({ms(fc)})") + " |")
    sc, fr = s["score_1000"], s["first_robust"]
    L += ["", f"In-process, worst object: scoring {ms(sc['in_process_worst_ms'])} ms of wall time, "
          f"{ms(s['score_1000_cpu']['in_process_worst_ms'])} ms of CPU time (goal "
          f"{sc['goal_ms']:.0f} ms: {'met' if sc['met_in_process'] else 'missed'}), first robust grasp "
          f"{ms(fr['in_process_worst_ms'])} ms (goal {fr['goal_ms']:.0f} ms: "
          f"{'met' if fr['met_in_process'] else 'missed'})"
          + (f", of the calling thread's CPU {ms(s['first_robust_cpu']['in_process_worst_ms'])} ms (median over "
             f"the objects {ms(s['first_robust_cpu']['in_process_median_ms'])} ms)" if "first_robust_cpu" in s else "")
          + "."]
    return "\n".join(L) + "\n"


@dataclass(frozen=True)
class Config:
    repeat: int = opt(5, "in-process calls after the first (median)")
    processes: int = opt(3, "fresh processes with a warm cache")
    seed: int = opt(16, "run seed")
    db: str | None = opt(None, "FS database folder (default: OUT/fsdb, built fresh)")
    cold: bool = opt(True, "also the first run on an empty numba cache")
    kinds: tuple[str, ...] = opt(KINDS, "objects", choices=KINDS)
    quick: bool = opt(False, "coarse maps (1 cm / 22 deg)", cli=False)
    QUICK: ClassVar[dict] = {"repeat": 2, "processes": 1, "kinds": ("cylinder", "mug"), "cold": False, "quick": True}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["--child"]:  # one measuring process (see _child)
        print(json.dumps(measure(**json.loads(argv[1]))))
        return 0
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=None)
    db = experiment_database(cfg.db, out, map_config(cfg.quick))
    args = {"seed": cfg.seed, "kinds": list(cfg.kinds), "repeat": cfg.repeat, "db_root": str(db.root)}
    runs = {"warm": []}
    _child({**args, "repeat": 0})  # warm the user's numba cache
    if cfg.cold:
        tmp = tempfile.mkdtemp(prefix="bench_robust-")
        try:
            runs["cold"] = _child(args, {"NUMBA_CACHE_DIR": tmp})
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    runs["warm"] = [_child(args) for _ in range(cfg.processes)]
    write_json(out / "runs.json", runs)
    text = run.write(out, _summarise(runs, cfg), readme_section)
    (out / "table.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
