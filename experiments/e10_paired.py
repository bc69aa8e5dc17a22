"""Two E10 runs compared scene by scene: how many episodes are the same, and how the rest
moved -- the paired comparison results.md quotes when a block is re-run ("769 of the 800
episodes are the same as at be26750").

Each argument is a published summary: a file (``experiments/reported/KEY.json`` or a run's
``summary.json``) or ``REV:PATH``, the file as committed at git revision REV. Episodes are
paired by condition (object set, kind, objects, execution error, ablation), seed and
scene; a condition in only one of the runs is named and skipped. *Same*: the attempts'
causes in order and the objects removed are equal (the grasps themselves may differ). Of
the episodes that changed, those the earlier run had ended with no grasp planned are
counted apart: a change that only acts where a frame has no grasp (the scene planner's
feature-grasp fallback) can change those alone, the rest is the machine or the code.

    python experiments/e10_paired.py --base 759a455:experiments/reported/e10_clutter_removal.json \\
        --new experiments/reported/e10_clutter_removal.json
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start

ROOT = Path(__file__).resolve().parent.parent
KEY = ("object_set", "kind", "objects", "noise", "ablation")


@dataclass(frozen=True)
class Config:
    base: str = opt("", "the earlier run's summary: a file or REV:PATH (a file as committed at git revision REV)")
    new: str = opt("", "the later run's summary: a file or REV:PATH")


def load(spec: str) -> dict:
    """A summary from a file, or from ``REV:PATH`` in the repository's history."""
    path = Path(spec)
    if path.is_file():
        return json.loads(path.read_text())
    rev, sep, rel = spec.partition(":")
    if not sep:
        raise SystemExit(f"e10_paired: {spec} is not a file (nor REV:PATH, a file as committed)")
    got = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{rel}"], capture_output=True, text=True)
    if got.returncode:
        raise SystemExit(f"e10_paired: {spec}: {got.stderr.strip().splitlines()[-1] if got.stderr else 'not found'}")
    return json.loads(got.stdout)


def condition_label(c: dict) -> str:
    noise = "with execution error" if c["noise"] == "default" else "no execution error"
    return (f"{c.get('object_set', 'mixed')} {c['kind']} of {c['objects']}, {noise}"
            + (f", ablation {c['ablation']}" if c.get("ablation") else ""))


def compare(base: dict, new: dict) -> tuple[list[dict], list[str]]:
    """Per condition in both runs: episodes paired, same, more / fewer objects removed,
    as many removed by other attempts, and GSR / DR of the paired episodes before and
    after; and the labels of conditions in only one run."""
    def conditions(s: dict) -> dict:
        return {tuple(c.get(k, "mixed" if k == "object_set" else None) for k in KEY): c for c in s["conditions"]}

    a, b = conditions(base), conditions(new)
    rows = []
    for key in [k for k in a if k in b]:
        ea = {(e["seed"], e["scene"]): e for e in a[key]["episodes"]}
        eb = {(e["seed"], e["scene"]): e for e in b[key]["episodes"]}
        pairs = [(ea[k], eb[k]) for k in ea if k in eb]
        alike = [x["causes"] == y["causes"] and x["removed"] == y["removed"] for x, y in pairs]
        same = sum(alike)
        ended = [x.get("stop") == "no_grasp" for x, _ in pairs]
        tot = {f"{w}_{q}": sum(p[i][q] for p in pairs) for i, w in ((0, "base"), (1, "new"))
               for q in ("successes", "attempts", "removed", "placed")}
        rows.append({"condition": condition_label(b[key]), "paired": len(pairs), "same": same,
                     "more_removed": sum(y["removed"] > x["removed"] for x, y in pairs),
                     "fewer_removed": sum(y["removed"] < x["removed"] for x, y in pairs),
                     "otherwise": sum(y["removed"] == x["removed"] and x["causes"] != y["causes"] for x, y in pairs),
                     "base_no_grasp": sum(ended), "changed_no_grasp": sum(e and not s for e, s in zip(ended, alike)),
                     **tot})
    only = [condition_label(c) for k, c in {**a, **b}.items() if (k in a) != (k in b)]
    return rows, only


def _rate(k: int, n: int) -> str:
    return f"{100 * k / n:.1f}" if n else "-"


def table(rows: list[dict]) -> str:
    L = ["| condition | paired episodes | same | more removed | fewer removed | as many, otherwise | changed, of the "
         "before run's no-grasp ends | GSR before -> after | DR before -> after |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        L.append(f"| {r['condition']} | {r['paired']} | {r['same']} | {r['more_removed']} | {r['fewer_removed']} | "
                 f"{r['otherwise']} | {r['changed_no_grasp']} of {r['base_no_grasp']} | "
                 f"{_rate(r['base_successes'], r['base_attempts'])} -> "
                 f"{_rate(r['new_successes'], r['new_attempts'])} | {_rate(r['base_removed'], r['base_placed'])} -> "
                 f"{_rate(r['new_removed'], r['new_placed'])} |")
    L.append(f"\nIn all: {sum(r['same'] for r in rows)} of {sum(r['paired'] for r in rows)} paired episodes the same.")
    return "\n".join(L)


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    if not cfg.base or not cfg.new:
        raise SystemExit("e10_paired: --base and --new name the two runs' summaries (a file or REV:PATH)")
    base, new = load(cfg.base), load(cfg.new)
    rows, only = compare(base, new)
    text = table(rows)
    record.write(out, {"config": cfg, "rows": rows, "only_in_one": only})
    print(text)
    for label in only:
        print(f"only in one run (skipped): {label}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
