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
        cfg, out, run = start(Config, __file__, argv, __doc__)  # --seed --per-case --kinds
        ...                                                     # --quick --out --publish
        print(run.write(out, {"config": cfg, ...}, readme_section))

    def readme_section(summary: dict) -> str: ...  # the README block (experiments/report.py)

What lives here, one of each:

* **The start of a run**: :func:`start` (``main``'s preamble: the config from the
  command line, logging, the :class:`RunRecord` and the output folder);
  :func:`task_results` (a run's tasks on its worker processes, in order) and
  :func:`resident_run_database` (a process's one read-only database).
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
* **Maps and scenes** (``_scenes.py``): :func:`map_config` (the default or the quick
  runs' coarse maps), :func:`standing_cloud` (an object standing on the table at a
  random yaw, seen as a (single-view) cloud).
* **Timing** (``_timing.py``): :class:`Clock`, :func:`stopwatch`, :func:`load_average`,
  :func:`run_fresh` (a command in a fresh process: wall, CPU, peak RSS) and
  :func:`run_cli_fresh` (``graspsim ARGS`` so, with the process's own peak RSS).
* **Text**: ``fmt`` and ``md_table`` (:mod:`graspsim.calibration.markdown`),
  :func:`mean_sd_text`, :func:`pct`, :func:`rate_ci`.
* **Simulation settings** (``_scenes.py``): :func:`noise_sigmas`.
* **The FS map database** (``_scenes.py``): :func:`experiment_database` (unless ``--db`` names one, a
  private ``<out>/fsdb`` built fresh from the paper's five shapes at the script's map
  config, so a rerun from a clean clone starts from the same maps, never the user's
  shared database another run has grown), :func:`database_record`,
  :func:`database_note`; :func:`build_grid` (a size grid of maps, :data:`GRID`, stored
  before a run) and :class:`RunDatabase` (the database read only during a run: what no
  stored map serves is built in memory, never stored).

Everything is imported from here (``from _common import ...``); ``_scenes.py`` and
``_timing.py`` hold parts of it. The statistics of the paper's table 2 (mixed ANOVA,
Bonferroni post-hoc) are in ``_stats.py``.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import argparse
import dataclasses
import json
import logging
import math
import os
import shlex
import subprocess
import sys
import types
import typing
from multiprocessing import get_context
from pathlib import Path

from _scenes import (
    GRID,
    RunDatabase,
    build_grid,
    database_note,
    database_record,
    experiment_database,
    grid_shapes,
    map_config,
    noise_sigmas,
    resident_run_database,
    standing_cloud,
)
from _timing import Clock, host_reference, load_average, run_cli_fresh, run_fresh, stopwatch

from graspsim._jsonable import to_jsonable
from graspsim.calibration.markdown import fmt, md_table
from graspsim.calibration.outputs import library_versions, write_json, write_text
from graspsim.contacts import DEFAULT_CONTACTS
from graspsim.seeding import derived_seed, rng_for, seed_sequence

__all__ = ["start", "opt", "parse_config", "RunRecord", "machine_load", "provenance", "default_out",
           "rng_for", "derived_seed", "seed_sequence", "map_config", "standing_cloud",
           "Clock", "stopwatch", "load_average", "host_reference", "reference_clause", "run_fresh", "run_cli_fresh",
           "write_json", "write_text", "write_config", "fmt", "md_table", "mean_sd_text", "pct", "rate_ci",
           "noise_sigmas", "experiment_database", "database_record", "database_note", "RunDatabase", "GRID",
           "grid_shapes", "build_grid", "resident_run_database", "task_results"]

EXPERIMENTS = Path(__file__).resolve().parent


# ------------------------------------------------------------------ config -> CLI
def opt(default, help: str = "", *, choices=None, cli: bool = True, const=None):
    """A config field with its CLI help (``cli=False``: no flag; ``const``: the flag may
    come alone, meaning this value, as ``--flag [VALUE]``)."""
    return dataclasses.field(default=default, metadata={"help": help, "choices": choices, "cli": cli,
                                                        "const": const})


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
    if f.metadata.get("const") is not None:  # --flag [VALUE]: alone, the const
        kw = {**kw, "nargs": "?", "const": f.metadata["const"]}
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


#: logging formats of :func:`start`: plain messages, or with level and logger name
PLAIN, NAMED = "%(message)s", "%(levelname)s %(name)s: %(message)s"


def start(cls, script: str, argv=None, description: str | None = None, *, log_format: str | None = PLAIN,
          quiet: tuple[str, ...] = ()):
    """``(config, out, record)``: the preamble of every script's ``main``. The config
    from the command line (:func:`parse_config`), INFO logging in ``log_format`` (None:
    left as it is) with the loggers named in ``quiet`` at WARNING, the :class:`RunRecord` (started now; its
    :meth:`~RunRecord.write` publishes when ``--publish`` was given) and the output folder
    ``--out`` (a ``Path``, created)."""
    cfg, opts = parse_config(cls, script, argv, description)
    if log_format is not None:
        logging.basicConfig(level=logging.INFO, format=log_format)
    for name in quiet:
        logging.getLogger(name).setLevel(logging.WARNING)
    record = RunRecord(script, argv, publish=opts.publish)
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    return cfg, out, record


# ------------------------------------------------------------------ the summary
def default_out(script: str) -> str:
    """``results/<stem>``: where a script writes by default (``report.py --collect``
    looks there)."""
    return f"results/{Path(script).stem}"


def provenance() -> dict:
    """Code state the results came from: git commit (``-dirty`` if the working tree has
    uncommitted changes: the tree is shared, so say so; the published summaries in
    ``experiments/reported/`` do not count: they are results, which ``--publish`` itself
    writes, not code), graspsim version, CPU count."""

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], capture_output=True, text=True, cwd=EXPERIMENTS,
                              timeout=10).stdout.strip()

    try:
        commit = git("describe", "--always") or None
        code = ("--", ":/", ":(exclude,top)experiments/reported")
        if commit and git("status", "--porcelain", "--untracked-files=no", *code):
            commit += "-dirty"
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"commit": commit, "graspsim": graspsim.__version__, "cpus": os.cpu_count()}


def run_study(cls, script: str, run, readme_section, argv=None, description: str | None = None) -> int:
    """The whole ``main`` of a study whose result is one dict: :func:`start`, ``run(config)``,
    the record written (and published with ``--publish``) with ``readme_section``, and that
    section printed."""
    cfg, out, record = start(cls, script, argv, description)
    res = run(cfg)
    record.write(out, {"config": cfg, **res}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


def task_results(fn, tasks: list, workers: int):
    """``fn`` of each task, in the tasks' order, on ``workers`` spawned processes (1: in
    this one), yielded as each is done; the pool is closed when the caller is done."""
    pool = get_context("spawn").Pool(workers) if workers > 1 else None
    try:
        yield from (pool.imap(fn, tasks) if pool is not None else map(fn, tasks))
    finally:
        if pool is not None:
            pool.close()
            pool.join()


def load_sentence(summary: dict) -> str:
    """The sentence 'Load average A at the start, B at the end, N cores.' of a run's summary,
    with the host's reference time (:func:`reference_clause`) where the run recorded it."""
    m = summary["machine"]
    return (f"Load average {m['load_avg_start'][0]:.1f} at the start, {m['load_avg_end'][0]:.1f} at the end, "
            f"{m['cpus']} cores{reference_clause(summary)}.")


def reference_clause(summary: dict) -> str:
    """", host reference R ms (...)" of a run that recorded ``machine.reference_s``
    (:func:`~_timing.host_reference`); empty for runs made before it was recorded."""
    r = summary.get("machine", {}).get("reference_s")
    if r is None:
        return ""
    return (f", host reference {1000 * r:.0f} ms (a fixed workload timed as the run ended: timings of "
            "two runs compare where it matches)")


def contacts_clause(config: dict, lead: str = "; ") -> str:
    """The contact model a run simulated (its ``config["contacts"]``, graspsim.sim.contact_model)
    as a clause of its block: empty for ``stiff``, the default; a run that recorded none or
    ``"default"`` ran before ``stiff`` became the default, on the ``soft`` model."""
    name = config.get("contacts", "default")
    name = "soft" if name == "default" else name
    if name == DEFAULT_CONTACTS:
        return ""
    return (f"{lead}the {name!r} contact model (graspsim.sim.contact_model; 2 ms steps and softer pads, the default "
            "until 'stiff' replaced it)")


class RunRecord:
    """The record every experiment's ``summary.json`` carries: the exact command line,
    machine facts (cores, load average at the start and the end, wall and CPU time),
    library versions and the git commit (``-dirty``: uncommitted changes) when it
    started. Start it before the work; :meth:`write` at the end (``publish``: whether
    :meth:`write` also publishes by default)."""

    def __init__(self, script: str, argv=None, *, publish: bool = False) -> None:
        self.stem = Path(script).stem
        self.publish = bool(publish)
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
                            "cpu_s": self.clock.cpu, "reference_s": host_reference(),
                            "platform": versions.pop("platform", None), "date": versions.pop("date", None)},
                "versions": versions, "provenance": self.provenance}

    def write(self, out: str | Path, data: dict, readme_section=None, *, publish: bool | None = None,
              config=None) -> str:
        """Write ``out/summary.json`` (:meth:`summary` of ``data``), ``out/README.md``
        (``readme_section(summary)``), ``out/config.json`` (``config``, or
        ``data["config"]``) and, with ``publish`` (default: the record's),
        ``experiments/reported/<key>.json`` (:meth:`report_key`). Returns the markdown
        ("" without ``readme_section``)."""
        publish = self.publish if publish is None else publish
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
            write_json(EXPERIMENTS / "reported" / f"{self.report_key(out)}.json", summary)
        return text

    def report_key(self, out: str | Path) -> str:
        """The reported JSON's name: ``STEM.VARIANT`` when the results folder is
        ``STEM.VARIANT`` (a second configuration of the script, as ``experiments/report.py``
        names its blocks), else the script's stem."""
        name = Path(out).name
        return name if name.startswith(f"{self.stem}.") and len(name) > len(self.stem) + 1 else self.stem


def machine_load(summary: dict) -> tuple[list, list]:
    """(load average at the start, at the end) of a summary (the benchmarks' older
    summaries say ``load_before`` / ``load_after``)."""
    m = summary["machine"]
    return (m.get("load_avg_start", m.get("load_before")) or [math.nan],
            m.get("load_avg_end", m.get("load_after")) or [math.nan])


def write_config(path: Path, cfg) -> None:
    """``write_json`` of a config (kept for scripts that call it by this name)."""
    write_json(path, cfg)



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
