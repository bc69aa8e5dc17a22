"""Hierarchical MVBB fit-and-split (Huebner, Ruthotto & Kragic 2008), as in paper 2.2.

One split of a cluster with box P: its points, in box coordinates, are projected onto
the three face planes of P; in each plane, candidate split lines parallel to a box axis
are swept across the 2-D hull; a candidate is scored by the summed areas of the 2-D
convex hulls of the two halves relative to the parent hull's area; the best candidate
over all planes cuts the 3-D cluster by the plane through that line. The split is kept
if it gains enough volume, eq. (1)::

    theta* = (V(C1) + V(C2) + V(A minus P)) / (V(P) + V(A minus P)) < theta_th

with A the current set of boxes and C1, C2 the children's MVBBs.

Hull areas of all candidate halves come from one incremental monotone-chain pass per
direction over the extreme points of thin slabs (slab width = the sweep step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from graspsim.errors import InvalidParameterError
from graspsim.perception.mvbb import OrientedBox, min_volume_box

__all__ = ["Split", "best_split", "theta_star"]


@dataclass(frozen=True)
class Split:
    """A chosen split: ``mask`` (N,) True for the first child; ``axis`` (0-2, box axis
    normal to the cut plane) at ``offset`` [m] in box coordinates; ``area_ratio`` the
    hull-area criterion; ``boxes`` the two children's MVBBs."""

    mask: np.ndarray
    axis: int
    offset: float
    area_ratio: float
    boxes: tuple[OrientedBox, OrientedBox]


def theta_star(v_parent: float, v_children: tuple[float, float], v_others: float) -> float:
    """Eq. (1): total box volume after the split over total volume before it; 1 (no
    gain: no split) when there is no volume to gain (flat boxes)."""
    before = v_parent + v_others
    if not before > 0.0:
        return 1.0
    return (v_children[0] + v_children[1] + v_others) / before


def _chain_areas(u: np.ndarray, b: np.ndarray, group: np.ndarray, n_groups: int) -> np.ndarray:
    """Hull areas (n_groups,) of the prefixes {points with group <= g}, points sorted by u.

    Incremental monotone chain; the area is the integral between upper and lower chains."""
    areas = np.zeros(n_groups)
    up: list[tuple[float, float]] = []
    lo: list[tuple[float, float]] = []
    up_a: list[float] = []
    lo_a: list[float] = []
    k = 0
    for x, y, g in zip(u.tolist(), b.tolist(), group.tolist()):
        while k < g:
            areas[k] = (up_a[-1] - lo_a[-1]) if up else 0.0
            k += 1
        for chain, acc, sign in ((up, up_a, 1.0), (lo, lo_a, -1.0)):
            while len(chain) >= 2:
                (x1, y1), (x2, y2) = chain[-2], chain[-1]
                if sign * ((x2 - x1) * (y - y1) - (y2 - y1) * (x - x1)) >= 0.0:
                    chain.pop()
                    acc.pop()
                else:
                    break
            if chain:
                x0, y0 = chain[-1]
                acc.append(acc[-1] + 0.5 * (y + y0) * (x - x0))
            else:
                acc.append(0.0)
            chain.append((x, y))
    while k < n_groups:
        areas[k] = (up_a[-1] - lo_a[-1]) if up else 0.0
        k += 1
    return areas


def _slab_extremes(u: np.ndarray, b: np.ndarray, slab: np.ndarray, n_slabs: int):
    """Per occupied slab, its lowest and highest point in b; sorted by (u, b)."""
    order = np.lexsort((b, slab))
    s, uu, bb = slab[order], u[order], b[order]
    first = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
    last = np.r_[first[1:] - 1, len(s) - 1]
    keep = np.unique(np.r_[first, last])
    uu, bb, ss = uu[keep], bb[keep], s[keep]
    o = np.lexsort((bb, uu))
    return uu[o], bb[o], ss[o]


def best_split(points: np.ndarray, box: OrientedBox, *, min_points: int = 30,
               step: float | None = None, max_cuts: int = 64) -> Split | None:
    """Best Huebner split of a cluster (N, 3) [m] with MVBB ``box``; None if no cut
    leaves ``min_points`` on both sides. ``step``: sweep step [m] (default: the
    longest box edge / ``max_cuts``, at least 1 mm)."""
    if min_points < 1:
        raise InvalidParameterError(f"min_points must be >= 1, got {min_points!r}")
    local = box.local(points)
    if len(local) < 2 * min_points:
        return None
    best = (np.inf, -1, 0.0)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        try:
            parent = ConvexHull(local[:, [i, j]]).volume
        except QhullError:
            continue
        if parent <= 0:
            continue
        for ax, other in ((i, j), (j, i)):
            u, b = local[:, ax], local[:, other]
            lo, hi = float(u.min()), float(u.max())
            d = step or max((hi - lo) / max_cuts, 1e-3)
            n_slabs = int(np.ceil((hi - lo) / d)) + 1
            if n_slabs < 3:
                continue
            slab = np.minimum(((u - lo) / d).astype(int), n_slabs - 1)
            count = np.cumsum(np.bincount(slab, minlength=n_slabs))  # points with slab <= g
            uu, bb, ss = _slab_extremes(u, b, slab, n_slabs)
            left = _chain_areas(uu, bb, ss, n_slabs)
            right = _chain_areas(-uu[::-1], bb[::-1], (n_slabs - 1 - ss)[::-1], n_slabs)[::-1]
            # cut after slab g: left = slabs <= g, right = slabs >= g + 1
            ratio = (left[:-1] + right[1:]) / parent
            ok = (count[:-1] >= min_points) & (len(u) - count[:-1] >= min_points)
            ratio = np.where(ok, ratio, np.inf)
            g = int(np.argmin(ratio))
            if ratio[g] < best[0]:
                best = (float(ratio[g]), ax, lo + (g + 1) * d)
    ratio, ax, offset = best
    if ax < 0 or not np.isfinite(ratio):
        return None
    mask = local[:, ax] < offset
    boxes = (min_volume_box(points[mask]), min_volume_box(points[~mask]))
    return Split(mask, ax, offset, ratio, boxes)
