"""Benchmark: full-scale map generation per primitive at the paper's resolution.

For each of the five paper primitives, in a fresh subprocess (so peak memory is the
map's own): time on all cores and on one (median of --repeat runs after a warm-up
that compiles the kernel), grasp counts, SR / VR, and peak memory (resident set
growth and numpy's traced allocation peak). Prints a markdown table and writes JSON.

    python experiments/bench_fsmap.py [--repeat 3] [--out results/bench_fsmap]

Goals on a 2-core machine (issue 2): cylinder r = 2 cm, h = 20 cm in <= 1 s on both
cores (<= 2 s on one), the other primitives <= 2 s each, peak memory <= 300 MB. Wall
times depend on what else runs; the CPU time of the one-thread run measures the work.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path


@dataclass(frozen=True)
class BenchConfig:
    repeat: int = 3
    primitives: tuple[str, ...] = ("cylinder", "box", "sphere", "cone", "half_toroid")
    out: str = "results/bench_fsmap"


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _run_one(name: str, repeat: int, queue) -> None:
    import resource
    import statistics
    import tracemalloc

    import numba

    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.metrics import map_rates
    from graspsim.primitives import Sphere

    shape = PAPER_SHAPES[name]
    generate_fs_map(Sphere(0.02))  # compile / load the cached kernels
    base_rss = _rss_mb()
    tracemalloc.start()
    t0 = time.perf_counter()
    gmap = generate_fs_map(shape)
    first = time.perf_counter() - t0
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    peak_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rates = map_rates(gmap)
    acc = map_rates(gmap, min_grade=0.7)
    all_threads = numba.get_num_threads()
    times, cpu = {}, {}
    for threads in sorted({all_threads, 1}, reverse=True):
        runs, cpus = [], []
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            generate_fs_map(shape, threads=threads)
            runs.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        times[threads] = statistics.median(runs)
        cpu[threads] = statistics.median(cpus)
    queue.put({
        "primitive": name, "dims": shape.dims, "grasps": len(gmap),
        "accepted": int(gmap.accepted.sum()), "SR": rates.sr, "VR": rates.vr,
        "SR_accepted": acc.sr, "VR_accepted": acc.vr,
        "seconds_all_cores": times[all_threads], "seconds_one_core": times[1],
        "cpu_seconds_one_core": cpu[1], "cpu_seconds_all_cores": cpu[all_threads],
        "load_average": os.getloadavg(),
        "threads": all_threads, "first_run_seconds": first,
        "timing_breakdown": gmap.meta.timing, "stats": gmap.meta.extra["stats"],
        "peak_rss_growth_mb": peak_rss - base_rss, "peak_rss_mb": peak_rss,
        "traced_peak_mb": traced_peak / 2**20,
        "map_memory_mb": sum(a.nbytes for a in gmap.columns().values()) / 2**20,
    })


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=BenchConfig.repeat)
    ap.add_argument("--primitives", nargs="+", default=list(BenchConfig.primitives))
    ap.add_argument("--out", default=BenchConfig.out, help="output path prefix (.json, .md)")
    a = ap.parse_args(argv)
    cfg = BenchConfig(repeat=a.repeat, primitives=tuple(a.primitives), out=a.out)
    ctx = mp.get_context("spawn")
    rows = []
    for name in cfg.primitives:
        q = ctx.Queue()
        p = ctx.Process(target=_run_one, args=(name, cfg.repeat, q))
        p.start()
        rows.append(q.get())
        p.join()
    import graspsim
    import mujoco
    import numba
    import numpy

    header = ("| primitive | grasps | accepted | SR | VR | s (all cores) | s (1 core) | "
              "CPU s (1 core) | peak RSS growth MB | traced peak MB |\n"
              "|---|---|---|---|---|---|---|---|---|---|")
    lines = [header] + [
        f"| {r['primitive']} | {r['grasps']:,} | {r['accepted']:,} | {r['SR']:.3f} | {r['VR']:.3f} | "
        f"{r['seconds_all_cores']:.3f} | {r['seconds_one_core']:.3f} | {r['cpu_seconds_one_core']:.3f} | "
        f"{r['peak_rss_growth_mb']:.0f} | {r['traced_peak_mb']:.0f} |" for r in rows]
    lines.append(f"\nload average at the end: {os.getloadavg()[0]:.2f} (other processes slow wall "
                 "times; CPU s (1 core) is the work itself)")
    table = "\n".join(lines)
    print(table)
    out = Path(cfg.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    result = {"config": asdict(cfg), "rows": rows, "machine": {
        "cpus": os.cpu_count(), "platform": platform.platform(), "python": sys.version.split()[0],
        "graspsim": graspsim.__version__, "numpy": numpy.__version__, "numba": numba.__version__,
        "mujoco": mujoco.__version__}}
    out.with_suffix(".json").write_text(json.dumps(result, indent=1))
    out.with_suffix(".md").write_text(table + "\n")
    print(json.dumps({"summary": {r["primitive"]: round(r["seconds_all_cores"], 3) for r in rows}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
