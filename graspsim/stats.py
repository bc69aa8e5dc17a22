"""Statistics, the library's one home for them: proportions' intervals (Wilson, and the
percentile intervals of pooled rates with whole clusters resampled), the exact McNemar
test of paired outcomes, the logistic fit (calibration's grade fits and the envs'
logistic policy share it), and binary trial outcomes against a score: ROC, reliability,
thresholds, bootstrap.

Pure numpy/scipy. A grasp is *accepted* at threshold t when its score is > t (the
paper's rule, grade > 0.7). Optional ``weights`` (N,) make every statistic a
population estimate from a stratified sample (inverse inclusion probabilities,
Horvitz-Thompson): with grasps drawn evenly over grade bins, unweighted precision and
recall describe the sample, weighted ones the map the sample was drawn from.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.special import expit
from scipy.stats import norm

from graspsim.errors import InvalidParameterError

__all__ = ["wilson_interval", "cluster_bootstrap_interval", "paired_cluster_difference_interval", "mcnemar",
           "roc_curve", "roc_auc", "fit_logistic", "logistic_predict", "reliability", "Reliability",
           "precision_recall", "threshold_for_precision", "youden_threshold", "bootstrap"]


def wilson_interval(k, n, confidence: float = 0.95):
    """Wilson score interval (lo, hi) of a proportion k / n; NaN where n = 0.

    Scalars give a pair of floats; arrays broadcast and give a pair of arrays.
    """
    scalar = np.ndim(k) == 0 and np.ndim(n) == 0
    k = np.asarray(k, float)
    n = np.asarray(n, float)
    z = norm.ppf(0.5 + 0.5 * confidence)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = k / n
        den = 1 + z * z / n
        mid = (p + z * z / (2 * n)) / den
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    lo = np.where(n > 0, np.clip(mid - half, 0, 1), np.nan)
    hi = np.where(n > 0, np.clip(mid + half, 0, 1), np.nan)
    return (float(lo), float(hi)) if scalar else (lo, hi)


def mcnemar(a: np.ndarray, b: np.ndarray) -> dict:
    """Exact McNemar test of paired successes a, b (E,) bool."""
    from scipy.stats import binomtest

    only_a, only_b = int(np.sum(a & ~b)), int(np.sum(~a & b))
    p = binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
    return {"only_first": only_a, "only_second": only_b, "p_exact": float(p)}


def cluster_bootstrap_interval(k, n, rng: np.random.Generator, *, reps: int = 4000,
                               confidence: float = 0.95) -> tuple[float, float]:
    """Percentile interval of a pooled rate sum(k) / sum(n) when whole clusters (k, n:
    successes and trials per cluster, e.g. per map) are resampled with replacement:
    trials within a cluster are not taken as independent."""
    k, n = np.asarray(k, float), np.asarray(n, float)
    idx = rng.integers(0, len(k), (reps, len(k)))
    tot = n[idx].sum(axis=1)
    rate = np.divide(k[idx].sum(axis=1), tot, out=np.full(reps, np.nan), where=tot > 0)
    a = 50.0 * (1.0 - confidence)
    lo, hi = np.nanpercentile(rate, [a, 100.0 - a])
    return float(lo), float(hi)


def paired_cluster_difference_interval(k1, n1, k0, n0, rng: np.random.Generator, *, reps: int = 4000,
                                       confidence: float = 0.95) -> tuple[float, float]:
    """Percentile interval of the difference of two pooled rates, sum(k1) / sum(n1) -
    sum(k0) / sum(n0), measured on the same clusters (e.g. the same scenes under two
    settings: k, n per cluster, aligned), when whole clusters are resampled with
    replacement, the same draw for both: the pairing and the correlation within a
    cluster are both kept."""
    k1, n1, k0, n0 = (np.asarray(a, float) for a in (k1, n1, k0, n0))
    if not (k1.shape == n1.shape == k0.shape == n0.shape) or k1.ndim != 1:
        raise ValueError("paired clusters: k1, n1, k0, n0 must be aligned 1-D arrays")
    idx = rng.integers(0, len(k1), (reps, len(k1)))
    t1, t0 = n1[idx].sum(axis=1), n0[idx].sum(axis=1)
    ok = (t1 > 0) & (t0 > 0)
    d = np.full(reps, np.nan)
    d[ok] = k1[idx].sum(axis=1)[ok] / t1[ok] - k0[idx].sum(axis=1)[ok] / t0[ok]
    a = 50.0 * (1.0 - confidence)
    lo, hi = np.nanpercentile(d, [a, 100.0 - a])
    return float(lo), float(hi)


def _check(scores, labels, weights=None):
    s = np.asarray(scores, float).reshape(-1)
    y = np.asarray(labels).reshape(-1).astype(bool)
    w = np.ones(len(s)) if weights is None else np.asarray(weights, float).reshape(-1)
    if not (len(s) == len(y) == len(w)):
        raise InvalidParameterError(
            f"scores, labels and weights must have one value per trial; got {len(s)}, {len(y)}, {len(w)}")
    if np.any(~np.isfinite(s)) or np.any(~np.isfinite(w)) or np.any(w < 0):
        raise InvalidParameterError("scores must be finite and weights finite and >= 0")
    return s, y, w


def _cumulative(s, y, w):
    """Distinct scores descending (T,) and the weighted positives / negatives with
    score >= each of them (T,)."""
    order = np.argsort(-s, kind="stable")
    s, y, w = s[order], y[order], w[order]
    last = np.r_[np.flatnonzero(np.diff(s) != 0), len(s) - 1]
    tp = np.cumsum(w * y)[last]
    fp = np.cumsum(w * ~y)[last]
    return s[last], tp, fp


def roc_curve(scores, labels, weights=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ROC (fpr, tpr, thresholds), each (T + 1,): point j accepts score >= thresholds[j]
    (thresholds[0] = +inf accepts nothing)."""
    s, y, w = _check(scores, labels, weights)
    u, tp, fp = _cumulative(s, y, w)
    P, Nn = tp[-1] if len(tp) else 0.0, fp[-1] if len(fp) else 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        tpr = np.r_[0.0, tp / P] if P > 0 else np.full(len(u) + 1, np.nan)
        fpr = np.r_[0.0, fp / Nn] if Nn > 0 else np.full(len(u) + 1, np.nan)
    return fpr, tpr, np.r_[np.inf, u]


def roc_auc(scores, labels, weights=None) -> float:
    """Area under the ROC curve (ties count one half); NaN without both classes."""
    fpr, tpr, _ = roc_curve(scores, labels, weights)
    if np.any(np.isnan(fpr)) or np.any(np.isnan(tpr)):
        return float("nan")
    return float(np.trapezoid(tpr, fpr)) if hasattr(np, "trapezoid") else float(np.trapz(tpr, fpr))


def fit_logistic(X, y, weights=None, *, l2: float = 0.0, max_iter: int = 100,
                 tol: float = 1e-10) -> np.ndarray:
    """Logistic regression by iteratively reweighted least squares (Newton).

    X: (N, K) features (an intercept column is added); y: (N,) 0/1; weights: (N,) >= 0;
    l2: ridge penalty on the K slopes (not the intercept), in units of the mean weighted
    log-loss. Returns (K + 1,) coefficients, intercept first.
    """
    X = np.asarray(X, float)
    if X.ndim == 1:
        X = X[:, None]
    y = np.asarray(y, float).reshape(-1)
    w = np.ones(len(y)) if weights is None else np.asarray(weights, float).reshape(-1)
    if len(X) != len(y) or len(w) != len(y):
        raise InvalidParameterError(f"X {X.shape}, y {y.shape}, weights {w.shape} disagree")
    A = np.column_stack([np.ones(len(X)), X])
    w = w / w.sum()
    pen = np.full(A.shape[1], 2.0 * l2)
    pen[0] = 0.0
    b = np.zeros(A.shape[1])
    for _ in range(max_iter):
        p = expit(A @ b)
        g = A.T @ (w * (p - y)) + pen * b
        H = (A * (w * p * (1 - p))[:, None]).T @ A + np.diag(pen) + 1e-12 * np.eye(len(b))
        step = np.linalg.solve(H, g)
        b -= step
        if np.max(np.abs(step)) < tol:
            break
    return b


def logistic_predict(b: np.ndarray, X) -> np.ndarray:
    X = np.asarray(X, float)
    if X.ndim == 1:
        X = X[:, None]
    return expit(b[0] + X @ np.asarray(b[1:], float))


@dataclass(frozen=True)
class Reliability:
    """Binned success rate vs score: edges (B + 1,), per bin n trials, k successes,
    rate k / n with its Wilson interval (lo, hi), mean score; NaN in empty bins."""

    edges: np.ndarray
    n: np.ndarray
    k: np.ndarray
    rate: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    mean_score: np.ndarray

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in self.__dataclass_fields__}


def reliability(scores, labels, edges=np.linspace(0.0, 1.0, 11),
                confidence: float = 0.95) -> Reliability:
    """Success rate per score bin [edges[i], edges[i+1]) (the last bin closed)."""
    s, y, _ = _check(scores, labels)
    edges = np.asarray(edges, float)
    b = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, len(edges) - 2)
    n = np.bincount(b, minlength=len(edges) - 1).astype(float)
    k = np.bincount(b, weights=y.astype(float), minlength=len(edges) - 1)
    ssum = np.bincount(b, weights=s, minlength=len(edges) - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rate, mean = k / n, ssum / n
    lo, hi = wilson_interval(k, n, confidence)
    return Reliability(edges, n, k, rate, lo, hi, mean)


def precision_recall(scores, labels, threshold: float, weights=None) -> tuple[float, float, float]:
    """(precision, recall, accepted fraction) of accepting score > threshold."""
    s, y, w = _check(scores, labels, weights)
    acc = s > threshold
    tp, pos, sel = np.sum(w * (acc & y)), np.sum(w * y), np.sum(w * acc)
    nan = float("nan")
    return (float(tp / sel) if sel > 0 else nan, float(tp / pos) if pos > 0 else nan,
            float(sel / w.sum()) if w.sum() > 0 else nan)


def threshold_for_precision(scores, labels, target: float = 0.97, weights=None, *,
                            min_count: int = 20) -> float:
    """Smallest threshold t at which accepting score > t reaches precision >= target
    with at least ``min_count`` trials accepted; -inf if accepting everything does,
    NaN if no such threshold exists. (Precision need not rise monotonically above t:
    the report gives the precision at the chosen t and its bootstrap interval.)"""
    if not 0.0 < target <= 1.0:
        raise InvalidParameterError(f"target precision must be in (0, 1], got {target!r}")
    s, y, w = _check(scores, labels, weights)
    u, tp, fp = _cumulative(s, y, w)
    n_ge = np.searchsorted(np.sort(-s), -u, side="right")  # trials with score >= u_j
    # candidate j accepts score > cand[j]: nothing (u_0), ..., everything (-inf)
    cand = np.r_[u, -math.inf]
    tp_gt, fp_gt, n_gt = np.r_[0.0, tp], np.r_[0.0, fp], np.r_[0, n_ge]
    with np.errstate(invalid="ignore", divide="ignore"):
        prec = tp_gt / (tp_gt + fp_gt)
    ok = np.flatnonzero((n_gt >= min_count) & (prec >= target - 1e-12))
    return float(cand[ok[-1]]) if len(ok) else float("nan")


def youden_threshold(scores, labels, weights=None) -> float:
    """Threshold t maximising tpr - fpr of accepting score > t (Youden's J)."""
    fpr, tpr, thr = roc_curve(scores, labels, weights)
    if np.any(np.isnan(fpr)) or np.any(np.isnan(tpr)):
        return float("nan")
    j = int(np.argmax(tpr - fpr))
    # accepting score >= thr[j] is accepting score > the next lower distinct score
    return float(thr[j + 1]) if j + 1 < len(thr) else -math.inf


def bootstrap(stat: Callable[[np.ndarray], float | np.ndarray], n_items: int, *,
              rng: np.random.Generator, n_boot: int = 500, strata=None,
              confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Percentile bootstrap interval (lo, hi) of ``stat(index)``, resampling item
    indices with replacement within ``strata`` (N,) labels (default: one stratum).
    Non-finite replicates are dropped."""
    strata = np.zeros(n_items, int) if strata is None else np.asarray(strata)
    groups = [np.flatnonzero(strata == g) for g in np.unique(strata)]
    reps = []
    for _ in range(n_boot):
        idx = np.concatenate([g[rng.integers(0, len(g), len(g))] for g in groups])
        reps.append(np.asarray(stat(idx), float))
    reps = np.array(reps)
    a = 0.5 * (1 - confidence)
    reps = np.where(np.isfinite(reps), reps, np.nan)
    with warnings.catch_warnings():  # a statistic undefined in every replicate: NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        lo = np.nanquantile(reps, a, axis=0)
        hi = np.nanquantile(reps, 1 - a, axis=0)
    return lo, hi
