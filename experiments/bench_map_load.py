"""Benchmark: what validation on load costs (issue 13 item 4).

Wall and CPU times, each the best of ``--repeat`` runs in this process, for one map file:

* ``raw``: the map's columns, metadata and object read with h5py and a
  :class:`GraspabilityMap` built from them -- no checks (what loading cost before
  files were validated);
* ``load_map``: :func:`graspsim.maps.io.load_map`, every check (layout, the
  ``grasps/transforms`` view, :func:`~graspsim.maps.validate.map_problems`);
* ``load_map_no_transforms``: ``load_map(..., verify_transforms=False)``, what the
  map database reads its own (validated when stored) maps with;
* the parts: ``map_problems`` on the loaded map and the transforms check alone.

Without ``--map`` the FS map of the paper's largest database object (cylinder r 2 cm,
h 20 cm, default settings: ~1.4 M grasps) is generated first (a few minutes).

    python experiments/bench_map_load.py [--map FILE] [--repeat 5] [--out results/bench_map_load]
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_load, opt, start


def _raw_load(path: Path):
    """The map read with no check at all."""
    import h5py

    from graspsim.maps.graspmap import GraspabilityMap, MapMeta
    from graspsim.maps.io import _PATHS

    with h5py.File(path, "r") as f:
        cols = {c: f[d][()] for c, d in _PATHS.items()}
        meta = json.loads(f["graspability/meta"][()])
        obj = json.loads(f["object/description"][()])
        grip = json.loads(f["gripper/configuration"][()])
    return GraspabilityMap(**cols, meta=MapMeta(object=obj, gripper=grip, quality=meta["quality"],
                                                resolution=meta["resolution"], method=meta["method"],
                                                timing=meta.get("timing", {}), version=meta.get("version", ""),
                                                extra=meta.get("extra", {})))


def _transforms_only(path: Path, gmap) -> None:
    import h5py

    from graspsim.maps.io import _check_transforms

    with h5py.File(path, "r") as f:
        _check_transforms(f["grasps/transforms"], range(len(gmap)), gmap.wrist_position, path)


def _best(fn, repeat: int) -> tuple[float, float]:
    """(best wall seconds, best CPU seconds of this process) over ``repeat`` runs: on
    a loaded machine the CPU time is the steadier of the two."""
    wall, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def _make_map(folder: Path) -> Path:
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.io import save_map
    from graspsim.primitives import Cylinder

    print("[bench_map_load] generating the cylinder r 2 cm x h 20 cm map ...", file=sys.stderr, flush=True)
    return save_map(generate_fs_map(Cylinder(0.02, 0.2)), folder / "cylinder.h5")


def readme_section(summary: dict) -> str:
    t, c = summary["seconds"], summary["cpu_seconds"]
    rows = ["| read | wall s | CPU s |", "|---|---|---|"] + [f"| {k} | {v:.3f} | {c[k]:.3f} |" for k, v in t.items()]
    return ("\n".join(rows) + f"\n\n{summary['grasps']:,} grasps; best of {summary['repeat']} runs; load average "
            f"{machine_load(summary)[0][0]} before. `{summary['command']}`")


@dataclass(frozen=True)
class Config:
    map: str | None = opt(None, "map file (default: generate the cylinder map)")
    repeat: int = opt(5, "timed reads (the best is kept)")


def main(argv: list[str] | None = None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=None)
    from graspsim.maps.io import load_map
    from graspsim.maps.validate import map_problems

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(cfg.map) if cfg.map else _make_map(Path(tmp))
        gmap = load_map(path)  # warm the page cache and the imports
        timed = {
            "raw": _best(lambda: _raw_load(path), cfg.repeat),
            "load_map": _best(lambda: load_map(path), cfg.repeat),
            "load_map_no_transforms": _best(lambda: load_map(path, verify_transforms=False), cfg.repeat),
            "map_problems": _best(lambda: map_problems(gmap), cfg.repeat),
            "transforms_check": _best(lambda: _transforms_only(path, gmap), cfg.repeat),
        }
    seconds = {k: w for k, (w, _) in timed.items()}
    cpu_seconds = {k: c for k, (_, c) in timed.items()}
    data = {"map": str(cfg.map or "generated cylinder r 0.02 m h 0.2 m"), "grasps": len(gmap),
            "repeat": cfg.repeat, "seconds": seconds, "cpu_seconds": cpu_seconds,
            "overhead_vs_raw": seconds["load_map"] / seconds["raw"],
            "cpu_overhead_vs_raw": cpu_seconds["load_map"] / cpu_seconds["raw"]}
    print(run.write(out, {"config": cfg, **data}, readme_section))
    return 0


if __name__ == "__main__":
    sys.exit(main())
