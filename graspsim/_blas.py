"""The one place that pins OpenBLAS's kernels, so that results repeat across x86-64 CPUs.

numpy's and scipy's wheels ship OpenBLAS built for every x86-64 CPU family (DYNAMIC_ARCH):
when it loads it picks the kernels of the CPU it finds, and the kernels of different
families sum a product's terms in different orders, so a matrix product can differ in its
last bits between two machines. A clutter episode amplifies such bits (a score that ties,
an object that settles one way or the other), so the same command, seed and database gave
different episodes on two machines: E10's household-tuning piles (25 scenes, 5 seeds x 5,
no execution error, ``3dc1ce2``'s code, the same map database), run on two hosts, had the
same grasp scores in 5 of the 25 episodes and the same outcomes in 21. On one host, with
one thing changed at a time: OpenBLAS's Sandybridge kernels instead of the Haswell ones it
picks (``OPENBLAS_CORETYPE=Sandybridge``) left the scores alike in 7 of the 25 and the
outcomes in 22, while numpy's own AVX2 loops turned off (``NPY_DISABLE_CPU_FEATURES=X86_V3``)
or numba's code for no particular CPU (``NUMBA_CPU_NAME=generic``) changed nothing
(docs/results.md, *Episodes across machines*).

OpenBLAS reads ``OPENBLAS_CORETYPE`` once, when it loads (numpy's first import). So
importing graspsim before numpy sets it to the Haswell kernels -- AVX2 and FMA, which
every x86-64 CPU since 2013 has (Intel Haswell, AMD Zen and later) -- on such a CPU under
Linux, unless the variable is set already (set it yourself to choose other kernels). The
``graspsim`` command and the experiments import graspsim first; a process that imported
numpy first keeps the kernels OpenBLAS picked, and :func:`blas_cores` says which (the
experiments record it). MuJoCo, the depth renderer and CoACD are compiled code that could
part on another CPU as well; with one CPU kind at hand that was not tested. So a result is
reproduced to the episode where the library versions, the BLAS kernels and the CPU kind match.
"""

from __future__ import annotations

import os
import platform
import sys

#: The OpenBLAS kernels graspsim pins (``OPENBLAS_CORETYPE``) where the CPU has them.
PINNED_CORE = "Haswell"
_NEEDS = ("avx2", "fma")  # the instructions the Haswell kernels use
#: The symbol that names the running kernels, in each OpenBLAS build numpy and scipy ship.
_CORENAME = ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename64_",
             "openblas_get_corename")


def _cpu_flags() -> set[str]:
    """The CPU's instruction-set flags (Linux's /proc/cpuinfo; empty elsewhere)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin_blas() -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to :data:`PINNED_CORE` before OpenBLAS loads, on an
    x86-64 Linux CPU that runs those kernels, when the user set none: the kernels pinned,
    or None where it did nothing (numpy loaded already, the variable set, another CPU)."""
    if "numpy" in sys.modules or "OPENBLAS_CORETYPE" in os.environ:
        return None
    if not sys.platform.startswith("linux") or platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    if not set(_NEEDS) <= _cpu_flags():
        return None
    os.environ["OPENBLAS_CORETYPE"] = PINNED_CORE
    return PINNED_CORE


def blas_cores() -> dict[str, str]:
    """The kernels each OpenBLAS loaded in this process runs, by library file name
    (e.g. ``{"libscipy_openblas64_-32a4b2a6.so": "Haswell"}``; numpy loaded first, scipy's
    own when scipy was imported); empty where they cannot be read (not Linux, another BLAS)."""
    import ctypes

    import numpy  # noqa: F401  (its OpenBLAS loaded)

    out: dict[str, str] = {}
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.lower() and "/" in line}
    except OSError:
        return out
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _CORENAME:
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                core = fn()
                if core:
                    out[os.path.basename(path)] = core.decode("ascii", "replace").strip()
                break
    return out
