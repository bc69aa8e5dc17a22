"""Benchmark: making a table-top scene (draw, compile, settle) and rendering what a
640 x 480 depth camera sees of it (issue 17's goal: rendering + settling <= 1 s).

For pile and packed scenes of 5 and 10 objects (``--scenes`` seeds each), in this process
after a warm-up scene:

* settle: ``make_scene`` (draw the objects, compile the MuJoCo scene, drop/place them and
  step until every object is at rest);
* first render: ``scene.sim()`` (compile again, as a user reloading it does) and one
  D435-like 640 x 480 depth + segmentation frame with a new renderer (its GL context
  included);
* warm render: the next frames from the same renderer (median of ``--renders``), depth
  and segmentation, depth alone, and depth and segmentation with ``DepthNoise()``;
* scene total = settle + first render (the goal's number).

And in fresh processes (``run_fresh``), as a user's script meets it: ``import graspsim.sim``,
make a 5-object pile, render one frame; the first run and the median of the next
``--fresh`` runs.

Planning (issue 17's goal: from a rendered 640 x 480 depth image to a ranked grasp for the
whole scene <= 0.5 s): for ``--plans`` 5-object scenes of each kind, the first frame
back-projected and planned by ``plan_scene`` as E10 plans it (its scene settings, the
camera's position as the viewpoint of the robust score's occlusion term; against a
private FS map database ``OUT/fsdb`` built fresh, or ``--db``), timed per stage (back-projection,
table, segmentation, identification of every segment, maps + robust scores against the
neighbours) and in total, wall and CPU (this process and its segment workers). Each
frame is timed as a user meets a NEW frame: this process has never seen its objects
(the collision samples, pad-contact contexts and surface samples of a primitive are
cached per process by its dimensions, so planning the same frame twice is much faster).
The FS maps the timed frames need (parts out of every stored map's range) are built
first in a separate process, and this one warms up (imports, compiled kernels, the
worker processes, the stored maps it loads) on ``WARMUP`` other scenes of each kind. The
segments are identified and planned on ``--workers`` processes (0: the scene's default,
one per core; 1 in this process: the result is the same). Writes summary.json and
config.json into ``--out``.

    python experiments/bench_scene.py
    python experiments/bench_scene.py --quick --out results/bench_scene-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import statistics
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import NAMED, experiment_database, machine_load, map_config, opt, run_fresh, start

log = logging.getLogger("bench_scene")


@dataclass(frozen=True)
class BenchConfig:
    scenes: int = opt(5, "scenes (seeds) per kind and size")
    sizes: tuple[int, ...] = opt((5, 10), "objects per scene")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    renders: int = opt(5, "warm renders per scene (median)")
    fresh: int = opt(4, "fresh processes (the first, then the median of the rest)")
    seed: int = opt(0, "first scene seed")
    plans: int = opt(10, "5-object scenes of each kind planned from their first frame (0: none)")
    db: str = opt("", "FS database folder for planning (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations): for smoke runs")
    workers: int = opt(0, "processes planning identifies segments on (0: SceneConfig's default, one per core)")
    budget: str = opt("", "per-segment planning budget ENOUGH:PER_SEGMENT (SceneConfig.enough, .per_segment; "
                      "empty: E10's, the default; see study_scene_budget.py)")
    QUICK: ClassVar[dict] = {"scenes": 1, "sizes": (5,), "kinds": ("pile",), "renders": 2, "fresh": 2, "plans": 1,
                             "coarse_db": True}

    def __post_init__(self) -> None:
        if min(self.scenes, self.renders, self.fresh, *self.sizes) < 1:
            raise ValueError("--scenes, --renders, --fresh and --sizes must be >= 1")
        if self.plans < 0 or self.workers < 0:
            raise ValueError("--plans and --workers must be >= 0")
        from graspsim.planning.scene_config import budget_fields

        budget_fields(self.budget)


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def one_scene(kind: str, n: int, seed: int, renders: int) -> dict:
    """Timings [s] of one scene: settle, first render, warm renders."""
    from graspsim.geometry.camera import rig
    from graspsim.tabletop.depth_noise import DepthNoise
    from graspsim.tabletop.table_scene import make_scene

    cam = rig(1)[0]
    scene, settle = _timed(lambda: make_scene(n, kind, seed))
    sim, build = _timed(scene.sim)
    frame, first = _timed(lambda: sim.render(cam))
    warm = [_timed(lambda: sim.render(cam))[1] for _ in range(renders)]
    r = sim._renderer_for(cam.intrinsics)
    depth_only = [_timed(lambda: r.render(sim.data, cam, segmentation=False))[1] for _ in range(renders)]
    rng = np.random.default_rng(seed)
    noisy = [_timed(lambda: sim.render(cam, noise=DepthNoise(), rng=rng))[1] for _ in range(renders)]
    sim.close()
    seen = sorted(int(k) for k in set(frame.labels.ravel().tolist()) - {-1})
    return {"kind": kind, "objects": n, "seed": seed, "attempts": scene.attempts, "settle_s": settle,
            "build_s": build, "first_render_s": build + first, "total_s": settle + build + first,
            "warm_render_s": statistics.median(warm), "warm_depth_only_s": statistics.median(depth_only),
            "warm_noisy_render_s": statistics.median(noisy),
            "objects_seen": len(seen), "valid_pixels": float((frame.depth > 0).mean())}


# a fresh process meets graspsim as a user's script does (without the harness's imports)
_FRESH = """
import json, sys, time
t0 = time.perf_counter()
from graspsim.geometry.camera import rig
from graspsim.tabletop.table_scene import make_scene
imported = time.perf_counter() - t0
t = time.perf_counter()
scene = make_scene(5, "pile", int(sys.argv[1]))
settle = time.perf_counter() - t
t = time.perf_counter()
frame = scene.sim().render(rig(1)[0])
first = time.perf_counter() - t
print(json.dumps({"import_s": imported, "settle_s": settle, "first_render_s": first, "total_s": settle + first}))
"""


def fresh_runs(cfg: BenchConfig) -> dict:
    runs = []
    for _ in range(cfg.fresh):
        r = run_fresh([sys.executable, "-c", _FRESH, str(cfg.seed)])
        if r["exit"] != 0:
            raise SystemExit(f"fresh run failed: {r['stderr'][-2000:]}")
        runs.append({**json.loads(r["stdout"].strip().splitlines()[-1]), "wall_s": r["wall_s"],
                     "cpu_s": r["cpu_s"], "peak_rss_mb": r["peak_rss_mb"], "load_before": r["load_before"]})
    rest = runs[1:] or runs
    med = {k: statistics.median(r[k] for r in rest) for k in ("wall_s", "cpu_s", "import_s", "total_s", "peak_rss_mb")}
    return {"first": {k: runs[0][k] for k in med}, "median_rest": med, "of": len(rest), "runs": runs}


PLAN_STAGES = ("backproject", "table", "segment", "identify", "plan", "total")

#: Scenes of each kind planned to warm up before the timed frames (seeds far from theirs).
WARMUP = 2
WARMUP_SEED = 10**6


def first_frame(kind: str, seed: int, budget: str = ""):
    """The first D435-like depth frame of a 5-object scene as E10 renders it (its sensor
    noise), and the scene settings E10 plans it with (with ``budget``, see
    :func:`graspsim.planning.scene.budget_fields`)."""
    from graspsim.geometry.camera import rig
    from graspsim.planning.scene_config import budget_fields
    from graspsim.seeding import rng_for
    from graspsim.tabletop.clutter import ClutterConfig, scene_settings
    from graspsim.tabletop.table_scene import make_scene

    clutter = ClutterConfig()  # E10's settings: its sensor noise, its scene planning (the kind's gap)
    sim = make_scene(5, kind, seed).sim()
    frame = sim.render(rig(1)[0], noise=clutter.depth_noise, rng=rng_for(seed, "depth"))
    sim.close()
    return frame, scene_settings(kind, **budget_fields(budget))


def _plan(points, scene_cfg, seed: int, db, workers: int, eye):
    """``plan_scene`` as E10 calls it: ``eye`` the camera's position (the viewpoint of the
    robust score's occlusion term)."""
    from graspsim.planning.scene import plan_scene
    from graspsim.seeding import rng_for

    cfg = scene_cfg if not workers else replace(scene_cfg, workers=workers)
    return plan_scene(points, db=db, rng=rng_for(seed, "plan"), config=cfg, viewpoint=eye)


def _eye(frame):
    return frame.camera.T_world_camera[:3, 3]


def _plan_frame(kind: str, seed: int, db, workers: int, budget: str = ""):
    from graspsim.geometry.camera import backproject

    frame, scene_cfg = first_frame(kind, seed, budget)
    return _plan(backproject(frame).world(), scene_cfg, seed, db, workers, _eye(frame))


def _cpu_seconds() -> float:
    """CPU seconds [user + system] of this process and its live children (the segment
    workers; Linux's /proc), NaN where they cannot be read."""
    import multiprocessing as mp
    import os

    total = time.process_time()
    for child in mp.active_children():
        try:
            with open(f"/proc/{child.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            return float("nan")
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def plan_one(kind: str, seed: int, db, workers: int = 0, budget: str = "") -> dict:
    """Planning times [s] of one 5-object scene's first frame, per stage and in total
    (back-projection included), wall and CPU."""
    from graspsim.geometry.camera import backproject

    frame, scene_cfg = first_frame(kind, seed, budget)
    c0 = _cpu_seconds()
    points, bp = _timed(lambda: backproject(frame).world())
    sp = _plan(points, scene_cfg, seed, db, workers, _eye(frame))
    cpu = _cpu_seconds() - c0
    t = {k: float(sp.timing.get(k, 0.0)) for k in PLAN_STAGES[1:]}
    t["total"] += bp
    return {"kind": kind, "seed": seed, "points": len(points), "segments": len(sp.segments),
            "grasps": len(sp.grasps), "scored": [[p.scored, len(p.primitives)] for p in sp.segments],
            "backproject": bp, **{k: t[k] for k in PLAN_STAGES[1:]}, "cpu": cpu}


_PREPARE = """
import json, sys
sys.path.insert(0, sys.argv[1])
import bench_scene
bench_scene.prepare_maps(**json.loads(sys.argv[2]))
"""


def prepare_maps(root: str, coarse: bool, scenes: list, workers: int, budget: str = "") -> None:
    """Plan ``scenes`` ([kind, seed] pairs) once against the database at ``root``: the
    FS maps their parts need are built and stored (run in a separate process, so the
    timing process never sees these scenes' objects)."""
    from graspsim.maps.database import MapDatabase

    db = MapDatabase(root, config=map_config(coarse))
    for kind, seed in scenes:
        _plan_frame(kind, seed, db, workers, budget)


# a fresh process plans a new frame as a user's script does: import, draw and render the scene,
# then back-project and plan it against the database (its maps already built); "started": the
# script starts the segment workers right after its imports (start_workers), as graspsim scene does
_FRESH_PLAN = """
import json, sys, time
t0 = time.perf_counter()
from graspsim.maps.database import MapDatabase
from graspsim.planning.scene_config import budget_fields
from graspsim.planning.scene import plan_scene, start_workers
from graspsim.seeding import rng_for
from graspsim.geometry.camera import backproject, rig
from graspsim.tabletop.clutter import ClutterConfig, scene_settings
from graspsim.tabletop.table_scene import make_scene
imported = time.perf_counter() - t0
kind, seed, root, coarse = sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5] == "1"
if sys.argv[6] == "started":
    start_workers()
sys.path.insert(0, sys.argv[1])
from _common import map_config
db = MapDatabase(root, config=map_config(coarse))
sim = make_scene(5, kind, seed).sim()
frame = sim.render(rig(1)[0], noise=ClutterConfig().depth_noise, rng=rng_for(seed, "depth"))
sim.close()
t = time.perf_counter()
config = scene_settings(kind, **budget_fields(sys.argv[7]))
sp = plan_scene(backproject(frame).world(), db=db, rng=rng_for(seed, "plan"), config=config,
                viewpoint=frame.camera.T_world_camera[:3, 3])
print(json.dumps({"import_s": imported, "plan_s": time.perf_counter() - t, "grasps": len(sp.grasps)}))
"""


FRESH_WAYS = ("plain", "started")


def fresh_plans(cfg: BenchConfig, root: str, scenes: list) -> dict:
    """Planning a new frame in fresh processes, per kind and way (``FRESH_WAYS``): the
    first run and the median of the rest, each on another of the timed scenes (their maps
    built beforehand); a kind's runs alternate between the ways."""
    out = {}
    for kind in cfg.kinds:
        runs: dict[str, list] = {way: [] for way in FRESH_WAYS}
        for _, seed in [sc for sc in scenes if sc[0] == kind][:cfg.fresh]:
            for way in FRESH_WAYS:
                r = run_fresh([sys.executable, "-c", _FRESH_PLAN, str(Path(__file__).resolve().parent), kind,
                               str(seed), root, str(int(cfg.coarse_db)), way, cfg.budget])
                if r["exit"] != 0:
                    raise SystemExit(f"fresh planning run failed: {r['stderr'][-2000:]}")
                runs[way].append({**json.loads(r["stdout"].strip().splitlines()[-1]), "seed": seed,
                                  "wall_s": r["wall_s"]})
        for way, rs in runs.items():
            rest = rs[1:] or rs
            med = {k: statistics.median(x[k] for x in rest) for k in ("wall_s", "import_s", "plan_s")}
            out[kind if way == "plain" else f"{kind}, started"] = {"first": rs[0], "of": len(rest), "runs": rs,
                                                                   "median_rest": med}
    return out


def plan_runs(cfg: BenchConfig, out: Path) -> dict:
    if not cfg.plans:
        return {}
    db = experiment_database(cfg.db, out, map_config(cfg.coarse_db))
    timed = [(kind, cfg.seed + i) for kind in cfg.kinds for i in range(cfg.plans)]
    spec = {"root": str(db.root), "coarse": cfg.coarse_db, "scenes": timed, "workers": cfg.workers,
            "budget": cfg.budget}
    r = run_fresh([sys.executable, "-c", _PREPARE, str(Path(__file__).resolve().parent), json.dumps(spec)])
    if r["exit"] != 0:
        raise SystemExit(f"building the timed scenes' maps failed: {r['stderr'][-2000:]}")
    for kind in cfg.kinds:
        for i in range(WARMUP):
            _plan_frame(kind, WARMUP_SEED + i, db, cfg.workers, cfg.budget)
    rows = [plan_one(kind, seed, db, cfg.workers, cfg.budget) for kind, seed in timed]
    groups = [{"kind": kind, "scenes": len(g), **{k: statistics.median(r[k] for r in g) for k in PLAN_STAGES},
               "cpu": statistics.median(r["cpu"] for r in g), "max_total": max(r["total"] for r in g),
               "within_goal": sum(r["total"] <= 0.5 for r in g)}
              for kind in cfg.kinds for g in [[r for r in rows if r["kind"] == kind]]]
    return {"rows": rows, "groups": groups, "prepare_s": r["wall_s"], "warmup_scenes": WARMUP, "viewpoint": True,
            "fresh": fresh_plans(cfg, str(db.root), timed)}


def run(cfg: BenchConfig) -> dict:
    one_scene("pile", 3, 10**6, 1)  # warm-up: imports, CoACD cache, GL library
    rows = [one_scene(kind, n, cfg.seed + i, cfg.renders)
            for kind in cfg.kinds for n in cfg.sizes for i in range(cfg.scenes)]
    groups = []
    for kind in cfg.kinds:
        for n in cfg.sizes:
            g = [r for r in rows if r["kind"] == kind and r["objects"] == n]
            groups.append({"kind": kind, "objects": n, "scenes": len(g),
                           **{f"median_{k}": statistics.median(r[k] for r in g)
                              for k in ("settle_s", "first_render_s", "total_s", "warm_render_s",
                                        "warm_depth_only_s", "warm_noisy_render_s")},
                           "max_total_s": max(r["total_s"] for r in g),
                           "within_goal": sum(r["total_s"] <= 1.0 for r in g)})
    return {"rows": rows, "groups": groups, "fresh": fresh_runs(cfg)}


def table(groups: list[dict]) -> str:
    head = ("scene", "scenes", "settle (median)", "first 640x480 frame", "settle + first frame (median / max)",
            "within 1 s", "next frames: depth + seg / depth / with DepthNoise()")
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for g in groups:
        out.append(f"| {g['kind']}, {g['objects']} objects | {g['scenes']} | {g['median_settle_s']:.2f} s | "
                   f"{g['median_first_render_s']:.2f} s | {g['median_total_s']:.2f} / {g['max_total_s']:.2f} s | "
                   f"{g['within_goal']}/{g['scenes']} | {1000 * g['median_warm_render_s']:.0f} / "
                   f"{1000 * g['median_warm_depth_only_s']:.0f} / "
                   f"{1000 * g.get('median_warm_noisy_render_s', np.nan):.0f} ms |")
    return "\n".join(out)


def main(argv=None) -> int:
    cfg, out, record = start(BenchConfig, __file__, argv, __doc__, log_format=NAMED)
    res = run(cfg)
    res["planning"] = plan_runs(cfg, out)
    record.write(out, {"config": cfg, **res}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


def readme_section(s: dict) -> str:
    """The README's scene-speed paragraph and table (see ``experiments/report.py``)."""
    m, (start, end) = s["machine"], machine_load(s)
    f = s["fresh"]
    L = [f"`{s['command']}` (in one process after a warm-up; {m['cpus']} cores, load average {start[0]:g} at "
         f"the start, {end[0]:g} at the end). Settle: draw, compile and settle the scene; first frame: "
         "compile it again and render one D435-like 640 x 480 (87 deg) depth + segmentation frame with a new "
         "renderer. Goal: settle + first frame <= 1 s.", "", table(s["groups"]), "",
         f"In a fresh process (import, a 5-object pile, one frame): {f['first']['wall_s']:.2f} s the first run, "
         f"{f['median_rest']['wall_s']:.2f} s the median of the next {f['of']} "
         f"(of which import {f['median_rest']['import_s']:.2f} s, scene + frame {f['median_rest']['total_s']:.2f} s; "
         f"peak RSS {f['median_rest']['peak_rss_mb']:.0f} MB)."]
    if s.get("planning"):
        p = s["planning"]
        cpu = int("cpu" in p["groups"][0])
        how = ("after a warm-up plan of the same frame" if "warmup_scenes" not in p else
               "as a user meets a new frame: this process had not seen the scene's objects (it warmed up on "
               f"{p['warmup_scenes']} other scenes of each kind; the maps the scenes' parts need were built "
               "beforehand in another process)")
        budget = s["config"].get("budget", "")
        settings = "E10's settings" if not budget else (
            f"E10's settings but the per-segment budget {budget} (`SceneConfig.enough`:`.per_segment`; "
            "`study_scene_budget.py` shows what it costs in grasps)")
        eye = (f"{settings} and, as E10, the camera's position as the viewpoint of the occlusion term"
               if p.get("viewpoint") else f"{settings} but no viewpoint: without the occlusion term E10 plans "
               "with")
        L += ["", f"Planning a 5-object scene's first frame with `plan_scene` ({eye}; {how}; medians over "
              "scenes [s]; goal: <= 0.5 s from depth image to ranked grasps" + (
                  "; CPU: this process and its segment workers" if cpu else "") + "):", "",
              "| scene | scenes | back-projection | table | segmentation | identification | maps + robust | total "
              "(median / max) | within 0.5 s |" + (" CPU |" if cpu else ""), "|" + "---|" * (9 + cpu)]
        for g in p["groups"]:
            L.append(f"| {g['kind']}, 5 objects | {g['scenes']} | " + " | ".join(
                f"{g[k]:.3f}" for k in PLAN_STAGES[:-1]) + f" | {g['total']:.2f} / {g['max_total']:.2f} | "
                f"{g['within_goal']}/{g['scenes']} |" + (f" {g['cpu']:.2f} |" if cpu else ""))
        if p.get("fresh"):
            L += ["", "In a fresh process (import, draw and render a 5-object scene, plan its frame; the maps built "
                  "beforehand), as a user's script meets it: " + "; ".join(
                      f"{k}: planning {f['first']['plan_s']:.2f} s the first run ({f['first']['wall_s']:.2f} s wall), "
                      f"{f['median_rest']['plan_s']:.2f} s the median of the next {f['of']} "
                      f"({f['median_rest']['wall_s']:.2f} s wall, of which import {f['median_rest']['import_s']:.2f} s)"
                      for k, f in p["fresh"].items()) + ". A fresh process starts its segment workers on its first "
                  "plan (each loads the compiled kernels and modules planning uses) and loads the maps it uses; "
                  "\"started\": the script calls `start_workers()` right after its imports, so the workers load "
                  "while it makes and renders the scene (on 2 cores they compete with it for the CPU)."]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
