"""Helpers shared by the experiment scripts: timing on a shared machine, output files,
and the statistics of paper table 2 (mixed ANOVA, Bonferroni post-hoc).

Not part of the library: experiments import it as ``_common`` (the scripts put their
own folder on ``sys.path``).
"""

from __future__ import annotations

import json
import math
import os
import shlex
import sys
import time
from contextlib import contextmanager
from dataclasses import asdict, is_dataclass
from pathlib import Path

import numpy as np
from scipy import stats

__all__ = ["Clock", "stopwatch", "load_average", "provenance", "write_json", "write_config", "mean_sd",
           "mixed_anova", "paired_posthoc", "fmt", "RunRecord", "default_out", "pct", "rate_ci",
           "DEFAULT_NOISE", "noise_sigmas", "database_record",
           "database_note", "run_cli_fresh", "write_summary"]


def load_average() -> list[float]:
    """1, 5 and 15 minute load averages (the machine is shared: timings are noisy)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover - not on every platform
        return []


def provenance() -> dict:
    """Code state the results came from: git commit (``-dirty`` if the working tree has
    uncommitted changes: the tree is shared, so say so), graspsim version, CPU count."""
    import subprocess

    import graspsim

    try:
        commit = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True,
                                cwd=Path(__file__).resolve().parent, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"commit": commit, "graspsim": graspsim.__version__, "cpus": os.cpu_count()}


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
    """``graspsim ARGS`` in a fresh Python process, as a user runs it: exit status,
    wall time [s] (start-up and imports included), that process's own peak resident
    memory [bytes] (``VmHWM``; Linux), stdout and stderr."""
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        hwm = os.path.join(d, "hwm")
        env = {**(os.environ if env is None else env), "GRASPSIM_BENCH_HWM": hwm}
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", _FRESH_CLI, *args], capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        try:
            with open(hwm) as f:
                peak = int(f.read()) * 1024
        except (OSError, ValueError):
            peak = None
    return {"exit": p.returncode, "wall_s": wall, "peak_rss_bytes": peak, "stdout": p.stdout, "stderr": p.stderr}


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


def _jsonable(o):
    if is_dataclass(o):
        return asdict(o)
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    if hasattr(o, "value"):  # enums
        return o.value
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _clean(o):
    """NaN / inf -> None, recursively (strict JSON)."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def write_json(path: Path, data) -> None:
    text = json.dumps(_clean(json.loads(json.dumps(data, default=_jsonable))), indent=1)
    Path(path).write_text(text + "\n")


def write_summary(summary: dict, out: str | Path, stem: str, readme_section, *, publish: bool = False) -> str:
    """Write ``summary.json`` and ``README.md`` (``readme_section(summary)``) to ``out``;
    with ``publish`` also ``experiments/reported/<stem>.json``. Returns the markdown."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", summary)
    text = readme_section(summary)
    (out / "README.md").write_text(text + "\n")
    if publish:
        dest = Path(__file__).resolve().parent / "reported" / f"{stem}.json"
        dest.parent.mkdir(exist_ok=True)
        write_json(dest, summary)
    return text


def write_config(path: Path, cfg) -> None:
    write_json(path, asdict(cfg) if is_dataclass(cfg) else cfg)


def default_out(script: str) -> str:
    """``results/<stem>``: where a script writes by default (``report.py --collect``
    looks there)."""
    return f"results/{Path(script).stem}"


class RunRecord:
    """The record every experiment's ``summary.json`` carries: the exact command line,
    machine facts (cores, load average before and after, wall and CPU time), library
    versions and the git commit (``-dirty``: uncommitted changes) when it started.
    Start it before the work::

        run = RunRecord(__file__, argv)
        ...
        write_json(out / "summary.json", run.summary({"headline": ...}))
    """

    def __init__(self, script: str, argv=None) -> None:
        from graspsim.calibration.outputs import library_versions

        self.stem = Path(script).stem
        args = list(sys.argv[1:] if argv is None else argv)
        self.command = " ".join(["python", f"experiments/{self.stem}.py", *map(shlex.quote, args)])
        # the code state at the start: the tree may change while a long run goes on
        self.provenance, self.versions = provenance(), library_versions()
        self.clock = Clock()

    def summary(self, data: dict) -> dict:
        versions = dict(self.versions)
        return {"experiment": self.stem, "command": self.command, **data,
                "machine": {"cpus": os.cpu_count(), "load_avg_start": self.clock.load,
                            "load_avg_end": load_average(), "wall_s": self.clock.wall,
                            "cpu_s": self.clock.cpu, "platform": versions.pop("platform", None),
                            "date": versions.pop("date", None)},
                "versions": versions, "provenance": self.provenance}


#: the execution error of the environments and E04 (sigma: position [m], rotation [deg])
DEFAULT_NOISE = (0.003, 2.0)


def noise_sigmas(label: str) -> tuple[float, float]:
    """(position [m], rotation [deg]) of a ``--noise`` label: default, none or MM:DEG."""
    if label == "default":
        return DEFAULT_NOISE
    if label == "none":
        return 0.0, 0.0
    try:
        mm, deg = (float(x) for x in label.split(":"))
    except ValueError:
        raise ValueError(f"a noise condition is default, none or MM:DEG (e.g. 3:2), got {label!r}") from None
    if not (mm >= 0 and deg >= 0 and math.isfinite(mm + deg)):
        raise ValueError(f"--noise sigmas must be finite and >= 0, got {label!r}")
    return mm / 1000.0, deg


def database_record(db) -> dict:
    """The FS maps a ``MapDatabase`` holds (keys), with its folder: maps the planner
    builds for parts out of every stored map's range are added during a run, and a
    rerun on a database that has grown can plan some objects differently."""
    return {"root": str(db.root), "maps": sorted(e["key"] for e in db.entries())}


def database_note(summary: dict) -> str:
    """A README sentence on the database a run planned against ("" if not recorded)."""
    d = summary.get("database")
    if not d:
        return ""
    a, b = len(d["start"]["maps"]), len(d["end"]["maps"])
    grew = f", {b} at the end: parts out of every stored map's range are built and stored during the run" \
        if b != a else ", none added during the run"
    return f" The FS map database held {a} maps at the start{grew}."


def pct(x: float | None, digits: int = 1) -> str:
    """``x`` (a fraction) as a percentage without the sign; "n/a" for None / NaN."""
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{100 * x:.{digits}f}"


def rate_ci(k: int, n: int, ci=None, digits: int = 1) -> str:
    """``"96.1 % (1074/1118) [94.8, 97.1]"``: a success rate with its numerator and
    denominator and, when given, its 95 % interval (fractions)."""
    if not n:
        return f"n/a (0/{n})"
    s = f"{pct(k / n, digits)} % ({k}/{n})"
    if ci is not None:
        s += f" [{pct(ci[0], digits)}, {pct(ci[1], digits)}]"
    return s


def mean_sd(x) -> tuple[float, float]:
    """Mean and sample SD (ddof 1, as R's sd) of the finite values; NaN if none."""
    a = np.asarray([v for v in x if v is not None], float)
    a = a[np.isfinite(a)]
    if len(a) == 0:
        return math.nan, math.nan
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else math.nan


def fmt(m: float, s: float, digits: int = 0) -> str:
    """``"m (s)"`` as in the paper's tables; "n/a" for NaN."""
    if not math.isfinite(m):
        return "n/a"
    sd = f"{s:.{digits}f}" if math.isfinite(s) else "-"
    return f"{m:.{digits}f} ({sd})"


def _effect(ss: float, df: float, ss_err: float, df_err: float) -> dict:
    ms, ms_err = ss / df, ss_err / df_err
    F = ms / ms_err if ms_err > 0 else (math.inf if ms > 0 else math.nan)
    p = float(stats.f.sf(F, df, df_err)) if math.isfinite(F) else (0.0 if F == math.inf else math.nan)
    return {"SS": ss, "df": df, "MS": ms, "F": F, "df_error": df_err, "p": p}


def mixed_anova(y: np.ndarray, group: np.ndarray) -> dict:
    """Split-plot (mixed) ANOVA: ``y`` (subjects, levels) holds one value per subject
    and within-subject level; ``group`` (subjects,) the between-subject factor.

    Returns the between effect (``between``), the within effect (``within``) and the
    interaction (``interaction``), each with SS, df, MS, F, df_error and p; the within
    tests also carry the Greenhouse-Geisser epsilon and corrected p (sphericity).
    The decomposition is the textbook one for balanced groups (as in table 2: five
    subjects per group); with unbalanced groups its sums are the sequential (type-I) ones.
    """
    y = np.asarray(y, float)
    group = np.asarray(group)
    if y.ndim != 2 or len(group) != len(y):
        raise ValueError(f"y must be (subjects, levels) with one group per subject; got {y.shape}, "
                         f"{group.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("y has missing values: the mixed ANOVA needs complete subjects")
    n, k = y.shape
    labels = np.unique(group)
    g = len(labels)
    gm = y.mean()
    subj = y.mean(axis=1)
    ss_subjects = k * np.sum((subj - gm) ** 2)
    ss_between = sum(k * np.sum(group == lab) * (y[group == lab].mean() - gm) ** 2 for lab in labels)
    ss_subj_err = ss_subjects - ss_between
    ss_within_total = np.sum((y - subj[:, None]) ** 2)
    level = y.mean(axis=0)
    ss_level = n * np.sum((level - gm) ** 2)
    ss_cells = sum(np.sum(group == lab) * np.sum((y[group == lab].mean(axis=0) - gm) ** 2) for lab in labels)
    ss_inter = ss_cells - ss_level - ss_between
    ss_err = ss_within_total - ss_level - ss_inter
    df_b, df_se = g - 1, n - g
    df_w, df_i, df_we = k - 1, (k - 1) * (g - 1), (k - 1) * (n - g)
    out = {"between": _effect(ss_between, df_b, ss_subj_err, df_se),
           "within": _effect(ss_level, df_w, ss_err, df_we),
           "interaction": _effect(ss_inter, df_i, ss_err, df_we),
           "subjects": int(n), "groups": [str(x) for x in labels], "levels": int(k)}
    # Greenhouse-Geisser: epsilon from the pooled within-group covariance of the levels
    resid = np.concatenate([y[group == lab] - y[group == lab].mean(axis=0) for lab in labels])
    S = resid.T @ resid / max(n - g, 1)
    C = np.linalg.qr(np.column_stack([np.ones(k), np.eye(k)[:, : k - 1]]))[0][:, 1:].T  # (k-1, k) orthonormal contrasts
    Sc = C @ S @ C.T
    tr2 = float(np.trace(Sc @ Sc))
    eps = float(np.trace(Sc) ** 2 / ((k - 1) * tr2)) if tr2 > 0 else 1.0
    eps = min(1.0, max(eps, 1.0 / (k - 1)))
    for key in ("within", "interaction"):
        e = out[key]
        e["gg_epsilon"] = eps
        e["p_gg"] = (float(stats.f.sf(e["F"], e["df"] * eps, e["df_error"] * eps))
                     if math.isfinite(e["F"]) else e["p"])
    return out


def paired_posthoc(y: np.ndarray, names: list[str]) -> list[dict]:
    """Paired t-tests between every pair of levels (columns of ``y`` (subjects,
    levels)), Bonferroni-adjusted (p times the number of pairs, capped at 1), as R's
    ``pairwise.t.test(paired=TRUE, p.adjust.method="bonferroni")``."""
    y = np.asarray(y, float)
    pairs = [(i, j) for i in range(y.shape[1]) for j in range(i + 1, y.shape[1])]
    out = []
    for i, j in pairs:
        d = y[:, i] - y[:, j]
        if np.allclose(d, d[0]) and d[0] == 0:
            t, p = math.nan, 1.0
        else:
            r = stats.ttest_rel(y[:, i], y[:, j])
            t, p = float(r.statistic), float(r.pvalue)
        out.append({"a": names[i], "b": names[j], "mean_diff": float(d.mean()), "t": t,
                    "df": int(len(d) - 1), "p": p, "p_bonferroni": min(1.0, p * len(pairs))})
    return out
