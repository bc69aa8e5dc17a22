"""Benchmark: a scene's first frame planned as E10 plans it, in a fresh process and warm.

For ``--scenes`` piles (or packed scenes, ``--kinds``) of each ``--objects`` size drawn from
``--object-set`` (E10's camera, its sensor noise; scene seeds from ``--seed``), the first
frame is rendered here and saved (``OUT/inputs``). Each scene i is then planned in a fresh
Python process (``run_fresh``, as a user's script meets it): ``plan_scene`` with E10's
settings for the kind (the camera's position as the viewpoint; the segments identified
and planned on ``--workers`` processes, 0: the scene's default, one per core), against
``--db`` read only (a part that no stored map serves gets its map built in memory, as
E10 does), first frame i (**cold**: the process's first planning -- compiled kernels read
from numba's cache, the segment workers forked, stored maps read from disk), then the
next scene's frame (**warm**: a new frame in a process that has planned one, as E10's
later scenes meet it). Per size: the planning time ``plan_scene`` reports (the
``total`` of its timing: cloud to ranked grasps) and its stages, cold and warm, mean,
median and max; the grasps ranked; the load average before and after each process (the
machine may be shared: compare runs made under the same load).

    python experiments/bench_first_frame.py --db /work/runs/e10-fsdb
    python experiments/bench_first_frame.py --quick --out results/bench_first_frame-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import experiment_database, machine_load, map_config, opt, run_fresh, start

_CHILD = """
import json, sys
sys.path.insert(0, {here!r})
from bench_first_frame import plan_files
print(json.dumps(plan_files(*json.loads(sys.argv[1]))))
"""


@dataclass(frozen=True)
class Config:
    scenes: int = opt(4, "scenes per kind and size (each planned cold in its own process, and warm after another)")
    objects: tuple[int, ...] = opt((5, 10), "objects per scene")
    kinds: tuple[str, ...] = opt(("pile",), "scene kinds", choices=("pile", "packed"))
    object_set: str = opt("household-tuning", "object set: a named set or a folder of meshes")
    seed: int = opt(500, "first scene seed")
    workers: int = opt(0, "segment worker processes (0: the scene's default, one per core; 1: in the process)")
    db: str = opt("", "FS database folder, read only (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations): for smoke runs")
    QUICK: ClassVar[dict] = {"scenes": 2, "objects": (5,), "coarse_db": True, "object_set": "primitives"}

    def __post_init__(self) -> None:
        from graspsim.tabletop.scene_objects import check_object_set

        if self.scenes < 2:
            raise ValueError("--scenes must be >= 2 (a warm frame is another scene's)")
        if not self.objects or any(not 1 <= n <= 10 for n in self.objects):
            raise ValueError("--objects must be in [1, 10]")
        if self.workers < 0:
            raise ValueError("--workers must be >= 0")
        check_object_set(self.object_set)


def write_frame(kind: str, n: int, seed: int, object_set: str, folder: Path) -> Path:
    """The first frame of a scene as E10 renders it: its world-frame cloud (N, 3) as .npy."""
    from graspsim.geometry.camera import backproject, rig
    from graspsim.seeding import rng_for
    from graspsim.tabletop.clutter import ClutterConfig
    from graspsim.tabletop.table_scene import make_scene

    sim = make_scene(n, kind, seed, object_set=object_set).sim()
    frame = sim.render(rig(1)[0], noise=ClutterConfig().depth_noise, rng=rng_for(seed, "depth"))
    sim.close()
    path = folder / f"{object_set.replace('/', '_')}-{kind}{n}-{seed}.npy"
    np.save(path, backproject(frame).world())
    return path


def plan_files(kind: str, files: list[tuple[str, int]], db_root: str, coarse: bool, workers: int) -> list[dict]:
    """In the fresh process: ``plan_scene`` of each (file, seed) in turn, as E10 plans its
    frames; per frame its timing [s] and the grasps ranked."""
    from dataclasses import replace

    from _scenes import RunDatabase

    from graspsim.geometry.camera import rig
    from graspsim.planning.scene import plan_scene
    from graspsim.seeding import rng_for
    from graspsim.tabletop.clutter import scene_settings

    db = RunDatabase(db_root, config=map_config(coarse))
    cfg = scene_settings(kind) if workers == 0 else replace(scene_settings(kind), workers=workers)
    out = []
    for path, seed in files:
        sp = plan_scene(np.load(path), db=db, rng=rng_for(seed, "plan"), config=cfg,
                        viewpoint=rig(1)[0].T_world_camera[:3, 3])
        out.append({"timing": sp.timing, "grasps": len(sp.grasps), "segments": len(sp.segments),
                    "built_in_memory": len(db.built)})
    return out


def _stats(xs: list[float]) -> dict:
    return {"mean": statistics.fmean(xs), "median": statistics.median(xs), "max": max(xs), "n": len(xs)}


def run(cfg: Config, out: Path) -> dict:
    folder = out / "inputs"
    folder.mkdir(parents=True, exist_ok=True)
    db = experiment_database(cfg.db or None, out, map_config(cfg.coarse_db))
    groups = []
    for kind in cfg.kinds:
        for n in cfg.objects:
            seeds = list(range(cfg.seed, cfg.seed + cfg.scenes))
            files = [(str(write_frame(kind, n, s, cfg.object_set, folder)), s) for s in seeds]
            runs = []
            for i, (f, s) in enumerate(files):
                nxt = files[(i + 1) % len(files)]
                task = json.dumps([kind, [[f, s], list(nxt)], str(db.root), cfg.coarse_db, cfg.workers])
                r = run_fresh([sys.executable, "-c", _CHILD.format(here=str(Path(__file__).resolve().parent)), task])
                if r["exit"] != 0:
                    raise SystemExit(f"planning {f} failed: {r['stderr'][-2000:]}")
                cold, warm = json.loads(r["stdout"].strip().splitlines()[-1])
                runs.append({"seed": s, "warm_seed": nxt[1], "cold": cold, "warm": warm, "wall_s": r["wall_s"],
                             "load_before": r["load_before"], "load_after": r["load_after"]})
            stages = sorted(runs[0]["cold"]["timing"])
            groups.append({"kind": kind, "objects": n, "runs": runs, **{
                w: {st: _stats([r[w]["timing"][st] for r in runs]) for st in stages} for w in ("cold", "warm")}})
    return {"groups": groups}


def readme_section(s: dict) -> str:
    rows = ["| scene | first frame, fresh process: mean / median / max | first frame, warm process: "
            "mean / median / max | stages (warm medians) |", "|---|---|---|---|"]
    for g in s["groups"]:
        c, w = g["cold"]["total"], g["warm"]["total"]
        st = ", ".join(f"{k} {g['warm'][k]['median']:.2f}" for k in ("table", "segment", "identify", "plan"))
        rows.append(f"| {g['kind']}, {g['objects']} objects ({c['n']}) | {c['mean']:.2f} / {c['median']:.2f} / "
                    f"{c['max']:.2f} s | {w['mean']:.2f} / {w['median']:.2f} / {w['max']:.2f} s | {st} |")
    load0, load1 = machine_load(s)
    loads = [r[k][0] for g in s["groups"] for r in g["runs"] for k in ("load_before", "load_after") if r[k]]
    return "\n".join(rows) + (f"\n\nLoad average {load0[0]:.2f} at the start, {load1[0]:.2f} at the end "
                              f"(per process {min(loads):.2f} to {max(loads):.2f}); {s['machine']['cpus']} cores.")


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__, quiet=("graspsim",))
    data = run(cfg, out)
    record.write(out, {"config": cfg, **data}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
