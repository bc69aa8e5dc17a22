"""Calibration figures (PNG, matplotlib Agg): reliability, ROC, threshold vs a parameter."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from graspsim import stats
from graspsim.plots import pyplot

__all__ = ["plot_reliability", "plot_roc", "plot_threshold_sweep"]


def plot_reliability(reports: dict, path: str | os.PathLike, title: str = "") -> None:
    """Binned success rate (Wilson bars) and the fitted logistic curve per score;
    ``reports``: {label: ScoreReport}."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    x = np.linspace(0, 1, 201)
    for i, (label, r) in enumerate(reports.items()):
        rel = r.reliability
        ok = rel.n > 0
        c = f"C{i}"
        ax.errorbar(rel.mean_score[ok], rel.rate[ok],
                    yerr=np.maximum(0.0, [rel.rate[ok] - rel.lo[ok], rel.hi[ok] - rel.rate[ok]]),
                    fmt="o", color=c,
                    capsize=3, label=f"{label} (binned, 95 % Wilson)")
        ax.plot(x, stats.logistic_predict(np.array(r.logistic), x), color=c, lw=1.2,
                label=f"{label} logistic fit")
        if np.isfinite(r.threshold):
            ax.axvline(r.threshold, color=c, ls=":", lw=1)
    ax.axvline(0.7, color="k", ls="--", lw=0.8, label="paper threshold 0.7")
    ax.set(xlabel="grade", ylabel="P(success)", ylim=(0, 1.02), xlim=(0, 1), title=title)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_roc(curves: dict, path: str | os.PathLike, title: str = "") -> None:
    """ROC curves; ``curves``: {label: (scores, success, weights or None)}."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 5))
    for label, (s, y, w) in curves.items():
        fpr, tpr, _ = stats.roc_curve(s, y, w)
        ax.plot(fpr, tpr, label=f"{label} (AUC {stats.roc_auc(s, y, w):.3f})")
    ax.plot([0, 1], [0, 1], color="0.6", ls=":")
    ax.set(xlabel="false positive rate", ylabel="true positive rate", xlim=(0, 1), ylim=(0, 1),
           title=title)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_threshold_sweep(x: Sequence[float], series: dict, path: str | os.PathLike, *,
                         xlabel: str, title: str = "") -> None:
    """Thresholds (with intervals) against a swept parameter; ``series``:
    {label: (values (K,), lo (K,), hi (K,))}."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for i, (label, (v, lo, hi)) in enumerate(series.items()):
        v, lo, hi = (np.asarray(a, float) for a in (v, lo, hi))
        err = np.nan_to_num(np.maximum(0.0, [v - lo, hi - v]))
        ax.errorbar(np.asarray(x, float) + 0.004 * i, v, yerr=err, fmt="o-", capsize=3,
                    label=label)
    ax.axhline(0.7, color="k", ls="--", lw=0.8, label="paper threshold 0.7")
    ax.set(xlabel=xlabel, ylabel="threshold", ylim=(0, 1), title=title)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
