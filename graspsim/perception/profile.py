"""Axial radius profile of a near-axisymmetric cluster, and where it changes.

A bottle is a body, a shoulder, a neck and a cap along one axis: along the axis of its
best cylinder or cone fit, the radius profile (per axial slice, an upper quantile of the
points' distances from the axis, so end caps and one-sided views do not pull it in) is
piecewise linear -- flat for a cylinder, sloped for a cone. :func:`profile_segments`
fits 1 to ``max_pieces`` linear pieces to the profile by dynamic programming (least
squares weighted by the slice's points) and keeps the number of pieces with the lowest
BIC of the profile; the cuts between pieces split the cluster across its axis.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["radius_profile", "piecewise_linear", "profile_segments"]


def radius_profile(points: np.ndarray, axis_point: np.ndarray, axis: np.ndarray, *, n_bins: int,
                   quantile: float = 0.9, min_count: int = 4):
    """(z of each point, bin edges (B+1,), bin centres, radius (B,), counts (B,)) along
    the unit ``axis`` through ``axis_point``; bins with fewer than ``min_count`` points
    have radius NaN."""
    rel = points - axis_point
    z = rel @ axis
    rho = np.linalg.norm(rel - z[:, None] * axis, axis=1)
    edges = np.linspace(z.min(), z.max() + 1e-12, n_bins + 1)
    b = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, n_bins - 1)
    counts = np.bincount(b, minlength=n_bins)
    radius = np.full(n_bins, np.nan)
    for i in np.flatnonzero(counts >= min_count):
        radius[i] = np.quantile(rho[b == i], quantile)
    return z, edges, 0.5 * (edges[1:] + edges[:-1]), radius, counts


def _line_sse(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(B, B) weighted SSE of the least-squares line through bins i..j (inclusive)."""
    n = len(x)
    sse = np.full((n, n), np.inf)
    for i in range(n):
        sw = swx = swy = swxx = swxy = swyy = 0.0
        for j in range(i, n):
            sw += w[j]
            swx += w[j] * x[j]
            swy += w[j] * y[j]
            swxx += w[j] * x[j] * x[j]
            swxy += w[j] * x[j] * y[j]
            swyy += w[j] * y[j] * y[j]
            if j - i < 1:
                sse[i, j] = 0.0
                continue
            vx = swxx - swx * swx / sw
            cxy = swxy - swx * swy / sw
            vy = swyy - swy * swy / sw
            sse[i, j] = max(vy - (cxy * cxy / vx if vx > 1e-30 else 0.0), 0.0)
    return sse


def piecewise_linear(x: np.ndarray, y: np.ndarray, w: np.ndarray, max_pieces: int, *, min_bins: int = 2):
    """Best segmentations of y(x) (weights w) into 1..max_pieces lines of at least
    ``min_bins`` points: {k: (sse, [first bin of each piece after the first])}."""
    n = len(x)
    sse = _line_sse(x, y, w)
    for i in range(n):  # pieces shorter than min_bins are not allowed
        sse[i, i:min(n, i + min_bins - 1)] = np.inf
    cost = np.full((max_pieces + 1, n + 1), np.inf)
    back = np.zeros((max_pieces + 1, n + 1), int)
    cost[0, 0] = 0.0
    for k in range(1, max_pieces + 1):
        for j in range(1, n + 1):  # first j bins in k pieces, the last piece = bins i..j-1
            c = cost[k - 1, :j] + sse[np.arange(j), j - 1]
            i = int(np.argmin(c))
            cost[k, j], back[k, j] = c[i], i
    out = {}
    for k in range(1, max_pieces + 1):
        if not np.isfinite(cost[k, n]):
            continue
        cuts, j = [], n
        for kk in range(k, 0, -1):
            i = back[kk, j]
            cuts.append(i)
            j = i
        out[k] = (float(cost[k, n]), sorted(cuts)[1:])
    return out


def profile_segments(points: np.ndarray, axis_point: np.ndarray, axis: np.ndarray, *, spacing: float,
                     scale: float, max_pieces: int = 4, min_points: int = 30) -> list[np.ndarray] | None:
    """Index arrays of the cluster's pieces along the axis where its radius profile
    changes, or None when one piece is best. ``scale``: the data's length scale [m]
    (the profile's noise floor)."""
    span = float(np.ptp(points @ axis))
    n_bins = int(np.clip(span / max(2.0 * spacing, 1e-6), 8, 48))
    z, edges, centres, radius, counts = radius_profile(points, axis_point, axis, n_bins=n_bins)
    ok = np.isfinite(radius)
    if ok.sum() < 6:
        return None
    x, y, w = centres[ok], radius[ok], counts[ok].astype(float)
    w = w / w.mean()
    fits = piecewise_linear(x, y, w, max_pieces)
    nb = len(x)
    floor = nb * scale * scale  # the profile cannot be fitted better than the data's scale

    def bic(k: int) -> float:
        return nb * math.log(max(fits[k][0], floor) / nb) + 3 * k * math.log(nb)

    best = min(fits, key=bic)
    if best == 1:
        return None
    cut_z = [0.5 * (x[c - 1] + x[c]) for c in fits[best][1]]
    label = np.searchsorted(np.asarray(cut_z), z)
    segs = [np.flatnonzero(label == i) for i in range(best)]
    segs = [s for s in segs if len(s)]
    if len(segs) < 2 or min(len(s) for s in segs) < min_points:
        segs = _merge_small(segs, min_points)
    return segs if len(segs) >= 2 else None


def _merge_small(segs: list[np.ndarray], min_points: int) -> list[np.ndarray]:
    """Pieces with fewer than ``min_points`` joined to their smaller neighbour."""
    segs = list(segs)
    while len(segs) > 1:
        sizes = [len(s) for s in segs]
        i = int(np.argmin(sizes))
        if sizes[i] >= min_points:
            break
        if i == 0:
            j = 1
        elif i == len(segs) - 1:
            j = i - 1
        else:
            j = i - 1 if sizes[i - 1] <= sizes[i + 1] else i + 1
        lo, hi = min(i, j), max(i, j)
        segs[lo:hi + 1] = [np.concatenate([segs[lo], segs[hi]])]
    return segs
