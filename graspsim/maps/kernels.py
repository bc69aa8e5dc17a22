"""Running the compiled map kernels (:mod:`graspsim.maps._kernel`): compile once, say so,
run on threads.

* :func:`ensure_compiled` compiles the kernels for their one signature each, or loads
  them from numba's on-disk cache (about 0.3 s). The first run on a machine compiles
  (a few seconds) and logs ``compiling map kernels (first run only) ...`` as a warning,
  one INFO line per kernel, so the wait is never silent; ``graspsim warmup`` does it
  ahead of time (e.g. after ``pip install``).
* The cache lives beside the module (``graspsim/maps/__pycache__``) when that folder is
  writable, else in numba's user cache (``~/.cache/numba`` or ``$XDG_CACHE_HOME/numba``);
  ``NUMBA_CACHE_DIR`` overrides both (numba's own rules); with neither writable, a
  per-user folder in the temporary directory.
* :func:`run_chunks` runs a kernel over index ranges on Python threads (one pool per
  process, started on first use): the kernels
  release the GIL, so this is as parallel as numba's ``prange`` without its compile
  cost.
* :func:`compile_all` compiles (or loads) every other compiled kernel too -- those
  identification, the robust score, collision samples and the pad-contact grade compile
  on their first call -- by calling each once on a tiny input through the code that
  calls it in planning, so that it is compiled for the types planning passes.
  ``graspsim warmup`` runs it: a machine's first scene plan would otherwise compile them
  silently (some fifteen seconds on a 2-core machine).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed, wait
from types import ModuleType

__all__ = ["ensure_compiled", "compile_all", "compiled_kernels", "kernels", "cache_dir", "default_threads",
           "run_chunks"]

log = logging.getLogger(__name__)

_lock = threading.Lock()
_ready = False


def kernels() -> ModuleType:
    """The compiled kernel module, every kernel compiled or loaded (see :func:`ensure_compiled`)."""
    ensure_compiled()
    from graspsim.maps import _kernel

    return _kernel


def ensure_compiled() -> bool:
    """Compile (first run on a machine) or load from the cache (later runs) every
    kernel, once per process. Returns True if this call compiled anything."""
    global _ready
    if _ready:
        return False
    with _lock:
        if _ready:
            return False
        k = _import_kernel()
        k.probe.compile(())
        cold = _misses(k.probe) > 0
        if cold:
            log.warning("compiling map kernels (first run only; cached in %s) ...", cache_dir())
        t0 = time.perf_counter()
        n = len(k.SIGNATURES)
        compiled = 0
        for i, (name, sig) in enumerate(k.SIGNATURES.items()):
            t = time.perf_counter()
            fn = getattr(k, name)
            fn.compile(sig)
            fn.disable_compile()  # calls with other types fail instead of compiling again
            compiled += _misses(fn) > 0
            if cold:
                log.info("  [%d/%d] %s %.1f s", i + 1, n, name.strip("_"), time.perf_counter() - t)
        if compiled:
            log.warning("map kernels compiled in %.1f s", time.perf_counter() - t0)
        _ready = True
        return bool(compiled)


#: The modules of graspsim's compiled kernels: the map kernels' and those compiled on their first call.
KERNEL_MODULES = ("graspsim.maps._kernel", "graspsim.maps._assemble_kernel", "graspsim.maps._hierarchy_kernel",
                  "graspsim.maps._robust_kernel", "graspsim.maps._robust_blocks", "graspsim.maps._occlusion_kernel",
                  "graspsim.perception._sdf_kernel",
                  "graspsim.perception._spacing_kernel", "graspsim.grades._pads")


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

    from graspsim.grades._pads import SERIAL_BELOW, run_pad_patches
    from graspsim.gripper import HGPL_25_60_A
    from graspsim.maps.generate import MapConfig
    from graspsim.maps.hierarchy import build_levels, clusters
    from graspsim.maps.robust import score_poses
    from graspsim.perception.prepare import median_spacing
    from graspsim.perception.shapes import DIM_NAMES, KINDS, sdf_function
    from graspsim.primitives import Box

    compiled = ensure_compiled()
    before = {k: _misses(v) for k, v in compiled_kernels().items()}
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
    coarse = MapConfig(collision_step=0.01, collision_tolerance=0.004)
    lv = build_levels(Box(0.03, 0.03, 0.03), coarse)  # collision samples
    clusters(lv["Q"], lv["RT"] + lv["HN"])
    for n in ((1, SERIAL_BELOW) if parallel else (1,)):  # the pad-contact grade's, serial and threaded
        run_pad_patches(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), np.full(len(pts), 1e-6),
                        np.repeat(np.eye(3)[None], n, axis=0), np.zeros((n, 3)), 0.01, 0.0, 0.02, 0.001)
    after = {k: _misses(v) for k, v in compiled_kernels().items()}
    now = sum(after.values()) > sum(before.get(k, 0) for k in after)
    if now:
        log.warning("compiled the planning kernels in %.1f s (first run only; cached in %s)",
                    time.perf_counter() - t0, cache_dir())
    return compiled or now


def cache_dir() -> str | None:
    """Folder of the kernels' on-disk cache."""
    k = _import_kernel()
    return k.probe.stats.cache_path


def _misses(fn) -> int:
    return sum(fn.stats.cache_misses.values())


def _import_kernel() -> ModuleType:
    try:
        from graspsim.maps import _kernel
    except RuntimeError as err:  # numba found no writable cache folder
        if "cannot cache function" not in str(err):
            raise
        import tempfile

        import numba

        user = os.getuid() if hasattr(os, "getuid") else "user"
        numba.config.CACHE_DIR = os.path.join(tempfile.gettempdir(), f"graspsim-numba-{user}")
        log.info("no writable cache folder for the map kernels (%s); caching them in %s; "
                    "set NUMBA_CACHE_DIR to choose", err, numba.config.CACHE_DIR)
        from graspsim.maps import _kernel
    return _kernel


def default_threads(threads: int | None = None) -> int:
    """Threads to use: ``threads`` clamped to [1, numba's thread count] (NUMBA_NUM_THREADS,
    default: the cores this process may use); None -> all of them."""
    import numba

    top = int(numba.config.NUMBA_NUM_THREADS)
    return top if threads is None else max(1, min(int(threads), top))


def run_chunks(fn: Callable[[int, int], object], n: int, threads: int, *, parts: int | None = None,
               progress: Callable[[float], None] | None = None) -> None:
    """Call ``fn(lo, hi)`` for contiguous ranges covering ``[0, n)`` (``parts`` of them,
    default one per thread) on ``threads`` threads; ``progress(done_fraction)`` after
    each range. ``fn`` must release the GIL (a ``nogil`` kernel) to run in parallel.
    The threads are the process's kernel pool (:func:`_pool`), started once: starting
    threads for every call costs milliseconds, more on a loaded machine."""
    if n <= 0:
        return
    parts = max(1, min(n, parts or threads))
    bounds = [n * i // parts for i in range(parts + 1)]
    ranges = list(zip(bounds[:-1], bounds[1:]))
    if threads <= 1 or parts == 1 or threading.current_thread().name.startswith(_PREFIX):
        for i, (lo, hi) in enumerate(ranges):
            fn(lo, hi)
            if progress:
                progress((i + 1) / parts)
        return
    futures = [_pool(min(threads, parts)).submit(fn, lo, hi) for lo, hi in ranges]
    try:
        for i, f in enumerate(as_completed(futures)):
            f.result()
            if progress:
                progress((i + 1) / parts)
    finally:  # nothing may still write into the caller's arrays once this returns
        for f in futures:
            f.cancel()
        wait(futures)


_PREFIX = "graspsim-kernel"
_pools: dict[int, tuple[int, ThreadPoolExecutor]] = {}  # workers -> (pid, pool)
_pool_lock = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    """The process's pool of ``workers`` kernel threads (made again in a forked child,
    whose copy has no threads)."""
    with _pool_lock:
        pid, ex = _pools.get(workers, (None, None))
        if ex is None or pid != os.getpid():
            ex = ThreadPoolExecutor(workers, thread_name_prefix=_PREFIX)
            _pools[workers] = (os.getpid(), ex)
        return ex
