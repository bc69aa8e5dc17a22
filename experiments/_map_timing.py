"""Timed map making for E02 (paper table 2): an FS map generated, a stored map scaled
and streamed best-first, each run cold (the collision-sample caches cleared, as for a new
object at run time), the median of ``repeats`` runs kept with every run's record."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import gc
import statistics

import numpy as np
from _common import Clock

from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps import generate as _generate
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.map_config import MapConfig
from graspsim.maps.scaling import ScalingConfig, scale_stream

__all__ = ["time_fs", "time_scaled"]


def _timed(run, repeats: int):
    """(the last result, timing) of ``repeats`` cold runs of ``run(clock)``, which
    returns (result, extra record fields); the medians of wall and CPU time (and of
    first_s / tenth_s where every run has them) with every run's record."""
    runs, result = [], None
    for _ in range(repeats):
        result = None  # the previous result is freed before the next run
        _generate.clear_caches()  # a new object has no cached collision samples at run time
        gc.collect()
        c = Clock()
        result, extra = run(c)
        runs.append({**c.record(), **extra})
    out = {"runs": runs, "load_avg": runs[0]["load_avg"]}
    for k in ("wall_s", "cpu_s", "first_s", "tenth_s"):
        vals = [r[k] for r in runs if r.get(k) is not None]
        out[k] = statistics.median(vals) if len(vals) == len(runs) else None
    return result, out


def time_fs(shape, config: MapConfig, repeats: int) -> tuple[GraspabilityMap, dict]:
    """The FS map of ``shape`` (the paper's gripper and quality model) and its timing."""
    return _timed(lambda c: (generate_fs_map(shape, HGPL_25_60_A, QualityModel(), config), {}), repeats)


def time_scaled(fs: GraspabilityMap, shape, scaling: ScalingConfig, repeats: int,
                hi_grade: float) -> tuple[GraspabilityMap, dict]:
    """Stream the scaled map best-first; times to the first and tenth grasp above
    ``hi_grade`` and to the whole map (concatenated)."""

    def run(c: Clock):
        first = tenth = None
        n_hi = 0
        batches = []
        for batch in scale_stream(fs, shape, scaling=scaling):
            n_hi += int(np.count_nonzero(batch.grade > hi_grade))
            if first is None and n_hi >= 1:
                first = c.wall
            if tenth is None and n_hi >= 10:
                tenth = c.wall
            batches.append(batch)
        gmap = GraspabilityMap.concat(batches) if batches else None
        return gmap, {"first_s": first, "tenth_s": tenth, "batches": len(batches)}

    return _timed(run, repeats)
