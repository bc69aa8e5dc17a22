"""The statistics of the paper's table 2 for the experiment scripts: mean and SD,
split-plot (mixed) ANOVA with the Greenhouse-Geisser correction, Bonferroni-adjusted
paired post-hoc tests, and their markdown. Not part of the library (``import _stats``
from a script); the library's statistics (McNemar, cluster-bootstrap intervals, Wilson)
are :mod:`graspsim.stats`."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import math

import numpy as np
from scipy import stats

__all__ = ["mean_sd", "mixed_anova", "paired_posthoc", "p_text", "tests_markdown"]


def mean_sd(x) -> tuple[float, float]:
    """Mean and sample SD (ddof 1, as R's sd) of the finite values; NaN if none."""
    a = np.asarray([v for v in x if v is not None], float)
    a = a[np.isfinite(a)]
    if len(a) == 0:
        return math.nan, math.nan
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else math.nan


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


def p_text(p: float | None) -> str:
    """A p value as the tables print it: "< .0001", "0.0123" or "n/a"."""
    return "n/a" if p is None or not math.isfinite(p) else ("< .0001" if p < 1e-4 else f"{p:.4f}")


def tests_markdown(tests: dict, metrics: list[tuple[str, str]], within: str = "algorithm",
                   between: str = "direction") -> list[str]:
    """Markdown lines of the mixed ANOVA and the post-hoc tests of each metric
    (``tests[key]``: {"anova": ..., "posthoc": ...} or {"skipped": why}); ``metrics``:
    (key, label) pairs."""
    L = ["", f"## Mixed ANOVA ({within} within, {between} between, variants as subjects)", "",
         "| metric | effect | F (df) | p | p (Greenhouse-Geisser) |", "|---|---|---|---|---|"]
    for k, lbl in metrics:
        t = tests[k]
        if "skipped" in t:
            L.append(f"| {lbl} | - | skipped: {t['skipped']} | | |")
            continue
        for eff, name in (("within", within), ("between", between), ("interaction", f"{within} x {between}")):
            e = t["anova"][eff]
            gg = p_text(e["p_gg"]) + f" (eps {e['gg_epsilon']:.2f})" if "p_gg" in e else ""
            L.append(f"| {lbl} | {name} | {e['F']:.2f} ({e['df']:g}, {e['df_error']:g}) | {p_text(e['p'])} | {gg} |")
    L += ["", f"## Post-hoc: paired t-tests of the {within}s, Bonferroni-adjusted", "",
          "| metric | pair | mean difference | t (df) | p (Bonferroni) |", "|---|---|---|---|---|"]
    for k, lbl in metrics:
        t = tests[k]
        if "skipped" in t:
            continue
        for ph in t["posthoc"]:
            L.append(f"| {lbl} | {ph['a']} - {ph['b']} | {ph['mean_diff']:.2f} | "
                     f"{ph['t']:.2f} ({ph['df']}) | {p_text(ph['p_bonferroni'])} |")
    return L
