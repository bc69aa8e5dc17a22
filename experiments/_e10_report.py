"""E10's README block (``readme_section``, rendered by ``experiments/report.py`` from the
summary): the conditions' table, the field's form (GSR and DR per seed, mean +- std over
seeds, beside GIGA's and EdgeGraspNet's published simulated numbers), the failure table
per object and where the planning time goes."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

from _common import contacts_clause, database_note, pct, rate_ci, reference_clause

from graspsim.tabletop.clutter import FAILURE_COLUMNS, OTHER, failure_rows

__all__ = ["readme_section", "rows_of", "literature_lines", "failure_lines", "source_lines", "PUBLISHED"]


def _label(c: dict) -> str:
    if c["ablation"] == "no_neighbours":
        return "no neighbour check"
    if c["ablation"] == "ground_truth":
        return "ground-truth segmentation"
    if c["ablation"] == "no_feel":
        return "no felt evidence (ClutterConfig.feel off)"
    return "with execution error" if c["noise"] == "default" else "no execution error"


#: Published simulated clutter removal, percent (GSR, DR; None: not given), as issue 34
#: quotes them, for reference only: other simulators (PyBullet), grippers and object sets,
#: each paper's own protocol (see the papers).
PUBLISHED = {
    ("GIGA (Jiang et al. 2021)", "packed"): (87.9, 86.0),
    ("GIGA (Jiang et al. 2021)", "pile"): (69.8, 51.1),
    ("EdgeGraspNet (Huang et al. 2022)", "packed"): (92.3, None),
    ("EdgeGraspNet (Huang et al. 2022)", "pile"): (92.3, 92.8),
}


#: The object set of a summary written before object sets were conditions (E10's old default).
OLD_SET = "mixed"


def rows_of(s: dict) -> list[dict]:
    """The summary's condition rows, each with its object set and its per-seed statistics
    (:func:`graspsim.tabletop.clutter_stats.per_seed`'s form). A summary written before
    object sets and seeds were conditions ran one set (its ``config.object_set``, else
    "mixed", the old default) and one seed (``config.seed``): its rows say so."""
    cfg = s.get("config", {})
    out = []
    for r in s["conditions"]:
        r = {"object_set": cfg.get("object_set", OLD_SET), **r}
        if not r.get("per_seed"):
            gsr = r["successes"] / r["attempts"] if r["attempts"] else None
            dr = r["removed"] / r["placed"] if r["placed"] else None
            r["per_seed"] = [{"seed": int(cfg.get("seed", 0)), "scenes": r["scenes"], "grasps": r["attempts"],
                              "successes": r["successes"], "placed": r["placed"], "removed": r["removed"],
                              "gsr": gsr, "dr": dr}]
            r["gsr_over_seeds"] = {"mean": gsr, "std": 0.0 if gsr is not None else None, "seeds": int(gsr is not None)}
            r["dr_over_seeds"] = {"mean": dr, "std": 0.0 if dr is not None else None, "seeds": int(dr is not None)}
        out.append(r)
    return out


def _ms(d: dict | None) -> str:
    """mean ± sample std (seeds) of a rate over seeds; one seed has no spread to show."""
    if not d or d.get("mean") is None:
        return "n/a"
    n = d.get("seeds", d.get("n", 0))
    return f"{100 * d['mean']:.1f}" + (f" ± {100 * d['std']:.1f}" if n > 1 and d.get("std") is not None
                                       else "") + f" ({n})"


def _sum_tables(tables: list[dict], counts: tuple[str, ...], tallies: tuple[str, ...]) -> dict:
    """Failure tables (``summarize``'s ``per_object`` or ``per_source``) summed row by row:
    the ``counts`` added, the ``tallies`` (cause -> n) merged; in first-seen order."""
    out: dict[str, dict] = {}
    for t in tables:
        for name, r in t.items():
            o = out.setdefault(name, {**{k: 0 for k in counts}, **{k: {} for k in tallies}})
            for k in counts:
                o[k] += r[k]
            for k in tallies:
                for why, n in r[k].items():
                    o[k][why] = o[k].get(why, 0) + n
    return out


def _merge_tables(tables: list[dict]) -> dict:
    """Per-object failure tables (``summarize``'s ``per_object``) summed, ordered as it orders them."""
    out = _sum_tables(tables, ("placed", "removed", "grasps", "lifted"), ("failed", "left"))
    return dict(sorted(out.items(), key=lambda kv: (-(kv[1]["placed"] - kv[1]["removed"]),
                                                    -(kv[1]["grasps"] - kv[1]["lifted"]), kv[0])))


def literature_lines(rows: list) -> list[str]:
    """The field's form: per object set and kind (5 objects, full method), GSR and DR
    mean +- std over seeds, each seed's, and the published numbers beside them."""
    L = ["| object set | scene | objects | condition | seeds x scenes | GSR mean ± std (seeds) | "
         "DR mean ± std (seeds) | per seed GSR / DR |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["ablation"] is not None:
            continue
        seeds = r.get("per_seed") or []
        each = "; ".join(f"{pct(x['gsr'], 0)} / {pct(x['dr'], 0)}" for x in seeds) or "-"
        n = f"{len(seeds)} x {max((x['scenes'] for x in seeds), default=0)}"
        L.append(f"| {r['object_set']} | {r['kind']} | {r['objects']} | {_label(r)} | {n} | "
                 f"{_ms(r.get('gsr_over_seeds'))} | {_ms(r.get('dr_over_seeds'))} | {each} |")
    L += ["", "Published simulated numbers, for reference only (PyBullet, their grippers and object sets, 5 "
          "objects per scene; GSR / DR %): "
          + "; ".join(f"{who} {kind} {g}" + ("" if d is None else f" / {d}") for (who, kind), (g, d)
                      in PUBLISHED.items())
          + ". EdgeGraspNet's packed figure is one number as quoted in issue 34 (its DR not given there)."]
    return L


def failure_lines(rows: list) -> list[str]:
    """The failure table per object, per object set, pooled over its conditions with the
    full method (every kind, size and execution error)."""
    L = []
    for o in dict.fromkeys(r["object_set"] for r in rows):
        t = _merge_tables([r.get("per_object", {}) for r in rows if r["object_set"] == o
                           and r["ablation"] is None])
        if not t:
            continue
        L += ["", f"Per object, {o} (the full method's conditions pooled): grasps aimed at it (the target: the "
              "object most of the chosen segment's points show), failed grasps by cause, objects left on the table "
              "by why (judged on the last look: not seen, merged with a neighbour, split, no grasp planned, "
              "excluded: its planned grasps all on a failed grasp's contacts, not "
              "tried before the episode stopped, off the table):", "",
              "| " + " | ".join(FAILURE_COLUMNS) + " |", "|" + "---|" * len(FAILURE_COLUMNS)]
        L += ["| " + " | ".join(str(x) for x in row) + " |" for row in failure_rows(t)]
    return L


def source_lines(rows: list) -> list[str]:
    """The grasps by what they were planned from (``summarize``'s ``per_source``: a part's
    primitive or the segment's own features), per object set and kind, pooled over the
    full method's conditions; nothing for runs that did not record it."""
    L = []
    for o, kind in dict.fromkeys((r["object_set"], r["kind"]) for r in rows):
        t = _sum_tables([r.get("per_source") or {} for r in rows
                         if (r["object_set"], r["kind"]) == (o, kind) and r["ablation"] is None],
                        ("grasps", "lifted"), ("failed",))
        if not t:
            continue
        if not L:
            L += ["", "Grasps by what they were planned from (an identified part's primitive, or the segment's own "
                  "features), the full method's conditions pooled:", "",
                  "| object set | scene | source | grasps | lifted | failed grasps |", "|---|---|---|---|---|---|"]
        for src, v in sorted(t.items(), key=lambda kv: (-kv[1]["grasps"], kv[0])):
            failed = ", ".join(f"{k} {n}" for k, n in sorted(v["failed"].items())) or "none"
            L.append(f"| {o} | {kind} | {src} | {v['grasps']} | {v['lifted']} ({pct(v['lifted'] / v['grasps'])} %) "
                     f"| {failed} |")
    return L


def _memory_note(rows: list) -> str:
    keys = {k for r in rows for k in r.get("built_in_memory", ())}
    return f" {len(keys)} FS maps were built in memory during the run (parts no stored map serves; not stored)." \
        if "built_in_memory" in rows[0] else ""


def _median(spread: dict | None) -> str:
    if not spread or spread.get("median") is None:
        return "n/a"
    return f"{spread['median']:.2f} s ({spread['count']})"


def _per_grasp(p: dict) -> str:
    """Every grasp's planning over the grasps (the mean over grasps: the planning a
    clearing run spends per grasp, first frames included)."""
    return "n/a" if p.get("mean") is None else f"{p['mean']:.2f} s"


def readme_section(s: dict) -> str:
    """The README's E10 block (see ``experiments/report.py``)."""
    rows = rows_of(s)
    short = [r for r in rows if not r.get("complete", s.get("complete"))]
    sets = ", ".join(f'"{o}"' for o in dict.fromkeys(r["object_set"] for r in rows))
    L = [f"`{s['command']}`: the scenes per condition are in the table"
         + ("" if not short else f" ({len(short)} of {len(rows)} conditions did not run all the scenes asked: "
            "the run was cut short, each row holds the scenes it finished)")
         + f"; objects from the {sets} set(s), one D435-like depth camera with sensor noise; "
         + (f"simulated with {cl}; " if (cl := contacts_clause(s.get("config", {}), lead="")) else "")
         + "grasps until the table is clear, two failures in a row, or no grasp found. GSR = grasps that lifted "
         "their target / grasps; a grasp that lifted another object is no success (its own column; the object "
         "leaves the table and counts in DR). DR = objects removed / placed (95 % Wilson intervals; grasps of "
         "one scene are correlated, so the intervals understate the spread between scenes). Planning per grasp: "
         "median seconds from the depth frame to the ranked grasps of the whole scene, in the first frame of a "
         "scene and in later frames (which reuse the plans of segments that did not change), and per grasp: "
         "the planning of every grasp's frame over the grasps (what clearing a scene spends per grasp).", "",
         "| object set | scene | objects | condition | scenes (of asked) | GSR | other object lifted | DR | "
         "cleared scenes | one cluster (first frame) | planning: first frame / later / per grasp | failure causes |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        causes = ", ".join(f"{k} {v}" for k, v in r["failure_causes"].items() if k != OTHER) or "none"
        seg = r["segmentation"]
        p = r["planning_s"]
        L.append(f"| {r['object_set']} | {r['kind']} | {r['objects']} | {_label(r)} | "
                 f"{r['scenes']} ({r.get('target', '-')}) | "
                 f"{rate_ci(r['successes'], r['attempts'], r['gsr_interval_95'])} | "
                 f"{r.get('other_objects', 'n/a')} | "
                 f"{rate_ci(r['removed'], r['placed'], r['cleared_interval_95'])} | {r['scenes_cleared']} | "
                 f"{pct(seg['share'], 1)} % ({seg['one_cluster']}/{seg['objects_seen']}) | "
                 f"{_median(p.get('first_frame'))} / {_median(p.get('later_frames'))} / {_per_grasp(p)} | {causes} |")
    L += ["", "In the field's form (GSR and DR per seed, mean ± sample std over the seeds; one seed: no spread):",
          "", *literature_lines(rows)]
    L += failure_lines(rows)
    L += source_lines(rows)
    lost = [(r, k) for r in rows for k in r.get("skipped", [])]
    if lost:
        L += ["", "Skipped (not counted above): " + "; ".join(
            f"{r['object_set']} {r['kind']} {r['objects']} {_label(r)}, seed "
            f"{k.get('seed', r['per_seed'][0]['seed'])} scene {k['scene']}: {k['reason']}" for r, k in lost) + "."]
    L += ["", "Where the planning time goes (median seconds per grasp, `plan_scene`'s stages; medians, so "
          "they do not add up to the planning column's per-grasp figure, a mean over every grasp that counts "
          "first frames, a process's first scene and FS maps built in memory in full): table fit, "
          "segmentation, identification of every segment, maps and robust scores of every segment "
          "(including FS maps built in memory for parts no stored map serves):", "",
          "| object set | scene | objects | condition | table | segmentation | identification | maps + scores "
          "| total |",
          "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        st = r["planning_s"].get("stages_median") or {}
        cells = " | ".join("n/a" if k not in st else f"{st[k]:.2f}" for k in ("table", "segment", "identify",
                                                                            "plan", "total"))
        L.append(f"| {r['object_set']} | {r['kind']} | {r['objects']} | {_label(r)} | {cells} |")
    m = s["machine"]
    L += ["", f"Planning = depth frame to ranked grasps for the whole scene (table, segmentation, identification "
          f"of every segment, maps, robust scores against the scene), measured at load "
          f"{m['load_avg_start'][0] if m.get('load_avg_start') else 'n/a'} (start) to "
          f"{m['load_avg_end'][0] if m.get('load_avg_end') else 'n/a'} (end) on {m['cpus']} cores"
          f"{reference_clause(s)}."
          + database_note(s) + _memory_note(rows)]
    return "\n".join(L) + "\n"
