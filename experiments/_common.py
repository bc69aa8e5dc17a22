"""The experiment harness: everything an ``experiments/*.py`` script shares. Read this
file to write one. Not part of the library: scripts put their own folder on
``sys.path`` and ``import _common``.

A script is thin (STYLE.md 16)::

    @dataclass(frozen=True)
    class Config:                                  # the defaults, written once
        seed: int = opt(0, "run seed")
        per_case: int = opt(500, "grasps drawn per map")
        kinds: tuple[str, ...] = opt(("box", "sphere"), "primitives", choices=KINDS)
        QUICK: ClassVar[dict] = {"per_case": 8}    # what --quick changes (a smoke run)

    def main(argv=None) -> int:
        cfg, opts = parse_config(Config, __file__, argv, __doc__)   # --seed --per-case --kinds
        run = RunRecord(__file__, argv)                             # --quick --out --publish
        ...                                                         # call the library
        print(run.write(opts.out, {"config": cfg, ...}, readme_section, publish=opts.publish))

    def readme_section(summary: dict) -> str: ...  # the README block (experiments/report.py)

What lives here, one of each:

* **Config -> CLI**: :func:`opt`, :func:`parse_config` (a flag per dataclass field, the
  dataclass default shown in ``--help``; ``--out``, ``--publish`` and, when the class
  has ``QUICK``, ``--quick``; a value the config rejects exits 2 with one line).
* **The summary**: :class:`RunRecord` starts the clock and records the command line,
  code state (:func:`provenance`) and library versions; :meth:`RunRecord.write` writes
  ``summary.json`` (headline numbers with denominators, ``command``, ``machine``,
  ``versions``, ``provenance``), the README block as ``README.md``, ``config.json``
  and, with ``--publish``, ``experiments/reported/<stem>.json``. :func:`machine_load`
  reads the load average of any summary, old or new.
* **Seeds**: ``rng_for(cfg.seed, *keys)`` / ``derived_seed`` from
  :mod:`graspsim.seeding`, the rule the library uses too: one integer seed per run,
  streams keyed by names (CRC-32) and indices, never a sum of character codes.
* **Maps and scenes**: :func:`map_config` (the default or the quick runs' coarse maps),
  :func:`standing_cloud` (an object standing on the table at a random yaw, seen as a
  (single-view) cloud).
* **Timing**: :class:`Clock`, :func:`stopwatch`, :func:`load_average`,
  :func:`run_fresh` (a command in a fresh process: wall, CPU, peak RSS) and
  :func:`run_cli_fresh` (``graspsim ARGS`` so, with the process's own peak RSS).
* **Text**: ``fmt`` and ``md_table`` (:mod:`graspsim.calibration.markdown`),
  :func:`mean_sd_text`, :func:`pct`, :func:`rate_ci`.
* **Simulation settings**: :func:`noise_sigmas`.
* **The FS map database**: :func:`experiment_database` (unless ``--db`` names one, a
  private ``<out>/fsdb`` built fresh from the paper's five shapes at the script's map
  config, so a rerun from a clean clone starts from the same maps, never the user's
  shared database another run has grown), :func:`database_record`,
  :func:`database_note`.

The statistics of the paper's table 2 (mixed ANOVA, Bonferroni post-hoc) are in
``_stats.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import types
import typing
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from graspsim._jsonable import to_jsonable
from graspsim.calibration.markdown import fmt, md_table
from graspsim.calibration.outputs import library_versions, write_json, write_text
from graspsim.seeding import derived_seed, rng_for, seed_sequence

__all__ = ["opt", "parse_config", "RunRecord", "machine_load", "provenance", "default_out",
           "rng_for", "derived_seed", "seed_sequence", "map_config", "standing_cloud",
           "Clock", "stopwatch", "load_average", "run_fresh", "run_cli_fresh",
           "write_json", "write_text", "write_config", "fmt", "md_table", "mean_sd_text", "pct", "rate_ci",
           "noise_sigmas", "experiment_database", "database_record", "database_note"]

EXPERIMENTS = Path(__file__).resolve().parent


# ------------------------------------------------------------------ config -> CLI
def opt(default, help: str = "", *, choices=None, cli: bool = True):
    """A config field with its CLI help (``cli=False``: no flag)."""
    return dataclasses.field(default=default, metadata={"help": help, "choices": choices, "cli": cli})


def _flag_kwargs(tp, default, f: dataclasses.Field) -> dict:
    """argparse keywords of a field of type ``tp``."""
    kw = {"help": f"{f.metadata.get('help', '')} (default: {default})".strip()}
    if f.metadata.get("choices"):
        kw["choices"] = list(f.metadata["choices"])
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if typing.get_origin(tp) in (typing.Union, types.UnionType) and args:
        tp = args[0]  # X | None: the flag takes an X
    if tp is bool:
        return {**kw, "action": argparse.BooleanOptionalAction}
    if typing.get_origin(tp) in (tuple, list):
        elem = (typing.get_args(tp) or (str,))[0]
        return {**kw, "nargs": "+", "type": elem}
    return {**kw, "type": tp if tp in (int, float, str) else str}


def parse_config(cls, script: str, argv=None, description: str | None = None):
    """``(config, opts)`` from the command line: one ``--field-name`` flag per field of
    the frozen dataclass ``cls`` (fields made with ``opt(cli=False)`` have none), with
    the dataclass defaults, or ``cls.QUICK``'s with ``--quick``; flags given override
    both. ``opts`` holds ``out`` (default ``results/<stem>``), ``publish`` and ``quick``."""
    hints = typing.get_type_hints(cls)
    p = argparse.ArgumentParser(description=(description or "").split("\n\n")[0])
    p.add_argument("--out", default=default_out(script), help="output folder (default: %(default)s)")
    p.add_argument("--publish", action="store_true",
                   help=f"also copy summary.json to experiments/reported/{Path(script).stem}.json")
    quick = getattr(cls, "QUICK", None)
    if quick is not None:
        p.add_argument("--quick", action="store_true",
                       help="smoke run: " + ", ".join(f"{k}={v}" for k, v in quick.items()))
    names = []
    for f in dataclasses.fields(cls):
        if f.metadata.get("cli", True) and f.init:
            names.append(f.name)
            p.add_argument("--" + f.name.replace("_", "-"), dest=f.name, default=argparse.SUPPRESS,
                           **_flag_kwargs(hints[f.name], f.default, f))
    a = p.parse_args(argv)
    given = {n: tuple(v) if isinstance(v, list) else v for n, v in vars(a).items() if n in names}
    try:
        base = cls(**quick) if quick is not None and a.quick else cls()
        cfg = dataclasses.replace(base, **given)
    except ValueError as e:  # GraspsimError subclasses included: one line, exit 2
        p.error(str(e))
    opts = argparse.Namespace(out=a.out, publish=a.publish, quick=bool(getattr(a, "quick", False)))
    return cfg, opts


# ------------------------------------------------------------------ the summary
def default_out(script: str) -> str:
    """``results/<stem>``: where a script writes by default (``report.py --collect``
    looks there)."""
    return f"results/{Path(script).stem}"


def provenance() -> dict:
    """Code state the results came from: git commit (``-dirty`` if the working tree has
    uncommitted changes: the tree is shared, so say so), graspsim version, CPU count."""
    import graspsim

    try:
        commit = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True,
                                cwd=EXPERIMENTS, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"commit": commit, "graspsim": graspsim.__version__, "cpus": os.cpu_count()}


class RunRecord:
    """The record every experiment's ``summary.json`` carries: the exact command line,
    machine facts (cores, load average at the start and the end, wall and CPU time),
    library versions and the git commit (``-dirty``: uncommitted changes) when it
    started. Start it before the work; :meth:`write` at the end."""

    def __init__(self, script: str, argv=None) -> None:
        self.stem = Path(script).stem
        args = list(sys.argv[1:] if argv is None else argv)
        self.command = " ".join(["python", f"experiments/{self.stem}.py", *map(shlex.quote, args)])
        # the code state at the start: the tree may change while a long run goes on
        self.provenance, self.versions = provenance(), library_versions()
        self.clock = Clock()

    def summary(self, data: dict) -> dict:
        """``data`` between the command and the machine facts."""
        versions = dict(self.versions)
        return {"experiment": self.stem, "command": self.command, **data,
                "machine": {"cpus": os.cpu_count(), "load_avg_start": self.clock.load,
                            "load_avg_end": load_average(), "wall_s": self.clock.wall,
                            "cpu_s": self.clock.cpu, "platform": versions.pop("platform", None),
                            "date": versions.pop("date", None)},
                "versions": versions, "provenance": self.provenance}

    def write(self, out: str | Path, data: dict, readme_section=None, *, publish: bool = False,
              config=None) -> str:
        """Write ``out/summary.json`` (:meth:`summary` of ``data``), ``out/README.md``
        (``readme_section(summary)``), ``out/config.json`` (``config``, or
        ``data["config"]``) and, with ``publish``, ``experiments/reported/<stem>.json``.
        Returns the markdown ("" without ``readme_section``)."""
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        summary = to_jsonable(self.summary(data))  # as readme_section reads it back from the file
        config = data.get("config") if config is None else config
        if config is not None:
            write_json(out / "config.json", config)
        text = readme_section(summary) if readme_section is not None else ""
        write_json(out / "summary.json", summary)
        if text:
            write_text(out / "README.md", text)
        if publish:
            (EXPERIMENTS / "reported").mkdir(parents=True, exist_ok=True)
            write_json(EXPERIMENTS / "reported" / f"{self.stem}.json", summary)
        return text


def machine_load(summary: dict) -> tuple[list, list]:
    """(load average at the start, at the end) of a summary (the benchmarks' older
    summaries say ``load_before`` / ``load_after``)."""
    m = summary["machine"]
    return (m.get("load_avg_start", m.get("load_before")) or [math.nan],
            m.get("load_avg_end", m.get("load_after")) or [math.nan])


def write_config(path: Path, cfg) -> None:
    """``write_json`` of a config (kept for scripts that call it by this name)."""
    write_json(path, cfg)


# ------------------------------------------------------------------ maps and scenes
def map_config(quick: bool = False, **kw):
    """The scripts' ``MapConfig(**kw)``: at the library's default resolution, or for
    quick runs coarse (1 cm surface step, 22 deg rotation step)."""
    from graspsim.maps.generate import MapConfig

    if quick:
        kw = {"surface_step": 0.01, "rotation_step": math.radians(22.0), **kw}
    return MapConfig(**kw)


def standing_cloud(truth, rng: np.random.Generator, *, resolution: float, noise: float, outliers: float,
                   at=(0.55, -0.05), camera: tuple[float, float] | None = None):
    """A cloud of ``truth`` (a Primitive or Compound) standing on the table (z = 0) at
    ``at`` (x, y) [m] and a yaw drawn from ``rng``; seen from all around, or with
    ``camera`` = (distance [m], elevation [deg]) from one camera at an azimuth drawn
    next. Returns (points (N, 3) [m] in the cloud's (world) frame, T_cloud_true)."""
    from graspsim.primitives import synthetic_cloud
    from graspsim.transforms import make_transform

    a = rng.uniform(0, 2 * math.pi)
    R = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    T = make_transform(R, [at[0], at[1], -truth.aabb[0, 2]])
    cam = None
    if camera is not None:
        dist, el = camera[0], math.radians(camera[1])
        az = rng.uniform(0, 2 * math.pi)
        cam = dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    c = synthetic_cloud(truth, rng, resolution=resolution, noise=noise, outliers=outliers, camera=cam,
                        T_world_obj=T)
    return c.points, T


# ------------------------------------------------------------------ timing
def load_average() -> list[float]:
    """1, 5 and 15 minute load averages (the machine is shared: timings are noisy)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover - not on every platform
        return []


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


# ------------------------------------------------------------------ text
def mean_sd_text(m: float, s: float, digits: int = 0) -> str:
    """``"m (s)"`` as in the paper's tables; "n/a" for a missing mean, "-" for a
    missing SD."""
    if not math.isfinite(m):
        return "n/a"
    return f"{fmt(float(m), digits)} ({fmt(float(s), digits) if math.isfinite(s) else '-'})"


def pct(x: float | None, digits: int = 1, missing: str = "n/a") -> str:
    """``x`` (a fraction) as a percentage without the sign; ``missing`` for None / NaN."""
    if x is None or not math.isfinite(x):
        return missing
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


# ------------------------------------------------------------------ simulation settings
def noise_sigmas(label: str) -> tuple[float, float]:
    """(position [m], rotation [deg]) of a ``--noise`` label: default (``ExecutionNoise``'s
    defaults, the execution error of the environments and E04), none or MM:DEG."""
    if label == "default":
        from graspsim.sim.noise import ExecutionNoise

        d = ExecutionNoise()
        return d.position_sigma, round(math.degrees(d.rotation_sigma), 12)
    if label == "none":
        return 0.0, 0.0
    try:
        mm, deg = (float(x) for x in label.split(":"))
    except ValueError:
        raise ValueError(f"a noise condition is default, none or MM:DEG (e.g. 3:2), got {label!r}") from None
    if not (mm >= 0 and deg >= 0 and math.isfinite(mm + deg)):
        raise ValueError(f"--noise sigmas must be finite and >= 0, got {label!r}")
    return mm / 1000.0, deg


def experiment_database(db: str | os.PathLike | None, out: str | os.PathLike, config, *, threads: int | None = None):
    """The ``MapDatabase`` a run plans against, with the paper's five shapes
    (``PAPER_SHAPES``) built in it at ``config`` (a ``MapConfig``): ``db`` (a folder
    given with ``--db``) used as it is, or by default a private ``<out>/fsdb`` emptied
    and built fresh (seconds), so the run does not depend on what ran before it. Maps
    the planner builds for parts during the run are added to it."""
    from graspsim.maps.database import PAPER_SHAPES, MapDatabase

    root = Path(db) if db else Path(out) / "fsdb"
    if not db:
        shutil.rmtree(root, ignore_errors=True)
    database = MapDatabase(root, config=config)
    database.build(PAPER_SHAPES.values(), threads=threads)
    return database


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
