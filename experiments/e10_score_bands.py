"""E10's executed grasps by the robust score the planner gave them: per object set (its
conditions of one execution-error setting pooled), how many grasps in each score band
lifted their target and how many started in collision (any ``start_collision*`` cause);
per condition the same by what the grasp was planned from (box, features, other
primitives), for runs that record it; and per object the grasps under the top band, for
runs that record each grasp's target. Where the failures sit: a planner that ranks well
fails in its low bands, and a set falls short where its objects get only low-scored grasps.

Each argument is a published summary (a file, or ``REV:PATH`` as in ``e10_paired.py``).

    python experiments/e10_score_bands.py --runs experiments/reported/e10_clutter_removal.json \\
        experiments/reported/e10_clutter_removal.random.json
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start
from e10_paired import condition_label, load


@dataclass(frozen=True)
class Config:
    runs: tuple[str, ...] = opt((), "published summaries: files or REV:PATH")
    noise: str = opt("none", "execution error of the conditions counted", choices=("none", "default"))
    edges: tuple[float, ...] = opt((0.5, 0.85), "score band edges (ascending, within (0, 1))")


def band_names(edges) -> list[str]:
    lo = [0.0, *edges]
    return [f"< {edges[0]:g}"] + [f"{a:g} to {b:g}" for a, b in zip(lo[1:], lo[2:])] + [f">= {edges[-1]:g}"]


def grasps(condition: dict):
    """(score, cause, source or None, target or None) of every executed grasp, in order."""
    for e in condition["episodes"]:
        n = len(e["causes"])
        yield from zip(e["scores"], e["causes"], e.get("sources") or [None] * n, e.get("targets") or [None] * n)


def count(rows, edges) -> dict:
    """Per band name: grasps, lifted, started in collision."""
    names = band_names(edges)
    out = {b: {"grasps": 0, "lifted": 0, "start_collision": 0} for b in names}
    for score, cause, *_ in rows:
        b = out[names[sum(score >= x for x in edges)]]
        b["grasps"] += 1
        b["lifted"] += cause == "success"
        b["start_collision"] += cause.startswith("start_collision")
    return out


def score_bands(summaries: list[dict], noise: str = "none", edges=(0.5, 0.85)) -> dict:
    edges = tuple(float(x) for x in edges)
    if not edges or list(edges) != sorted(set(edges)) or not 0 < edges[0] <= edges[-1] < 1:
        raise SystemExit(f"e10_score_bands: --edges must ascend within (0, 1), got {list(edges)}")
    conds = [c for s in summaries for c in s["conditions"] if c["noise"] == noise]
    sets: dict = {}
    for c in conds:
        sets.setdefault(c.get("object_set", "mixed"), []).extend(grasps(c))
    by_source, below = {}, {}
    for c in conds:
        rows = list(grasps(c))
        if any(r[2] is not None for r in rows):  # a run that records sources records every grasp's
            group = [r[2] if r[2] in ("box", "features") else "other" for r in rows]
            by_source[condition_label(c)] = {src: count([r for r, g in zip(rows, group) if g == src], edges)
                                             for src in ("box", "features", "other") if src in group}
        if any(r[3] is not None for r in rows):
            low = Counter(r[3] for r in rows if r[0] < edges[-1])
            fail = Counter(r[3] for r in rows if r[0] < edges[-1] and r[1] != "success")
            every = Counter(r[3] for r in rows)
            below[condition_label(c)] = {o: {"grasps": every[o], "below": low[o], "below_failed": fail[o]}
                                         for o, _ in low.most_common()}
    return {"bands": band_names(edges), "sets": {k: count(v, edges) for k, v in sets.items()},
            "by_source": by_source, "below_top_by_object": below}


def _cell(b: dict) -> str:
    return f"{b['lifted']}/{b['grasps']}, {b['start_collision']} start coll." if b["grasps"] else "-"


def table(s: dict) -> str:
    head = "| {} | " + " | ".join(s["bands"]) + " |"
    L = [head.format("object set"), "|---" * (len(s["bands"]) + 1) + "|"]
    L += [f"| {k} | " + " | ".join(_cell(v[b]) for b in s["bands"]) + " |" for k, v in s["sets"].items()]
    if s["by_source"]:
        L += ["", head.format("condition | source"), "|---" * (len(s["bands"]) + 2) + "|"]
        L += [f"| {c} | {src} | " + " | ".join(_cell(v[b]) for b in s["bands"]) + " |"
              for c, srcs in s["by_source"].items() for src, v in srcs.items()]
    for c, objs in s["below_top_by_object"].items():
        L += ["", f"{c}: grasps under {s['bands'][-1][3:]} by object (of its grasps; failed): " + "; ".join(
            f"{o} {v['below']} of {v['grasps']} ({v['below_failed']})" for o, v in objs.items())]
    return "\n".join(L)


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    if not cfg.runs:
        raise SystemExit("e10_score_bands: --runs names one or more published summaries (a file or REV:PATH)")
    s = score_bands([load(r) for r in cfg.runs], cfg.noise, cfg.edges)
    record.write(out, {"config": cfg, **s})
    print(table(s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
