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
* :func:`graspsim.maps.warmup.compile_all` compiles (or loads) every other compiled kernel too -- those
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

__all__ = ["ensure_compiled", "cache_misses", "kernels", "cache_dir", "default_threads",
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
        cold = cache_misses(k.probe) > 0
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
            compiled += cache_misses(fn) > 0
            if cold:
                log.info("  [%d/%d] %s %.1f s", i + 1, n, name.strip("_"), time.perf_counter() - t)
        if compiled:
            log.warning("map kernels compiled in %.1f s", time.perf_counter() - t0)
        _ready = True
        return bool(compiled)


def cache_dir() -> str | None:
    """Folder of the kernels' on-disk cache."""
    k = _import_kernel()
    return k.probe.stats.cache_path


def cache_misses(fn) -> int:
    """Compilations a numba dispatcher did not find in its on-disk cache."""
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
