"""Long fuzz run (nightly style): the fuzz suite's properties with many more examples.

The same properties as ``tests/fuzz`` (clouds and cloud files, primitive dimensions
and memory budgets, corrupted map files, output paths, option values, database
content, and the memory-capped worst cases), each run by hypothesis with a seed and
an example count scaled from its CI count. A failing input does not stop the run:
it is recorded with its exception and a reproducer (the case's repr and a pickled
copy that ``--replay`` runs again), and generation goes on.

    python experiments/fuzz_long.py [--scale 10] [--seed 0] [--only NAME ...]
                                    [--out results/fuzz_long] [--publish]
    python experiments/fuzz_long.py --replay results/fuzz_long/failures/0.pkl

Writes ``summary.json`` (inputs tried per category, outcomes per property, failures
with reproducers, wall time, machine load) and ``README.md`` to ``--out``.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import base64
import collections
import pickle
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(REPO / "tests"))
from _common import machine_load, opt, start  # noqa: E402 (after the sys.path lines, which need REPO)

MAX_FAILURES_KEPT = 5  # per distinct failure (property, exception type, place)


def _place(exc: BaseException) -> str:
    """The innermost frame of graspsim (else the innermost) where ``exc`` was raised."""
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if "/graspsim/" in f.filename] or frames
    f = ours[-1] if ours else None
    return f"{Path(f.filename).name}:{f.lineno} ({f.name})" if f else "?"


def run_property(prop, examples: int, seed: int, failures: list, out: Path) -> dict:
    """Run one property for ``examples`` generated inputs; failures are recorded, not raised."""
    from fuzz.registry import hypothesis_settings
    from hypothesis import given
    from hypothesis import seed as hseed

    outcomes: collections.Counter = collections.Counter()
    seen: collections.Counter = collections.Counter()

    @hseed(seed)
    @hypothesis_settings(examples, derandomize=False)
    @given(case=prop.strategy())
    def run(case):
        try:
            outcomes[prop.check(case)] += 1
        except BaseException as exc:  # noqa: BLE001 - every failure is a finding
            if isinstance(exc, KeyboardInterrupt):
                raise
            outcomes["FAILED"] += 1
            key = (prop.name, type(exc).__name__, _place(exc))
            seen[key] += 1
            if seen[key] <= MAX_FAILURES_KEPT:
                path = out / "failures" / f"{len(failures)}.pkl"
                path.parent.mkdir(parents=True, exist_ok=True)
                blob = pickle.dumps({"property": prop.name, "case": case})
                path.write_bytes(blob)
                failures.append({"property": prop.name, "error": type(exc).__name__, "place": key[2],
                                 "message": str(exc)[:600], "case": repr(case)[:1500],
                                 "replay": f"python experiments/fuzz_long.py --replay {path}",
                                 "case_pickle_b64": base64.b64encode(blob).decode() if len(blob) < 20000 else None})

    t0 = time.perf_counter()
    run()
    return {"examples_asked": examples, "outcomes": dict(outcomes), "seconds": time.perf_counter() - t0,
            "distinct_failures": [{"error": k[1], "place": k[2], "count": v} for k, v in seen.items()]}


def _default_budget(failures: list) -> list[dict]:
    """The maps that fill the default memory budget: peak resident memory of each."""
    import shutil

    from fuzz.assets import assets
    from fuzz.props_memory import DEFAULT_BUDGET_JOBS, run_default_budget_jobs

    print("[fuzz_long] default-budget worst cases", file=sys.stderr, flush=True)
    folder = assets().fresh()
    try:
        results = run_default_budget_jobs(folder)
        return [{"argv": r.argv, "exit": r.code, "seconds": r.seconds, "peak_rss_mib": r.peak_rss / 2**20,
                 "growth_mib": r.growth / 2**20, "message": r.err.strip()[-300:]} for r in results]
    except AssertionError as exc:
        failures.append({"property": "default_budget", "error": "AssertionError", "place": "run_default_budget_jobs",
                         "message": str(exc)[:600], "case": repr(DEFAULT_BUDGET_JOBS)})
        return []
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def replay(path: str) -> int:
    from fuzz.registry import all_properties

    data = pickle.loads(Path(path).read_bytes())
    prop = all_properties()[data["property"]]
    print(f"{prop.name}: {data['case']!r}"[:3000])
    print("outcome:", prop.check(data["case"]))
    return 0


def readme_section(summary: dict) -> str:
    h = summary["headline"]
    rows = ["| category | inputs |", "|---|---|"]
    rows += [f"| {k} | {v:,} |" for k, v in sorted(summary["inputs_per_category"].items())]
    fails = summary["failures"]
    m = summary["machine"]
    load_start, load_end = machine_load(summary)
    text = ("\n".join(rows) + "\n\n"
            f"{h['inputs']:,} generated inputs ({h['properties']} properties, seed {summary['seed']}; a damaged "
            "database counts once per command run on it, a memory batch once per job), "
            f"{h['failing_inputs']} failing ({h['distinct_failures']} distinct failures) in "
            f"{h['wall_s'] / 60:.0f} min on {m['cpus']} cores (load average {load_start[0]} before, "
            f"{load_end[0]} after). A failing input is one that raised anything but a GraspsimError, "
            "printed a traceback or more than one error line, leaked a warning, changed a file although it "
            "failed, stored or loaded an invalid map, or ran past its memory or time limit.")
    if fails:
        text += "\n\n" + "\n".join(f"- {f['property']}: {f['error']} at {f['place']}" for f in fails[:10])
    worst = summary.get("default_budget_worst_cases") or []
    if worst:
        text += ("\n\nUnder the default memory budget (half the RAM, at most 3.5 GiB), one after another in "
                 "one process (peak: its resident memory's high-water mark, reset before each command): "
                 + "; ".join(f"`graspsim {' '.join(Path(t).name if '/' in t else t for t in w['argv'][:6])}` "
                             f"exit {w['exit']}, peak {w['peak_rss_mib'] / 1024:.2f} GiB (grew "
                             f"{w['growth_mib'] / 1024:.2f} GiB)" for w in worst) + ".")
    return text + f"\n\n`{summary['command']}`"


@dataclass(frozen=True)
class Config:
    scale: float = opt(10.0, "examples per property = scale x its CI count")
    seed: int = opt(0, "hypothesis seed")
    only: tuple[str, ...] = opt((), "run only these properties (default: all)")
    replay: str | None = opt(None, "run one recorded failure again (a .pkl of --out/failures)")
    default_budget: bool = opt(True, "also the maps that fill the default memory budget (a few minutes)")

    def __post_init__(self) -> None:
        if not self.scale > 0:
            raise ValueError(f"--scale must be > 0, got {self.scale}")


def main(argv: list[str] | None = None) -> int:
    a, out, run = start(Config, __file__, argv, __doc__, log_format=None)
    if a.replay:
        return replay(a.replay)
    from fuzz.harness import COUNTS
    from fuzz.registry import all_properties

    props = all_properties()
    names = list(a.only) or list(props)
    unknown = sorted(set(names) - set(props))
    if unknown:
        print(f"fuzz_long: unknown properties {unknown}; valid: {sorted(props)}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    failures: list = []
    per_property = {}
    for name in names:
        prop = props[name]
        n = max(1, round(a.scale * prop.examples))
        print(f"[fuzz_long] {name}: {n} examples", file=sys.stderr, flush=True)
        per_property[name] = run_property(prop, n, a.seed, failures, out)
        print(f"[fuzz_long] {name}: {per_property[name]['outcomes']} in {per_property[name]['seconds']:.0f} s",
              file=sys.stderr, flush=True)
    default_budget = _default_budget(failures) if a.default_budget else None
    data = {
        "config": a, "seed": a.seed, "scale": a.scale,
        "headline": {"inputs": sum(COUNTS.values()), "properties": len(names),
                     "failing_inputs": sum(p["outcomes"].get("FAILED", 0) for p in per_property.values()),
                     "distinct_failures": sum(len(p["distinct_failures"]) for p in per_property.values()),
                     "wall_s": time.perf_counter() - t0,
                     "denominator": "generated inputs run through the properties (each counted once)"},
        "inputs_per_category": dict(COUNTS), "properties": per_property, "failures": failures,
        "default_budget_worst_cases": default_budget,
    }
    print(run.write(out, data, readme_section))
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
