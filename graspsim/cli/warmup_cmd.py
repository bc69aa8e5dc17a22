"""``graspsim warmup``: compile graspsim's kernels now, so that no later command waits.

The first map generation on a machine compiles the map kernels, and the first scene plan
or adaptation the kernels of identification, the robust score, collision samples and
the pad-contact grade (numba; tens of seconds together; cached on disk afterwards). Run
this once after installing, e.g. in a container build.
"""

from __future__ import annotations

import time

from graspsim.cli._common import command, emit

__all__ = ["register"]


def _cmd_warmup(args) -> int:
    """Compile graspsim's numba kernels now (the first map generation, scene plan or
    adaptation on a machine otherwise does it, tens of seconds; they are cached on
    disk). Run once after installing, e.g. in a container build."""
    from graspsim.maps.kernels import cache_dir
    from graspsim.maps.warmup import compile_all

    t0 = time.perf_counter()
    compiled = compile_all()
    summary = {"compiled": compiled, "seconds": time.perf_counter() - t0, "cache": cache_dir()}
    what = "compiled" if compiled else "loaded from the cache"
    emit(summary, args.json, f"kernels {what} in {summary['seconds']:.1f} s "
                             f"(cache: {summary['cache'] or 'none writable'})")
    return 0


def register(sub) -> None:
    with command(sub, "warmup", run=_cmd_warmup, help="compile graspsim's kernels now (first run only; cached)"):
        pass  # no options of its own
