"""What a grade says about success: the calibration report of one or more scores.

For every score (the paper's grade, a calibrated grade, single components) on the
feasible trials of a :class:`TrialTable`: ROC AUC (of the sample, and of the map
population via the sampling weights) with a bootstrap interval, per-object AUCs, the
binned reliability curve with Wilson intervals and a fitted logistic P(success | score),
the threshold reaching a target precision and the Youden-optimal threshold (bootstrap
intervals), and precision / recall at a reference threshold (the paper's 0.7). The
bootstrap resamples trials within each case. Precision, recall and thresholds are
population estimates (weighted); the reliability curve is conditional on the score and
needs no weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from graspsim import stats
from graspsim.calibration.trial_table import TrialTable
from graspsim.errors import InvalidParameterError

__all__ = ["ScoreReport", "CalibrationReport", "score_report", "calibrate", "base_rates", "attempt_precision"]


@dataclass(frozen=True)
class ScoreReport:
    """Calibration of one score; thresholds accept score > t. ``*_ci``: (lo, hi)."""

    name: str
    auc: float
    auc_ci: tuple[float, float]
    auc_population: float
    auc_by_group: dict
    reliability: stats.Reliability
    logistic: tuple[float, float]
    target_precision: float
    threshold: float
    threshold_ci: tuple[float, float]
    youden: float
    youden_ci: tuple[float, float]
    at: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "reliability"}
        d["reliability"] = self.reliability.to_dict()
        return _clean(d)


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return None if not math.isfinite(float(o)) else float(o)
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    return o


def _operating_point(s, y, w, t) -> dict:
    p, r, a = stats.precision_recall(s, y, t, w)
    acc = s > t
    k, n = int(np.sum(acc & y)), int(np.sum(acc))
    lo, hi = stats.wilson_interval(k, n)
    return {"threshold": t, "precision": p, "recall": r, "accepted_fraction": a,
            "kept_successes": float(np.sum(w * (acc & y))), "trials_accepted": n,
            "successes_accepted": k, "sample_precision_ci": (float(lo), float(hi))}


def score_report(name: str, scores, success, weights=None, groups=None, strata=None, *,
                 target: float = 0.97, reference: dict | None = None, n_boot: int = 500,
                 rng: np.random.Generator | None = None, edges=np.linspace(0, 1, 11),
                 min_count: int = 20) -> ScoreReport:
    """Report of one score over trials: scores, success (N,); weights (N,) population
    weights; groups (N,) objects for per-object AUCs; strata (N,) bootstrap strata;
    reference: {label: threshold} operating points to report (e.g. {"paper_0.7": 0.7}), with
    bootstrap intervals of their precision and recall."""
    s = np.asarray(scores, float)
    y = np.asarray(success, bool)
    w = np.ones(len(s)) if weights is None else np.asarray(weights, float)
    if len(s) == 0:
        raise InvalidParameterError(f"no trials to calibrate {name!r} on")
    rng = rng or np.random.default_rng(0)
    groups = np.zeros(len(s), int) if groups is None else np.asarray(groups)
    by_group = {str(g): stats.roc_auc(s[groups == g], y[groups == g]) for g in np.unique(groups)}
    t_target = stats.threshold_for_precision(s, y, target, w, min_count=min_count)
    t_youden = stats.youden_threshold(s, y, w)

    refs = dict(reference or {})

    def boot(idx):
        out = [stats.roc_auc(s[idx], y[idx]),
               stats.threshold_for_precision(s[idx], y[idx], target, w[idx], min_count=min_count),
               stats.youden_threshold(s[idx], y[idx], w[idx])]
        for t in refs.values():
            out += stats.precision_recall(s[idx], y[idx], t, w[idx])[:2]
        return out

    lo, hi = stats.bootstrap(boot, len(s), rng=rng, n_boot=n_boot, strata=strata)
    b = stats.fit_logistic(s, y.astype(float))
    at = {}
    for j, (label, t) in enumerate(refs.items()):
        at[label] = {**_operating_point(s, y, w, t),
                     "precision_ci": (float(lo[3 + 2 * j]), float(hi[3 + 2 * j])),
                     "recall_ci": (float(lo[4 + 2 * j]), float(hi[4 + 2 * j]))}
    at["target"] = _operating_point(s, y, w, t_target)
    at["youden"] = _operating_point(s, y, w, t_youden)
    return ScoreReport(
        name=name, auc=stats.roc_auc(s, y), auc_ci=(float(lo[0]), float(hi[0])),
        auc_population=stats.roc_auc(s, y, w), auc_by_group=by_group,
        reliability=stats.reliability(s, y, edges), logistic=(float(b[0]), float(b[1])),
        target_precision=target, threshold=t_target, threshold_ci=(float(lo[1]), float(hi[1])),
        youden=t_youden, youden_ci=(float(lo[2]), float(hi[2])), at=at)


@dataclass(frozen=True)
class CalibrationReport:
    """Scores' reports over the feasible trials of a table, plus the trial summary
    (counts per outcome, START_COLLISION apart) and single-feature AUCs."""

    scores: dict
    summary: dict
    components: dict

    def to_dict(self) -> dict:
        return _clean({"summary": self.summary, "components": self.components,
                       "scores": {k: v.to_dict() for k, v in self.scores.items()}})

    def markdown(self) -> str:
        from graspsim.calibration.markdown import report_markdown

        return report_markdown(self)


def calibrate(table: TrialTable, scores: dict | None = None, *, target: float = 0.97,
              reference: dict | None = None, n_boot: int = 500, seed: int = 0,
              components: tuple[str, ...] = ()) -> CalibrationReport:
    """Calibrate ``scores`` ({report name: column}, default {"paper": "grade"}) on the
    feasible trials of ``table``. ``reference``: {label: threshold or {score name:
    threshold}} operating points to report (default: the paper's 0.7 for every score). ``components``: columns whose
    single-feature AUC (higher = better; a leading "-" negates) is reported."""
    from graspsim.sim.outcomes import TrialOutcome

    scores = scores or {"paper": "grade"}
    reference = {"at_0.7": 0.7} if reference is None else reference
    feas = table.feasible
    t = table.select(feas)
    counts = {o.label: int(np.sum(table["outcome"] == o)) for o in TrialOutcome}
    y = t["success"].astype(bool)
    summary = {"trials": len(table), "feasible": int(feas.sum()), "counts": counts,
               "success_rate": float(y.mean()) if len(y) else float("nan"),
               "success_rate_population": float(np.sum(t["weight"] * y) / np.sum(t["weight"]))
               if len(y) else float("nan"),
               "cases": int(len(np.unique(table["case"]))), "groups": int(len(np.unique(table["group"])))}
    lo, hi = stats.wilson_interval(int(y.sum()), len(y))
    summary["success_ci"] = (float(lo), float(hi))
    summary.update(base_rates(table))
    rng = np.random.default_rng(seed)
    def ref_for(name):  # a reference value is a threshold or {score name: threshold}
        return {k: (v[name] if isinstance(v, dict) else v) for k, v in reference.items()
                if not isinstance(v, dict) or name in v}

    out = {name: score_report(name, t[col], y, t["weight"], t["group"], t["case"], target=target,
                              reference=ref_for(name), n_boot=n_boot, rng=rng)
           for name, col in scores.items()}
    for name, col in scores.items():  # the same operating points, START_COLLISION a failure
        for op in out[name].at.values():
            op.update(attempt_precision(table, col, op["threshold"]))
    comp = {}
    for c in components:
        col = c.lstrip("-")
        if col in t:
            v = -t[col] if c.startswith("-") else t[col]
            comp[c] = {"auc": stats.roc_auc(v, y), "auc_population": stats.roc_auc(v, y, t["weight"])}
    return CalibrationReport(out, summary, comp)


def _success_all(table: TrialTable) -> np.ndarray:
    """(N,) bool: SUCCESS, every other outcome (START_COLLISION included) a failure."""
    from graspsim.sim.outcomes import TrialOutcome

    return np.asarray(table["outcome"]) == TrialOutcome.SUCCESS


def base_rates(table: TrialTable) -> dict:
    """The base rate: success of all the table's drawn grasps under its condition, as a
    population estimate (sampling weights) -- per feasible trial (``base_rate``) and per
    attempt, START_COLLISION counted as a failure (``base_rate_attempts``: a pose that
    execution noise pushes into collision is a failed grasp) -- with the sample counts."""
    w = np.asarray(table["weight"], float)
    y = _success_all(table)
    feas = np.asarray(table.feasible)
    k, n_f, n = int(y.sum()), int(feas.sum()), len(y)
    return {"base_rate": float(np.sum(w * y) / np.sum(w[feas])) if n_f else float("nan"),
            "base_rate_attempts": float(np.sum(w * y) / np.sum(w)) if n else float("nan"),
            "base_successes": k, "base_feasible": n_f, "base_attempts": n,
            "start_collision": n - n_f}


def attempt_precision(table: TrialTable, col: str, threshold: float) -> dict:
    """Precision of ``col > threshold`` over every attempt (START_COLLISION a failure):
    population estimate and the sample's successes / trials accepted."""
    w = np.asarray(table["weight"], float)
    acc = np.asarray(table[col], float) > threshold
    y = _success_all(table)
    return {"precision_attempts": float(np.sum(w * (acc & y)) / np.sum(w * acc)) if acc.any() else float("nan"),
            "successes_accepted_attempts": int(np.sum(acc & y)), "trials_accepted_attempts": int(acc.sum())}
