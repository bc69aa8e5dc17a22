"""Every compiled kernel of graspsim compiled (first run on a machine) or loaded from the
cache in one call (:func:`compile_all`, what ``graspsim warmup`` and the scene workers
run), each run once on a tiny input through the function planning calls it from. The
map kernels' own compilation and cache are :mod:`graspsim.maps.kernels`."""

from __future__ import annotations

import logging
import time

from graspsim.maps.kernels import cache_dir, cache_misses, ensure_compiled

__all__ = ["KERNEL_MODULES", "compiled_kernels", "compile_all"]

log = logging.getLogger(__name__)


#: The modules of graspsim's compiled kernels: the map kernels' and those compiled on their first call.
KERNEL_MODULES = ("graspsim.maps._kernel", "graspsim.maps._assemble_kernel", "graspsim.maps._hierarchy_kernel",
                  "graspsim.maps._robust_kernel", "graspsim.maps._robust_blocks", "graspsim.maps._occlusion_kernel",
                  "graspsim.primitives.sdf_kernel",
                  "graspsim.geometry.spacing_kernel", "graspsim.grades.pad_kernel", "graspsim.maps._feature_kernel",
                  "graspsim.grippers.between_kernel")


def compiled_kernels() -> dict:
    """Every compiled kernel of graspsim by qualified name (numba dispatchers)."""
    import importlib

    from numba.core.registry import CPUDispatcher

    out = {}
    for name in KERNEL_MODULES:
        mod = importlib.import_module(name)
        out.update({f"{name}.{k}": v for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)})
    return out


def compile_all(*, parallel: bool = True) -> bool:
    """Compile (first run on a machine) or load from the cache every compiled kernel:
    the map kernels (:func:`ensure_compiled`), then the others by running each once on
    a tiny input through the function planning calls it from (so for the argument types
    planning passes). ``parallel``: also the pad-contact grade's multi-threaded kernel
    (running it starts numba's thread pool in this process; a process that will fork
    scene workers can do without). Returns True if anything was compiled."""
    import numpy as np

    from graspsim.geometry.spacing import median_spacing
    from graspsim.grades.pad_kernel import SERIAL_BELOW, run_pad_patches
    from graspsim.grades.paper import QualityModel
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.feature_grasps import feature_columns
    from graspsim.maps.hierarchy import build_levels, clusters
    from graspsim.maps.map_config import MapConfig
    from graspsim.maps.robust import score_poses
    from graspsim.primitives import Box
    from graspsim.primitives.sdf import DIM_NAMES, KINDS, sdf_function

    compiled = ensure_compiled()
    before = {k: cache_misses(v) for k, v in compiled_kernels().items()}
    t0 = time.perf_counter()
    pts = np.random.default_rng(0).normal(0.0, 0.02, (40, 3))
    for kind in KINDS:  # identification's distances
        k = len(DIM_NAMES[kind])
        sdf_function(kind, pts)(np.eye(3)[None], np.zeros((1, 3)), np.full((1, k), 0.02))
    median_spacing(pts)  # point spacing (identification, the occlusion term's depth image)
    T = np.eye(4)[None].copy()
    T[0, 2, 3] = 0.1
    c = np.array([[[-0.02, 0.0, 0.0], [0.02, 0.0, 0.0]]])
    score_poses(T, np.array([0.04]), c, -c / 0.02, pts, HGPL_25_60_A,  # the robust score's kernels
                table=(np.array([0.0, 0.0, 1.0]), -0.1), viewpoint=np.array([0.0, 0.0, 0.5]))
    HGPL_25_60_A.points_between(T, np.array([0.04]), pts)  # the closing region's point count (seen between)
    coarse = MapConfig(collision_step=0.01, collision_tolerance=0.004)
    lv = build_levels(Box(0.03, 0.03, 0.03), coarse)  # collision samples
    clusters(lv["Q"], lv["RT"] + lv["HN"])
    bar = np.stack(np.meshgrid(np.arange(8) * 0.003, np.arange(4) * 0.003, [0.0, 0.01]), -1).reshape(-1, 3)
    feature_columns(bar, HGPL_25_60_A, QualityModel(), gap=0.005, up=np.array([0.0, 0.0, 1.0]))  # feature chords
    for n in ((1, SERIAL_BELOW) if parallel else (1,)):  # the pad-contact grade's, serial and threaded
        run_pad_patches(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), np.full(len(pts), 1e-6),
                        np.repeat(np.eye(3)[None], n, axis=0), np.zeros((n, 3)), 0.01, 0.0, 0.02, 0.001)
    after = {k: cache_misses(v) for k, v in compiled_kernels().items()}
    now = sum(after.values()) > sum(before.get(k, 0) for k in after)
    if now:
        log.warning("compiled the planning kernels in %.1f s (first run only; cached in %s)",
                    time.perf_counter() - t0, cache_dir())
    return compiled or now
