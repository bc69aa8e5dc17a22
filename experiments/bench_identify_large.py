"""Benchmark: identifying dense clouds (10^4, 10^5, 10^6 points) as a user meets it.

Each run is a fresh ``graspsim identify CLOUD.npy --json`` process (its wall time
includes Python start-up and imports); the script reports that wall time, the
identification's own seconds (from the JSON) and the process's peak resident memory
(``wait4``). Clouds: a cylinder (r 3 cm, h 12 cm) and a sphere (r 4 cm), uniform over
the whole surface, 0.5 mm sensor noise, randomly posed; the smaller clouds are the first
points of the largest one. Clouds above ``IdentifyConfig.max_points`` (20000) are
voxel-downsampled before identification (issue 13); the summary also gives how far
the 10^5-point result lies from the 10^6-point one.

    python experiments/bench_identify_large.py [--repeat 3] [--sizes 10000 100000 1000000]
                                               [--quick] [--out results/bench_identify_large] [--publish]

Goal (issue 13): 10^6 points identified in <= 5 s with <= 1 GiB peak memory.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_load, opt, rng_for, run_cli_fresh, start

SHAPES = {"cylinder": {"radius": 0.03, "height": 0.12}, "sphere": {"radius": 0.04}}
GOAL_SECONDS, GOAL_BYTES = 5.0, 1 << 30


@dataclass(frozen=True)
class BenchConfig:
    sizes: tuple[int, ...] = opt((10**4, 10**5, 10**6), "cloud sizes [points]")
    repeat: int = opt(3, "fresh processes per row (median)")
    seed: int = opt(0, "cloud seed")
    shapes: tuple[str, ...] = opt(tuple(SHAPES), "shapes", choices=tuple(SHAPES))
    QUICK: ClassVar[dict] = {"sizes": (2000, 25000), "repeat": 1, "shapes": ("sphere",)}

    def __post_init__(self) -> None:
        if self.repeat < 1 or min(self.sizes) < 100:
            raise ValueError(f"--repeat must be >= 1 and --sizes >= 100, got {self.repeat}, {self.sizes}")
        object.__setattr__(self, "sizes", tuple(sorted(self.sizes)))


def make_cloud(kind: str, n: int, seed: int) -> np.ndarray:
    """``n`` points (N, 3) [m] of a posed ``kind`` with 0.5 mm noise, in random order."""
    from graspsim.primitives import make_primitive, synthetic_cloud
    from graspsim.transforms import make_transform, random_rotation

    shape = make_primitive(kind, **SHAPES[kind])
    rng = rng_for(seed)  # the same stream as every earlier run: np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), [0.2, -0.1, 0.6])
    res = float(np.sqrt(shape.mesh(sections=96).area / (1.02 * n)))
    pts = synthetic_cloud(shape, rng, resolution=res, noise=0.0005, T_world_obj=T).points
    if len(pts) < n:
        raise RuntimeError(f"cloud of {len(pts)} points, wanted {n}")
    return pts[rng.permutation(len(pts))[:n]]


def run_cli(path: Path) -> dict:
    """One fresh ``graspsim identify --json`` process: wall [s], peak RSS [bytes], its JSON."""
    r = run_cli_fresh(["identify", str(path), "--json"])
    if r["exit"] != 0 or not r["stdout"].strip():
        raise RuntimeError(f"identify failed ({r['exit']}): {r['stderr'][-500:]}")
    return {"wall_s": r["wall_s"], "peak_rss_bytes": r["peak_rss_bytes"],
            "result": json.loads(r["stdout"].strip().splitlines()[-1])}


def bench(cfg: BenchConfig) -> dict:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in cfg.shapes:
            full = make_cloud(kind, max(cfg.sizes), cfg.seed)
            for n in cfg.sizes:
                path = Path(tmp) / f"{kind}_{n}.npy"
                np.save(path, full[:n])
                runs = [run_cli(path) for _ in range(cfg.repeat)]
                r = runs[0]["result"]
                part = r["parts"][0] if len(r["parts"]) == 1 else None
                rows.append({
                    "shape": kind, "points": n, "runs": cfg.repeat,
                    "identify_s_median": statistics.median(x["result"]["seconds"] for x in runs),
                    "wall_s_median": statistics.median(x["wall_s"] for x in runs),
                    "peak_rss_mib_max": max(x["peak_rss_bytes"] for x in runs) / 2**20,
                    "status": r["status"], "primitive": part["primitive"] if part else None,
                    "dims": part["dims"] if part else None, "downsampling": r["downsampling"]})
    return {"rows": rows, "agreement": _agreement(rows, cfg.sizes, cfg.shapes)}


def _agreement(rows: list[dict], sizes, shapes) -> dict:
    """Largest dimension difference [m] of each smaller cloud's result from the largest's."""
    out = {}
    big = max(sizes)
    for kind in shapes:
        ref = next(r for r in rows if r["shape"] == kind and r["points"] == big)
        for r in rows:
            if r["shape"] == kind and r["points"] != big and r["dims"] and ref["dims"]:
                same = r["primitive"] == ref["primitive"]
                diff = max(abs(r["dims"][k] - ref["dims"][k]) for k in ref["dims"]) if same else None
                out[f"{kind} {r['points']} vs {big}"] = {"same_primitive": same, "max_dim_diff_m": diff}
    return out


def readme_section(summary: dict) -> str:
    """Markdown for the README: the table and the command that produced it."""
    lines = ["| cloud | points | used after downsampling | identify s | process wall s | peak RSS MiB | found |",
             "|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        d = r["downsampling"]
        used = f"{d['used_points']:,} ({d['voxel'] * 1000:.1f} mm voxels)" if d else "all"
        dims = ", ".join(f"{k} {v * 1000:.1f} mm" for k, v in (r["dims"] or {}).items())
        lines.append(f"| {r['shape']} | {r['points']:,} | {used} | {r['identify_s_median']:.2f} | "
                     f"{r['wall_s_median']:.2f} | {r['peak_rss_mib_max']:.0f} | {r['primitive']} {dims} |")
    agree = "; ".join(
        f"{k}: " + (f"same primitive, dims within {v['max_dim_diff_m'] * 1000:.1f} mm" if v["same_primitive"]
                    else "DIFFERENT primitive") for k, v in summary["agreement"].items())
    m, (before, after) = summary["machine"], machine_load(summary)
    return ("\n".join(lines) + "\n\n"
            f"Median of {summary['config']['repeat']} fresh `graspsim identify --json` processes per row "
            f"(wall includes start-up and imports); peak RSS is the largest of them. {m['cpus']} cores, "
            f"load average {before[0]} before, {after[0]} after. Agreement: {agree}. "
            f"Goal: 10^6 points in <= {GOAL_SECONDS:g} s, <= 1 GiB.\n\n"
            f"`{summary['command']}`")


def main(argv: list[str] | None = None) -> int:
    cfg, out, run = start(BenchConfig, __file__, argv, __doc__, log_format=None)
    res = bench(cfg)
    big = [r for r in res["rows"] if r["points"] == max(cfg.sizes)]
    headline = {
        "points": max(cfg.sizes),
        "identify_s_median": max(r["identify_s_median"] for r in big),
        "wall_s_median": max(r["wall_s_median"] for r in big),
        "peak_rss_mib_max": max(r["peak_rss_mib_max"] for r in big),
        "denominator": f"median of {cfg.repeat} runs per shape, worst of {len(big)} shapes",
        "goal": {"seconds": GOAL_SECONDS, "peak_rss_mib": GOAL_BYTES / 2**20}}
    print(run.write(out, {"config": cfg, "headline": headline, **res}, readme_section))
    return 0


if __name__ == "__main__":
    sys.exit(main())
