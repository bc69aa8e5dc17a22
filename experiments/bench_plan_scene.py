"""Benchmark: ``graspsim plan-scene`` as a user meets it -- a fresh process per scene file.

For ``--scenes`` 5-object scenes of each kind (E10's: its camera, its sensor noise, seeds
from ``--seed``), the first frame is written as a user's camera driver would: the
camera-frame cloud as ``.pcd`` with its camera record (``cloud``) and the depth image as
a 16-bit PNG in millimetres (``depth``). Each file is planned once beforehand in its own
process (the maps of new sizes its parts need are built into the database then, as a
user's first run would); then every file is planned again, timed, by ``graspsim
plan-scene FILE -o GRASPS.json --db DB --min-gap GAP --json`` in a fresh process (the
cloud with nothing more: its camera record gives the viewpoint; the depth image with
``--camera d435``): wall time (start, imports, reading, planning, writing), the planning
the command reports (depth or cloud to ranked grasps), its own peak memory, and the
grasps it wrote. Per kind and input: the first scene's run and the median of the rest.

    python experiments/bench_plan_scene.py
    python experiments/bench_plan_scene.py --quick --out results/bench_plan_scene-quick
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
from _common import database_record, experiment_database, machine_load, map_config, opt, run_cli_fresh, start

INPUTS = ("cloud", "depth")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(5, "scenes per kind (the first, then the median of the rest)")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    seed: int = opt(300, "first scene seed")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations): for smoke runs")
    QUICK: ClassVar[dict] = {"scenes": 2, "kinds": ("packed",), "coarse_db": True}

    def __post_init__(self) -> None:
        if self.scenes < 1:
            raise ValueError("--scenes must be >= 1")


def write_inputs(kind: str, seed: int, folder: Path) -> dict[str, Path]:
    """The first frame of a 5-object scene as E10 renders it, as a cloud file (camera
    frame, with its camera record) and a 16-bit PNG depth image in millimetres."""
    from PIL import Image

    from graspsim.geometry.camera import backproject, rig
    from graspsim.seeding import rng_for
    from graspsim.tabletop.cloud_io import save_view
    from graspsim.tabletop.clutter import ClutterConfig
    from graspsim.tabletop.table_scene import make_scene

    sim = make_scene(5, kind, seed).sim()
    frame = sim.render(rig(1)[0], noise=ClutterConfig().depth_noise, rng=rng_for(seed, "depth"))
    sim.close()
    paths = {"cloud": folder / f"{kind}{seed}.pcd", "depth": folder / f"{kind}{seed}.png"}
    save_view(paths["cloud"], backproject(frame))
    Image.fromarray(np.round(frame.depth * 1000).astype(np.uint16)).save(paths["depth"])
    return paths


def _argv(kind: str, source: str, path: Path, out: Path, db: str, coarse: bool) -> list[str]:
    from graspsim.tabletop.table_scene import known_gap

    flags = ["--surface-step", "0.01", "--rotation-step-deg", "22"] if coarse else []
    return ["plan-scene", str(path), *(["--camera", "d435"] if source == "depth" else []), "-o", str(out),
            "--db", db, "--min-gap", str(known_gap(kind) or 0), *flags, "--json"]


def plan_fresh(argv: list[str]) -> dict:
    r = run_cli_fresh(argv)
    if r["exit"] not in (0, 1):  # 1: no grasp scores above 0 (a result, not a failure)
        raise SystemExit(f"graspsim {' '.join(argv)} failed: {r['stderr'][-2000:]}")
    s = json.loads(r["stdout"].strip().splitlines()[-1])
    return {"exit": r["exit"], "wall_s": r["wall_s"], "plan_s": s["timing"]["total"],
            "peak_rss_mb": None if r["peak_rss_bytes"] is None else r["peak_rss_bytes"] / 2**20,
            "grasps": s["grasps"], "segments": len(s["segments"]), "load_before": r["load_before"]}


def run(cfg: Config, out: Path) -> dict:
    folder = out / "inputs"
    folder.mkdir(parents=True, exist_ok=True)
    db = experiment_database(cfg.db, out, map_config(cfg.coarse_db))
    start = database_record(db)
    files = {(kind, seed): write_inputs(kind, seed, folder)
             for kind in cfg.kinds for seed in range(cfg.seed, cfg.seed + cfg.scenes)}
    for (kind, _), paths in files.items():  # maps of new sizes built now, untimed
        for source, path in paths.items():
            plan_fresh(_argv(kind, source, path, out / "prepare.json", str(db.root), cfg.coarse_db))
    groups = []
    for kind in cfg.kinds:
        for source in INPUTS:
            runs = [{"seed": seed, **plan_fresh(_argv(kind, source, files[kind, seed][source],
                                                      out / f"{kind}{seed}_{source}.json", str(db.root),
                                                      cfg.coarse_db))}
                    for seed in range(cfg.seed, cfg.seed + cfg.scenes)]
            rest = runs[1:] or runs
            groups.append({"kind": kind, "input": source, "runs": runs, "first": runs[0], "of": len(rest),
                           **{f"median_{k}": statistics.median(r[k] for r in rest)
                              for k in ("wall_s", "plan_s", "peak_rss_mb", "grasps")}})
    return {"groups": groups, "database": {"start": start, "end": database_record(db)}}


def readme_section(s: dict) -> str:
    rows = ["| scene | input | first run: wall / planning | median of the next: wall / planning | peak memory, "
            "the command's process (median) | grasps written (median) |", "|---|---|---|---|---|---|"]
    for g in s["groups"]:
        f = g["first"]
        rows.append(f"| {g['kind']}, 5 objects | {g['input']} | {f['wall_s']:.2f} / {f['plan_s']:.2f} s | "
                    f"{g['median_wall_s']:.2f} / {g['median_plan_s']:.2f} s ({g['of']}) | "
                    f"{g['median_peak_rss_mb']:.0f} MB | {g['median_grasps']:.0f} |")
    load0, load1 = machine_load(s)
    cpus = s["machine"]["cpus"]
    return (f"`{s['command']}` (a fresh `graspsim plan-scene` process per file; {cpus} cores, load average "
            f"{load0[0]} at the start, {load1[0]} at the end). Input: E10's first frame of each scene as a "
            "camera-frame `.pcd` with its camera record (cloud) or a 16-bit PNG in millimetres with "
            "`--camera d435` (depth); wall: start, imports, reading, planning and writing; planning: what the "
            "command reports (table, segmentation, identification, maps and scores; the first plan in a "
            "process also starts its segment workers and loads the maps it uses); peak memory: the command's own "
            "process, its forked segment workers not counted:\n\n" + "\n".join(rows))


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    print(record.write(out, {"config": cfg, **run(cfg, out)}, readme_section))
    return 0


if __name__ == "__main__":
    sys.exit(main())
