"""Markdown tables of calibration reports and success rates."""

from __future__ import annotations

import math

__all__ = ["md_table", "report_markdown", "fmt"]


def fmt(v, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, (tuple, list)) and len(v) == 2:
        return f"[{fmt(v[0], digits)}, {fmt(v[1], digits)}]"
    if isinstance(v, float):
        if math.isnan(v):
            return "–"
        if math.isinf(v):
            return "-inf" if v < 0 else "inf"
        return f"{v:.{digits}f}"
    return str(v)


def md_table(header, rows) -> str:
    out = ["| " + " | ".join(str(h) for h in header) + " |",
           "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(fmt(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def report_markdown(rep) -> str:
    s = rep.summary
    lines = [f"Trials: {s['trials']} ({s['feasible']} feasible, "
             f"{s['counts'].get('start_collision', 0)} START_COLLISION reported apart), "
             f"{s['cases']} cases, {s['groups']} objects. Success of feasible trials: "
             f"{fmt(s['success_rate'])} {fmt(s['success_ci'])} (sample), "
             f"{fmt(s['success_rate_population'])} (map population). Base rate, the success of all "
             f"table-clear grasps of the maps (population estimate): {fmt(s['base_rate'])} per feasible "
             f"trial, {fmt(s['base_rate_attempts'])} per attempt (START_COLLISION counted as failed).", "",
             "Outcomes: " + ", ".join(f"{k} {v}" for k, v in s["counts"].items()), ""]
    rows = []
    for name, r in rep.scores.items():
        rows.append([name, r.auc, r.auc_ci, r.auc_population, r.threshold, r.threshold_ci,
                     r.youden, r.youden_ci])
    lines += [md_table(["score", "AUC", "95% CI", "AUC (population)",
                        f"t for precision {fmt(next(iter(rep.scores.values())).target_precision, 2)}",
                        "CI", "Youden t", "CI"], rows), ""]
    rows = []
    for name, r in rep.scores.items():
        for label, op in r.at.items():
            rows.append([name, label, op["threshold"], op["precision"], op.get("precision_ci"),
                         op.get("precision_attempts"), s["base_rate"], op["recall"], op.get("recall_ci"),
                         op["accepted_fraction"], f"{op['successes_accepted']}/{op['trials_accepted']}"])
    lines += ["Operating points (population estimates, bootstrap 95 % intervals; accept score > t; "
              "precision per feasible trial and per attempt, beside the base rate; last column: "
              "successes / feasible trials accepted in the sample):", "",
              md_table(["score", "point", "t", "precision", "CI", "precision (attempts)", "base rate",
                        "recall", "CI", "accepted", "sample"], rows), ""]
    if rep.components:
        lines += ["Single-feature AUCs (sample / population):", "",
                  md_table(["feature", "AUC", "AUC (population)"],
                           [[k, v["auc"], v["auc_population"]] for k, v in rep.components.items()]), ""]
    for name, r in rep.scores.items():
        rel = r.reliability
        rows = [[f"{rel.edges[i]:.1f}–{rel.edges[i + 1]:.1f}", int(rel.n[i]), rel.rate[i],
                 (rel.lo[i], rel.hi[i])] for i in range(len(rel.n)) if rel.n[i] > 0]
        lines += [f"Reliability of {name} (logistic fit: a = {fmt(r.logistic[0])}, "
                  f"b = {fmt(r.logistic[1])}):", "",
                  md_table(["score bin", "trials", "success", "95% Wilson"], rows), ""]
        groups = r.auc_by_group
        lines += [f"AUC of {name} per object: " + ", ".join(f"{g} {fmt(a)}" for g, a in groups.items()), ""]
    return "\n".join(lines)
