"""Clutter-removal statistics as the field reports them: per seed, then mean ± std.

VGN (Breyer et al. 2020), GIGA and their successors report the grasp success rate (GSR)
and declutter rate (DR) of each random seed -- each seed its own set of scenes and
episodes -- and their mean and standard deviation over the seeds. :func:`per_seed` does
that from :func:`graspsim.tabletop.clutter.run_benchmark`'s results, one list per seed:

* GSR of a seed: grasps that lifted their target / grasps executed, pooled over its scenes
  (a grasp that lifted another object is not a success);
* DR of a seed: objects removed / objects placed, pooled over its scenes;
* mean and sample standard deviation (ddof = 1; 0 for one seed) over the seeds.

The protocol they count (``graspsim scene``; :class:`graspsim.tabletop.clutter.ClutterEpisode`):
scene ``i`` of a seed is ``make_scene(n, kind, derived_seed(seed, "scene", i))``, seen
by one D435-like depth camera with its noise; each step executes one grasp (the
planner's best left to try) and removes whatever it lifted; an episode stops when the
table is clear, after two failed grasps in a row, when no grasp is proposed, or after
2 x objects + 2 grasps. A start pose in collision is an executed grasp that failed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["per_seed", "benchmark_seeds"]


def benchmark_seeds(seed: int, n: int) -> list[int]:
    """The seeds of ``n`` repetitions of a benchmark run with ``seed``: ``seed`` itself
    for one, else ``derived_seed(seed, "seed", k)`` for k < n (graspsim.seeding's rule)."""
    from graspsim.seeding import derived_seed

    return [int(seed)] if n == 1 else [derived_seed(seed, "seed", k) for k in range(n)]


def per_seed(by_seed: dict) -> dict:
    """``{seed: [ClutterResult, ...]}`` -> per-seed GSR / DR and their mean and std."""
    rows = []
    for seed, results in by_seed.items():
        attempts = sum(len(r.attempts) for r in results)
        ok = sum(r.successes for r in results)
        placed, removed = sum(r.placed for r in results), sum(r.removed for r in results)
        rows.append({"seed": int(seed), "scenes": len(results), "grasps": attempts, "successes": ok,
                     "placed": placed, "removed": removed,
                     "gsr": ok / attempts if attempts else None, "dr": removed / placed if placed else None})
    out = {"per_seed": rows}
    for key in ("gsr", "dr"):
        v = np.array([r[key] for r in rows if r[key] is not None], float)
        mean = float(v.mean()) if len(v) else None
        std = float(v.std(ddof=1)) if len(v) > 1 else (0.0 if len(v) else None)
        out[key] = {"mean": mean, "std": std, "seeds": int(len(v))}
        out[f"{key}_text"] = "n/a" if mean is None else f"{100 * mean:.1f} ± {100 * std:.1f} %"
    return out
