"""What every fuzz property checks: the CLI run in-process with its output captured,
a clean failure (one error line, no traceback, no leaked warning), files unchanged by
a failed command, valid maps only in a database, and bounded memory and time for the
cases that run in a capped child process.
"""

from __future__ import annotations

import collections
import contextlib
import hashlib
import io
import json
import os
import re
import resource
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from graspsim.errors import GraspsimError

REPO = Path(__file__).resolve().parents[2]

#: Generated inputs run so far in this process, by category (a test prints the total).
COUNTS: collections.Counter = collections.Counter()

#: Warnings that are a library's own business (deprecations), not a leaked numeric problem.
_TOLERATED = (DeprecationWarning, PendingDeprecationWarning, FutureWarning)

_LOG_LINE = re.compile(r"^(DEBUG|INFO|WARNING|ERROR|CRITICAL) [\w.]+: ")
_ERROR_LINE = re.compile(r"^graspsim[\w -]*: ")


def count(category: str, n: int = 1) -> None:
    COUNTS[category] += n


#: Address space a case run in this process may add to it [bytes]: a blow-up ends in a
#: MemoryError (a failure of the property) instead of filling the machine.
IN_PROCESS_HEADROOM = 3 << 30


def _vm_size() -> int:
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) * 1024 for ln in f if ln.startswith("VmSize:"))


@contextlib.contextmanager
def memory_cap(headroom: int = IN_PROCESS_HEADROOM):
    """Lower this process's soft RLIMIT_AS to its current size + ``headroom`` for the
    block (restored after; the hard limit is untouched, so it can be raised again)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = _vm_size() + headroom
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


@contextlib.contextmanager
def environ(env: dict[str, str | None] | None):
    """Set (value) or unset (None) environment variables for the block."""
    env = env or {}
    old = {k: os.environ.get(k) for k in env}
    try:
        _set_environ(env)
        yield
    finally:
        _set_environ(old)


def _set_environ(values: dict[str, str | None]) -> None:
    for k, v in values.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


class CaseTimeout(BaseException):
    """A case ran past its time limit (a BaseException: code under test cannot swallow it)."""


#: Longest one in-process case may run [s] (generous: CI machines are loaded).
CASE_SECONDS = 90


@contextlib.contextmanager
def time_limit(seconds: float = CASE_SECONDS):
    """Raise :class:`CaseTimeout` in the block after ``seconds`` (SIGALRM; main thread)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum, frame):
        raise CaseTimeout(f"the case ran longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def no_leaked_warnings():
    """Fail if the block emits a warning other than a deprecation."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    leaked = [f"{w.category.__name__}: {w.message} ({Path(w.filename).name}:{w.lineno})"
              for w in caught if not issubclass(w.category, _TOLERATED)]
    assert not leaked, f"leaked warnings: {leaked}"


@dataclass
class CliRun:
    argv: list[str]
    code: int
    out: str
    err: str
    seconds: float

    @property
    def error_lines(self) -> list[str]:
        """stderr without log records, progress notes and argparse's usage block."""
        lines = [ln for ln in self.err.splitlines() if ln.strip() and not _LOG_LINE.match(ln)
                 and not ln.startswith("[graspsim]")]
        if lines and lines[0].startswith("usage: "):  # argparse: usage block, then one error line
            lines = [ln for ln in lines[1:] if not ln[:1].isspace()]
        return lines


def run_cli(argv: list[str], env: dict[str, str | None] | None = None, cwd: Path | None = None) -> CliRun:
    """``graspsim ARGV`` in this process (stdout and stderr captured, argparse's exit
    caught), in folder ``cwd`` (relative output paths land there, not in the checkout);
    any exception other than SystemExit propagates: that is a failure."""
    from graspsim.cli import main

    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with environ(env), _chdir(cwd), time_limit(), memory_cap(), no_leaked_warnings(), \
            contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as e:  # argparse: bad option values
            code = e.code if isinstance(e.code, int) else 2
    return CliRun([str(a) for a in argv], code, out.getvalue(), err.getvalue(), time.perf_counter() - t0)


@contextlib.contextmanager
def _chdir(folder: Path | None):
    if folder is None:
        yield
        return
    old = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(old)


def assert_clean(run: CliRun) -> str:
    """A finished command: exit 0, or 1/2 with exactly one error line; never a traceback.
    Returns "ok" or "exit <code>" (the outcome's label)."""
    assert "Traceback" not in run.err and "Traceback" not in run.out, (run.argv, run.err[-3000:])
    assert run.code in (0, 1, 2), (run.argv, run.code, run.err[-2000:])
    if run.code == 0:
        return "ok"
    lines = run.error_lines
    assert len(lines) == 1 and _ERROR_LINE.match(lines[0]), (run.argv, run.err[-2000:])
    return f"exit {run.code}"


def api_call(fn, *args, **kwargs):
    """(result, None) or (None, the GraspsimError); any other exception or a leaked
    warning fails."""
    with time_limit(), memory_cap(), no_leaked_warnings():
        try:
            return fn(*args, **kwargs), None
        except GraspsimError as err:
            assert str(err).strip(), f"{type(err).__name__} without a message"
            return None, err


# ------------------------------------------------------------------ files
def snapshot(folder: Path) -> dict[str, str]:
    """Every entry under ``folder``: relative path -> content hash ("dir" for folders)."""
    state = {}
    for p in sorted(Path(folder).rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            state[rel] = "link:" + os.readlink(p)
        elif p.is_dir():
            state[rel] = "dir"
        elif p.is_file():
            state[rel] = hashlib.sha1(p.read_bytes()).hexdigest()
    return state


def assert_unchanged(before: dict, after: dict, what: str) -> None:
    changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
    assert not changed, f"{what}: files changed by a failed command: {changed}"


def oracle_problems(gmap) -> list[str]:
    """The map invariants checked independently of graspsim.maps.validate (row by row,
    in float64), so a regression in the library's own checks cannot hide itself."""
    import math

    import numpy as np

    out = []
    for name in ("wrist_position", "wrist_quat", "grasp_point", "contacts", "normals", "width", "fc_angle",
                 "q_fc", "stability_distance", "q_st", "grade"):
        a = np.asarray(getattr(gmap, name), np.float64).reshape(len(gmap), -1)
        if not np.isfinite(a).all():
            out.append(f"{name}: non-finite")
    with np.errstate(invalid="ignore"):
        for name, lo, hi in (("grade", 0, 1), ("q_fc", 0, 1), ("q_st", 0, 1), ("fc_angle", 0, math.pi),
                             ("stability_distance", 0, math.inf), ("part", 0, math.inf)):
            a = np.asarray(getattr(gmap, name), np.float64)
            if np.any((a < lo - 1e-4) | (a > hi + 1e-4)):
                out.append(f"{name}: outside [{lo}, {hi}]")
        if np.any(np.asarray(gmap.width, np.float64) <= 0):
            out.append("width <= 0")
        norms = np.linalg.norm(np.asarray(gmap.wrist_quat, np.float64), axis=1)
        if np.any(np.abs(norms - 1) > 1e-2):
            out.append("wrist_quat: not unit")
    return out


def database_problems(root: Path, touched: set[str]) -> list[str]:
    """Problems of the maps at ``touched`` (paths relative to ``root``) and of the
    index records that list them: every map a command stored must be valid."""
    from graspsim.maps.io import load_map
    from graspsim.maps.validate import map_problems

    out = []
    for rel in sorted(touched):
        if not rel.endswith(".h5") or not (root / rel).is_file():
            continue
        try:
            gmap = load_map(root / rel)
            probs = map_problems(gmap) + oracle_problems(gmap) + ([] if len(gmap) else ["no grasps"])
        except GraspsimError as err:
            probs = [f"unreadable: {err}"]
        out += [f"{rel}: {p}" for p in probs]
    return out


def changed_files(before: dict, after: dict) -> set[str]:
    return {k for k, v in after.items() if before.get(k) != v and v != "dir"}


# ------------------------------------------------------------------ capped child process
_CHILD = r"""
import contextlib, io, json, os, signal, sys, time, traceback

class _Timeout(BaseException):
    pass

def _alarm(signum, frame):
    raise _Timeout()

def _status(key):
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith(key + ":"))

signal.signal(signal.SIGALRM, _alarm)
import logging
logging.getLogger().addHandler(logging.NullHandler())  # main's basicConfig: a no-op
from graspsim.cli import main
results = []
for job in json.loads(sys.stdin.read()):
    old = {k: os.environ.get(k) for k in job["env"]}
    os.environ.update(job["env"])
    with open("/proc/self/clear_refs", "w") as f:  # reset VmHWM: this job's own peak
        f.write("5")
    rss_before = _status("VmRSS")
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    signal.alarm(int(job["seconds"]))
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(job["argv"])
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else 2
    except _Timeout:
        code = "timeout"
    except BaseException as exc:
        code = "exception"
        err.write("Traceback: " + "".join(traceback.format_exception(exc))[-3000:])
    finally:
        signal.alarm(0)
    seconds = time.perf_counter() - t0
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
    results.append({"argv": job["argv"], "code": code, "out": out.getvalue()[-2000:],
                    "err": err.getvalue()[-4000:], "seconds": seconds, "peak_rss": _status("VmHWM"),
                    "rss_before": rss_before})
print("@@RESULTS@@" + json.dumps(results))
"""


@dataclass
class CappedResult:
    argv: list[str]
    code: int | str
    out: str
    err: str
    seconds: float
    peak_rss: int  # this job's peak resident memory (the process's, VmHWM reset before it) [bytes]
    rss_before: int  # resident memory when the job started [bytes]

    @property
    def growth(self) -> int:
        return self.peak_rss - self.rss_before


def run_capped(jobs: list[dict], *, address_space: int = 4 << 30, timeout: float = 600.0,
               cwd: Path | None = None) -> list[CappedResult]:
    """Run CLI ``jobs`` ({"argv", "env", "seconds"}) one after another in a child process
    whose address space is capped (``RLIMIT_AS``); each job's own peak resident memory
    is measured (VmHWM reset before it) and it is stopped after ``seconds``. Thread
    pools are held at two threads so the cap means the same on any machine."""
    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
           "NUMBA_NUM_THREADS": "2", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    payload = json.dumps([{"env": {}, "seconds": 120, **j, "argv": [str(a) for a in j["argv"]]} for j in jobs])
    p = subprocess.run([sys.executable, "-c", _CHILD], input=payload, capture_output=True, text=True,
                       env=env, preexec_fn=cap, timeout=timeout, cwd=cwd)
    marker = p.stdout.rfind("@@RESULTS@@")
    assert p.returncode == 0 and marker >= 0, f"capped child died ({p.returncode}): {p.stderr[-3000:]}"
    return [CappedResult(**r) for r in json.loads(p.stdout[marker + len("@@RESULTS@@"):])]
