"""Small statistics helpers shared by the library, its experiments and reports."""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

__all__ = ["wilson_interval"]


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
