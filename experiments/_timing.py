"""The experiment harness's timing: wall and CPU clocks, the load average, and commands
timed in a fresh process (:func:`run_fresh`, :func:`run_cli_fresh`). Scripts import these
through ``_common``."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import os
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager

__all__ = ["load_average", "host_reference", "Clock", "stopwatch", "run_fresh", "run_cli_fresh"]


def load_average() -> list[float]:
    """1, 5 and 15 minute load averages (the machine is shared: timings are noisy)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover - not on every platform
        return []


def host_reference(repeats: int = 5) -> float:
    """Wall seconds of a fixed workload of the kinds planning does (a k-d tree over a few
    thousand points and its neighbour queries, batched 3 x 3 eigendecompositions, a loop of
    small numpy calls), the best of ``repeats``. No change to graspsim moves it, the host's
    speed does: on a shared or virtual machine of one name the same planning took half as long
    again in the evening as in the morning of one day (docs/results.md). Every run records it
    when it ends (``machine.reference_s``; at the end, so that no run's own first-run timings
    follow it), so that a change in two runs' timings can be told apart from a change of host."""
    import numpy as np
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(0)
    P = rng.normal(size=(4000, 3))
    A = rng.normal(size=(2000, 3, 3))
    A = A @ A.transpose(0, 2, 1)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        cKDTree(P).query(P, k=8)
        np.linalg.eigh(A)
        x = P[:64].copy()
        for _ in range(300):
            x = x + 1e-3 * np.cross(x, P[:64])
            np.median(np.linalg.norm(x, axis=1))
        best = min(best, time.perf_counter() - t0)
    return best


class Clock:
    """Wall time and process CPU time (all threads) since construction [s]."""

    def __init__(self) -> None:
        self.wall0 = time.perf_counter()
        self.cpu0 = time.process_time()
        self.load = load_average()

    @property
    def wall(self) -> float:
        return time.perf_counter() - self.wall0

    @property
    def cpu(self) -> float:
        return time.process_time() - self.cpu0

    def record(self) -> dict:
        return {"wall_s": self.wall, "cpu_s": self.cpu, "load_avg": self.load}


@contextmanager
def stopwatch():
    """``with stopwatch() as t: ...``; afterwards ``t["wall_s"]``, ``t["cpu_s"]``,
    ``t["load_avg"]`` (at the start)."""
    c = Clock()
    out: dict = {}
    try:
        yield out
    finally:
        out.update(c.record())


def run_fresh(argv: list[str], env: dict | None = None) -> dict:
    """``argv`` in a fresh process: exit status, wall time [s], CPU time (user + system)
    [s] and peak RSS [MB] from ``wait4`` (a forked child's peak can include what it was
    forked from: :func:`run_cli_fresh` reads the CLI's own), stdout, stderr and the load
    average before and after. ``env`` is added to this process's environment."""
    load0 = load_average()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(argv, stdout=out, stderr=err, env={**os.environ, **(env or {})})
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        out.seek(0), err.seek(0)
        stdout, stderr = out.read().decode(), err.read().decode()
    return {"exit": os.waitstatus_to_exitcode(status), "wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime,
            "peak_rss_mb": ru.ru_maxrss / 1024, "stdout": stdout, "stderr": stderr, "load_before": load0,
            "load_after": load_average()}


_FRESH_CLI = """
import os, sys
from graspsim.cli import main
try:
    code = main()
finally:  # this process's own peak (VmHWM is reset at exec, unlike wait4's ru_maxrss)
    with open("/proc/self/status") as f, open(os.environ["GRASPSIM_BENCH_HWM"], "w") as out:
        out.write(next((line.split()[1] for line in f if line.startswith("VmHWM:")), ""))
sys.exit(code)
"""


def run_cli_fresh(args: list[str], env: dict | None = None) -> dict:
    """``graspsim ARGS`` in a fresh Python process, as a user runs it: :func:`run_fresh`'s
    record, with ``peak_rss_bytes`` the process's own peak resident memory (``VmHWM``;
    Linux; None where unreadable). ``env`` is added to this process's environment."""
    with tempfile.TemporaryDirectory() as d:
        hwm = os.path.join(d, "hwm")
        r = run_fresh([sys.executable, "-c", _FRESH_CLI, *args], {**(env or {}), "GRASPSIM_BENCH_HWM": hwm})
        try:
            with open(hwm) as f:
                r["peak_rss_bytes"] = int(f.read()) * 1024
        except (OSError, ValueError):
            r["peak_rss_bytes"] = None
    return r
