"""Benchmark: adapting a Festo map to another gripper (issue 18's goal: <= 0.2 s per
map, Festo HGPL-25-60-A -> Franka hand).

For each of the paper's five primitives: the Festo FS map at the default map settings
(as E11's adaptation rows use), then ``graspsim.maps.regrip.adapt_to_gripper`` to
``--to-gripper`` in this process: once cold (the object's collision sample hierarchy
built inside the timed call, as for an object seen at run time) and ``--repeat`` times
warm (median wall and process CPU seconds; the CPU figure counts the kernel's threads and
changes less with other processes' load than the wall time).

    python experiments/bench_regrip.py [--publish]
    python experiments/bench_regrip.py --quick --out results/bench_regrip-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import load_average, map_config, opt, start

log = logging.getLogger("bench_regrip")

KINDS = ("box", "cylinder", "sphere", "cone", "half_toroid")
GOAL_S = 0.2


@dataclass(frozen=True)
class Config:
    kinds: tuple[str, ...] = opt(KINDS, "the paper's primitives to adapt", choices=KINDS)
    to_gripper: str = opt("franka_hand", "the gripper the Festo maps are adapted to")
    repeat: int = opt(5, "warm adaptations per map (median)")
    coarse: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations)")
    QUICK: ClassVar[dict] = {"coarse": True, "repeat": 2, "kinds": ("box", "cylinder")}

    def __post_init__(self) -> None:
        if self.repeat < 1:
            raise ValueError("--repeat must be >= 1")


def _timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def measure(kind: str, target, cfg: Config) -> dict:
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.hierarchy import clear_caches
    from graspsim.maps.regrip import adapt_to_gripper

    fs = generate_fs_map(PAPER_SHAPES[kind], HGPL_25_60_A, config=map_config(cfg.coarse))
    clear_caches()
    _, cold, cold_cpu = _timed(lambda: adapt_to_gripper(fs, target))
    warm = [(*_timed(lambda: adapt_to_gripper(fs, target)), load_average()[0]) for _ in range(cfg.repeat)]
    adapted = warm[-1][0]
    row = {"kind": kind, "source_grasps": len(fs), "source_accepted": int(fs.accepted.sum()),
           "adapted": len(adapted), "cold_s": cold, "cold_cpu_s": cold_cpu,
           "warm_s": statistics.median(w[1] for w in warm), "warm_cpu_s": statistics.median(w[2] for w in warm),
           "warm_runs_s": [w[1] for w in warm], "load": [w[3] for w in warm]}
    log.info("%-12s %8d -> %6d grasps: cold %.3f s, warm %.3f s (CPU %.3f s)", kind, len(fs), len(adapted),
             cold, row["warm_s"], row["warm_cpu_s"])
    return row


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    from graspsim.grippers import get_gripper

    target = get_gripper(cfg.to_gripper)
    rows = [measure(k, target, cfg) for k in cfg.kinds]
    warm = [r["warm_s"] for r in rows]
    data = {"config": cfg, "target": target.name, "goal_s": GOAL_S, "rows": rows,
            "worst_warm_s": max(warm), "within_goal": sum(w <= GOAL_S for w in warm),
            "denominators": f"per primitive: one cold adaptation, the median of {cfg.repeat} warm ones"}
    print(run.write(out, data, readme_section))
    return 0


def readme_section(s: dict) -> str:
    """The README's paragraph for this benchmark (see ``experiments/report.py``)."""
    m = s["machine"]
    L = [f"`{s['command']}` (issue 18's goal: a Festo map adapted to the {s['target']} in <= {s['goal_s']:g} s): "
         "the Festo FS map of each primitive adapted by `adapt_to_gripper`, in one process; cold: the object's "
         "collision samples built inside the call; warm: median of "
         f"{s['config']['repeat']} calls after it.", "",
         "| primitive | Festo grasps | adapted | cold s | warm s | warm CPU s |", "|---|---|---|---|---|---|"]
    for r in s["rows"]:
        L.append(f"| {r['kind']} | {r['source_grasps']} | {r['adapted']} | {r['cold_s']:.3f} | {r['warm_s']:.3f} | "
                 f"{r['warm_cpu_s']:.3f} |")
    L += ["", f"Warm within {s['goal_s']:g} s: {s['within_goal']}/{len(s['rows'])} (worst {s['worst_warm_s']:.3f} s). "
          f"Load average {m['load_avg_start'][0]:.1f} at the start, {m['load_avg_end'][0]:.1f} at the end, on "
          f"{m['cpus']} cores; commit `{s['provenance']['commit']}`."]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
