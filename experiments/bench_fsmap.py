"""Benchmark: full-scale map generation as a user meets it, per primitive.

For each of the paper's five primitives and each thread count (all cores, one):

* cold: ``graspsim map PRIMITIVE ... -o X.h5`` in a fresh process with an empty numba
  cache (the first run on a machine: the kernels compile);
* fresh: the same command with a warm cache (``--repeat`` runs, medians): the time the
  command reports for generation and the process's wall time, CPU time and peak RSS;
* in-process: ``generate_fs_map`` repeated in one process after a warm-up (medians),
  with the collision hierarchy rebuilt every run (``clear_caches``) and reused.

Then the startup costs (``import graspsim``, ``graspsim --help``, ``graspsim info MAP``:
fresh processes, medians) and, with ``--db``, the FS database build that the demo and
the planner run on first use (``graspsim db build``: serially in one process as the demo
does, with the default two worker processes, and serially on a cold numba cache).

    python experiments/bench_fsmap.py [--repeat 3] [--db] [--publish]
    python experiments/bench_fsmap.py --quick --out results/bench_fsmap-quick   # a coarse cylinder only

Results: results/bench_fsmap/summary.json (and rows.json, table.md); --publish copies
the summary to experiments/reported/bench_fsmap.json (what the README quotes). Cold runs
compile into empty temporary folders (NUMBA_CACHE_DIR); the others use the user's numba
cache, warmed first (``graspsim warmup``).
Wall times depend on what else runs: the load average is recorded before and after
every measurement; CPU time (all threads) measures the work itself.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import math
import multiprocessing as mp
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import load_average, machine_load, opt, run_fresh, start, write_json

README_DIMS = {"radius": 0.02, "height": 0.2}  # the README's example cylinder
QUICK_FLAGS = ("--surface-step", "0.02", "--rotation-step-deg", "30")
PRIMITIVES = ("cylinder", "box", "sphere", "cone", "half_toroid")


@dataclass(frozen=True)
class BenchConfig:
    repeat: int = opt(3, "runs per measurement (median)")
    startup_repeat: int = opt(7, "fresh processes per startup measurement (median)")
    primitives: tuple[str, ...] = opt(PRIMITIVES, choices=PRIMITIVES)
    threads: tuple[int, ...] = opt((0, 1), "thread counts (0: all cores)")
    cold: bool = opt(True, "time a first run on an empty compile cache")
    db: bool = opt(False, "also time the FS database build")
    quick: bool = opt(False, "coarse maps (2 cm / 30 deg)", cli=False)
    QUICK: ClassVar[dict] = {"repeat": 1, "startup_repeat": 1, "primitives": ("cylinder",), "threads": (1,),
                             "cold": False, "quick": True}

    def __post_init__(self) -> None:
        if self.repeat < 1 or self.startup_repeat < 1 or min(self.threads) < 0:
            raise ValueError(f"--repeat and --startup-repeat must be >= 1, --threads >= 0; got {self.repeat}, "
                             f"{self.startup_repeat}, {self.threads}")


def _graspsim_cmd() -> list[str]:
    """The console script a user runs (beside this interpreter), else the same via -c."""
    script = Path(sys.executable).parent / "graspsim"
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from graspsim.cli import main; sys.exit(main())"]


def _child(argv: list[str], env: dict | None = None) -> dict:
    """:func:`run_fresh` of ``argv``; a failure stops the benchmark."""
    r = run_fresh(argv, env)
    if r.pop("exit") != 0:
        raise RuntimeError(f"{' '.join(argv)} failed:\n{r['stderr'][-2000:]}")
    return r


def _median(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def _map_argv(name: str, threads: int, out: Path, quick: bool) -> list[str]:
    from graspsim.maps.database import PAPER_SHAPES

    dims = README_DIMS if name == "cylinder" else PAPER_SHAPES[name].dims
    argv = _graspsim_cmd() + ["map", name, "-o", str(out), "--json"]
    argv += [x for k, v in dims.items() for x in (f"--{k.replace('_', '-')}", repr(v))]
    argv += ["--threads", str(threads)] if threads else []
    return argv + (list(QUICK_FLAGS) if quick else [])


def _cache_env(cache: str | None) -> dict:
    """NUMBA_CACHE_DIR for a cold run (an empty folder); None: the user's own cache."""
    return {"NUMBA_CACHE_DIR": cache} if cache else {}


def _cli_map(name: str, threads: int, cache: str | None, out: Path, quick: bool) -> dict:
    r = _child(_map_argv(name, threads, out, quick), _cache_env(cache))
    s = json.loads(r.pop("stdout").strip().splitlines()[-1])
    r["compile_notice"] = "compiling map kernels" in r.pop("stderr")
    return {**r, "generation_s": s["seconds"], "grasps": s["grasps"], "timing": s.get("timing")}


def _in_process(name: str, threads: int, repeat: int, quick: bool, queue) -> None:
    """Spawned worker: in-process generation times (kernels loaded beforehand)."""
    import resource

    from graspsim.maps.database import PAPER_SHAPES
    from graspsim.maps.generate import clear_caches, generate_fs_map
    from graspsim.maps.kernels import default_threads, ensure_compiled
    from graspsim.maps.map_config import MapConfig
    from graspsim.primitives import Cylinder

    ensure_compiled()
    shape = Cylinder(**README_DIMS) if name == "cylinder" else PAPER_SHAPES[name]
    cfg = MapConfig(surface_step=0.02, rotation_step=math.radians(30)) if quick else MapConfig()
    used = default_threads(threads or None)
    generate_fs_map(Cylinder(0.02, 0.05), config=cfg, threads=used)  # first-call effects
    out = {}
    for mode in ("rebuilt", "reused"):
        runs = []
        for _ in range(repeat):
            if mode == "rebuilt":
                clear_caches()
            t0, c0, load0 = time.perf_counter(), time.process_time(), load_average()
            gmap = generate_fs_map(shape, config=cfg, threads=used)
            runs.append({"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                         "load_before": load0})
            del gmap
        out[mode] = {"generation_s": _median(runs, "wall_s"), "cpu_s": _median(runs, "cpu_s"),
                     "load_before": runs[0]["load_before"], "runs": runs}
    out["threads"] = used
    out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    queue.put(out)


def _spawned(fn, *args):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=fn, args=(*args, q))
    p.start()
    result = q.get()
    p.join()
    return result


def bench_primitive(name: str, threads: int, cfg: BenchConfig, tmp: Path) -> dict:
    """One row: cold process, fresh processes on a warm cache, in-process."""
    row: dict = {"primitive": name, "threads": threads or os.cpu_count()}
    out = tmp / f"{name}.h5"
    if cfg.cold:
        cold_cache = tempfile.mkdtemp(dir=tmp)
        row["cold"] = _cli_map(name, threads, cold_cache, out, cfg.quick)
    fresh = [_cli_map(name, threads, None, out, cfg.quick) for _ in range(cfg.repeat)]
    row["fresh"] = {k: _median(fresh, k) for k in ("generation_s", "wall_s", "cpu_s", "peak_rss_mb")}
    row["fresh"]["runs"] = fresh
    row["fresh"]["load_before"] = fresh[0]["load_before"]
    row["grasps"] = fresh[0]["grasps"]
    row["map_mb"] = out.stat().st_size / 2**20
    row["in_process"] = _spawned(_in_process, name, threads, cfg.repeat, cfg.quick)
    gen = row["in_process"]["rebuilt"]["generation_s"]
    row["fresh_wall_over_in_process"] = row["fresh"]["wall_s"] / gen
    row["fresh_generation_over_in_process"] = row["fresh"]["generation_s"] / gen
    # the same in CPU time (all threads), which the machine's load hardly moves
    row["fresh_cpu_over_in_process"] = row["fresh"]["cpu_s"] / row["in_process"]["rebuilt"]["cpu_s"]
    return row


def bench_startup(cfg: BenchConfig, map_file: Path) -> dict:
    """Fresh-process times of what a user types first (medians of startup_repeat)."""
    cases = {"import graspsim": [sys.executable, "-c", "import graspsim"],
             "python -c pass": [sys.executable, "-c", "pass"],
             "graspsim --help": _graspsim_cmd() + ["--help"],
             "graspsim map --help": _graspsim_cmd() + ["map", "--help"],
             "graspsim info MAP": _graspsim_cmd() + ["info", str(map_file)]}
    out = {}
    for name, argv in cases.items():
        runs = [_child(argv) for _ in range(cfg.startup_repeat)]
        out[name] = {"median_s": _median(runs, "wall_s"), "min_s": min(r["wall_s"] for r in runs),
                     "max_s": max(r["wall_s"] for r in runs), "runs": len(runs),
                     "load_before": runs[0]["load_before"], "load_after": runs[-1]["load_after"]}
    return out


def bench_db(tmp: Path) -> dict:
    """``graspsim db build`` of the five paper maps into an empty folder, as the demo
    does on first use (serial), with the default local workers, and on a cold cache."""
    out = {}
    for case, executor, cache in (("serial", "serial", None), ("local", "local", None),
                                  ("serial_cold_cache", "serial", tempfile.mkdtemp(dir=tmp))):
        root = tmp / f"db_{case}"
        r = _child(_graspsim_cmd() + ["db", "build", "--db", str(root), "--executor", executor,
                                      "--json"], _cache_env(cache))
        maps = json.loads(r.pop("stdout").strip().splitlines()[-1])["maps"]
        r.pop("stderr")
        out[case] = {**r, "maps": len(maps), "sum_map_seconds": sum(m["seconds"] for m in maps)}
    return out


def main(argv: list[str] | None = None) -> int:
    cfg, out, run = start(BenchConfig, __file__, argv, __doc__, log_format=None)
    tmp = Path(tempfile.mkdtemp(prefix="bench_fsmap-"))
    try:
        _child(_graspsim_cmd() + ["warmup"])  # the user's cache: warm from here on
        rows = [bench_primitive(n, t, cfg, tmp) for n in cfg.primitives for t in cfg.threads]
        startup = bench_startup(cfg, tmp / f"{cfg.primitives[0]}.h5")
        db = bench_db(tmp) if cfg.db else None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    text = run.write(out, _summary(cfg, rows, startup, db), readme_section)
    write_json(out / "rows.json", rows)
    (out / "table.md").write_text(text + "\n")
    print(text)
    return 0


def _summary(cfg, rows, startup, db) -> dict:
    keep = ("generation_s", "wall_s", "cpu_s", "peak_rss_mb", "load_before", "load_after",
            "compile_notice")
    table = [{"primitive": r["primitive"], "threads": r["threads"], "grasps": r["grasps"],
              "map_mb": r["map_mb"],
              "cold": {k: v for k, v in r["cold"].items() if k in keep} if "cold" in r else None,
              "fresh": {k: v for k, v in r["fresh"].items() if k != "runs"},
              "in_process": {m: {k: r["in_process"][m][k] for k in ("generation_s", "cpu_s", "load_before")}
                             for m in ("rebuilt", "reused")} | {
                  "peak_rss_mb": r["in_process"]["peak_rss_mb"]},
              "fresh_wall_over_in_process": r["fresh_wall_over_in_process"],
              "fresh_generation_over_in_process": r["fresh_generation_over_in_process"],
              "fresh_cpu_over_in_process": r["fresh_cpu_over_in_process"]}
             for r in rows]
    first = table[0]
    return {
        "headline": {  # the first row: the README's cylinder on all cores unless configured
            "primitive": first["primitive"], "threads": first["threads"],
            "cold_generation_s": (first["cold"] or {}).get("generation_s"),
            "cold_wall_s": (first["cold"] or {}).get("wall_s"),
            "fresh_generation_s": first["fresh"]["generation_s"],
            "fresh_wall_s": first["fresh"]["wall_s"],
            "in_process_generation_s": first["in_process"]["rebuilt"]["generation_s"],
            "fresh_wall_over_in_process": first["fresh_wall_over_in_process"],
            "fresh_cpu_over_in_process": first["fresh_cpu_over_in_process"],
            "import_graspsim_s": startup["import graspsim"]["median_s"],
            "help_s": startup["graspsim --help"]["median_s"],
            "info_s": startup["graspsim info MAP"]["median_s"],
            "db_build_serial_s": db["serial"]["wall_s"] if db else None},
        "config": cfg,
        "denominators": "medians of config.repeat fresh processes / in-process runs per row "
                        "(startup: of config.startup_repeat processes); one cold process per row",
        "rows": table, "startup": startup, "db_build": db}


def _s(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def readme_section(summary: dict) -> str:
    """Markdown for the README: per-primitive times, startup, database build."""
    before, after = machine_load(summary)
    lines = [f"`{summary['command']}` (load {before[0]:.1f} before, "
             f"{after[0]:.1f} after; {summary['machine']['cpus']} cores; "
             "medians)", "",
             "| primitive | threads | grasps | first run (empty compile cache): generation / wall s "
             "| `graspsim map`: generation / wall s | in-process: generation s (CPU s) "
             "| `graspsim map` / in-process: wall (CPU) | peak RSS MB |",
             "|---|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        c, f, p = r["cold"] or {}, r["fresh"], r["in_process"]["rebuilt"]
        lines.append(f"| {r['primitive']} | {r['threads']} | {r['grasps']:,} | "
                     f"{_s(c.get('generation_s'))} / {_s(c.get('wall_s'))} | "
                     f"{_s(f['generation_s'])} / {_s(f['wall_s'])} | "
                     f"{_s(p['generation_s'])} ({_s(p['cpu_s'])}) | "
                     f"{r['fresh_wall_over_in_process']:.1f} ({r['fresh_cpu_over_in_process']:.1f}) | "
                     f"{f['peak_rss_mb']:.0f} |")
    st = summary["startup"]
    lines += ["", "Startup (fresh processes): " + ", ".join(
        f"`{k}` {v['median_s']:.2f} s" for k, v in st.items()) + "."]
    db = summary.get("db_build")
    if db:
        lines += ["", f"FS database (the five paper maps) built on first use: "
                      f"{db['serial']['wall_s']:.0f} s serially as the demo does "
                      f"(`graspsim db build --executor serial`), {db['local']['wall_s']:.0f} s with "
                      f"the default worker processes, {db['serial_cold_cache']['wall_s']:.0f} s "
                      "serially on a machine's first run (kernels compiling)."]
    return "\n".join(lines)


def headline(summary: dict) -> str:
    """The README's headline line (see ``experiments/report.py``)."""
    h = summary["headline"]
    return (f"An FS map of the paper's {h['primitive']} in {h['in_process_generation_s']:.1f} s of generation "
            f"in a warm process, {h['fresh_wall_s']:.1f} s wall for `graspsim map` in a fresh one "
            f"({h['threads']} threads); the paper's five-map database in {h['db_build_serial_s']:.0f} s on first use.")

if __name__ == "__main__":
    sys.exit(main())
