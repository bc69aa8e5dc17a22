"""Benchmark: the FS-map preflight (issue 13) -- refusals as a user meets them, and the
memory estimate against measured peak memory.

Part A: ``graspsim map <primitive> <10 m dims> -o x.h5`` for each of the five
primitives in a fresh process: wall time, exit status, stderr line count, peak RSS
(``wait4``); and a 10 m x 10 m x 5 cm plate (graspable at its edge) refused by the
memory estimate under ``GRASPSIM_MEMORY_BUDGET=4GiB``.

Part B: for each of the paper's five primitives at the default resolution, in a
fresh process: the resident memory growth of ``generate_fs_map`` + ``save_map`` (what
``graspsim map`` does) over the process after imports and kernel loading, against
``estimate_map_memory(...).bytes(grasps)`` -- the bound the generator checks before
it allocates the map's columns.

    python experiments/bench_map_preflight.py [--quick] [--out results/bench_map_preflight] [--publish]
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import multiprocessing as mp
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_load, opt, run_cli_fresh, start

TEN_METRES = {
    "sphere": ["--radius", "10"],
    "cylinder": ["--radius", "10", "--height", "10"],
    "box": ["--x", "10", "--y", "10", "--z", "10"],
    "cone": ["--bottom-radius", "10", "--top-radius", "10", "--height", "10"],
    "half_toroid": ["--major-radius", "10", "--minor-radius", "5"],
    "plate (box 10 x 10 x 0.05 m, budget 4GiB)": ["--x", "10", "--y", "10", "--z", "0.05"],
}


PRIMITIVES = ("cylinder", "box", "sphere", "cone", "half_toroid")


@dataclass(frozen=True)
class Config:
    refusals: tuple[str, ...] = opt(tuple(TEN_METRES), "10 m requests (part A)", choices=tuple(TEN_METRES))
    estimates: tuple[str, ...] = opt(PRIMITIVES, "paper primitives measured (part B)", choices=PRIMITIVES)
    QUICK: ClassVar[dict] = {"refusals": ("sphere",), "estimates": ("sphere",)}


def _refusal(name: str, dims: list[str], folder: str) -> dict:
    kind = "box" if name.startswith("plate") else name
    out = Path(folder) / f"{kind}.h5"
    r = run_cli_fresh(["map", kind, *dims, "-o", str(out)], env={"GRASPSIM_MEMORY_BUDGET": "4GiB"})
    text = r["stderr"].strip()
    return {"case": name, "exit": r["exit"], "wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_bytes"] / 2**20,
            "stderr_lines": len(text.splitlines()), "message": text, "output_written": out.exists()}


def _status_mib(key: str) -> float:
    """VmRSS (now) or VmHWM (peak since exec) of this process [MiB]."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _measure(name: str, queue) -> None:
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.io import save_map
    from graspsim.maps.map_config import MapConfig
    from graspsim.maps.preflight import estimate_map_memory
    from graspsim.primitives import Sphere

    generate_fs_map(Sphere(0.01))  # load the compiled kernels
    base = _status_mib("VmRSS")
    shape = PAPER_SHAPES[name]
    with tempfile.TemporaryDirectory() as d:
        gmap = generate_fs_map(shape)
        save_map(gmap, Path(d) / "m.h5")
    peak = _status_mib("VmHWM")
    est = estimate_map_memory(shape, HGPL_25_60_A, MapConfig())
    queue.put({"primitive": name, "dims": shape.dims, "grasps": len(gmap),
               "contacts": gmap.meta.extra["stats"]["contacts"], "estimated_contacts": est.contacts,
               "estimate_mib": est.bytes(len(gmap)) / 2**20, "estimate_before_sweep_mib": est.work_bytes / 2**20,
               "measured_growth_mib": peak - base, "base_rss_mib": base})


def readme_section(summary: dict) -> str:
    a = ["| 10 m request | exit | wall s | peak RSS MiB | stderr lines |", "|---|---|---|---|---|"]
    a += [f"| {r['case']} | {r['exit']} | {r['wall_s']:.2f} | {r['peak_rss_mib']:.0f} | {r['stderr_lines']} |"
          for r in summary["refusals"]]
    b = ["| primitive | grasps | estimate MiB | measured RSS growth MiB | estimate / measured |",
         "|---|---|---|---|---|"]
    b += [f"| {r['primitive']} | {r['grasps']:,} | {r['estimate_mib']:.0f} | {r['measured_growth_mib']:.0f} | "
          f"{r['estimate_mib'] / r['measured_growth_mib']:.2f} |" for r in summary["estimates"]]
    m, (before, after) = summary["machine"], machine_load(summary)
    return ("\n".join(a) + "\n\n" + "\n".join(b) + "\n\n"
            f"Each row is one fresh process ({m['cpus']} cores, load average {before[0]} before, "
            f"{after[0]} after); wall times include Python start-up and imports. Measured growth: "
            "peak resident memory of generating and writing the map over the process after imports.\n\n"
            f"`{summary['command']}`")


def main(argv: list[str] | None = None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__, log_format=None)
    with tempfile.TemporaryDirectory() as folder:
        refusals = [_refusal(n, TEN_METRES[n], folder) for n in cfg.refusals]
    ctx = mp.get_context("spawn")
    estimates = []
    for name in cfg.estimates:
        q = ctx.Queue()
        p = ctx.Process(target=_measure, args=(name, q))
        p.start()
        estimates.append(q.get())
        p.join()
    headline = {"refusals": len(refusals), "slowest_refusal_s": max(r["wall_s"] for r in refusals),
                "all_one_line_exit_2": all(r["exit"] == 2 and r["stderr_lines"] == 1 for r in refusals),
                "estimate_over_measured_min": min(r["estimate_mib"] / r["measured_growth_mib"] for r in estimates),
                "denominator": f"{len(refusals)} requests at 10 m; {len(estimates)} paper primitives for the "
                               "estimate"}
    summary = {"config": cfg, "headline": headline, "refusals": refusals, "estimates": estimates}
    print(run.write(out, summary, readme_section))
    return 0


if __name__ == "__main__":
    sys.exit(main())
