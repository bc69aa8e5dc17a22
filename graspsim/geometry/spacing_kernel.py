"""Compiled nearest-neighbour distances (numba) for
:func:`~graspsim.perception.prepare.median_spacing`: every distinct location of a cloud
and the distance to its nearest other one, from a grid of cells instead of a KD-tree.

The points are sorted by cell; each point scans the cells around its own, ring by ring,
until the nearest point found lies closer than any point outside the scanned block can
(a ring ``r`` cells out is at least ``r`` cells from the point). The distances are
computed as ``sqrt((dx * dx + dy * dy) + dz * dz)`` (no fast-math): the KD-tree's
arithmetic, so the median is the same number. Repeated points count once (the first
of them in input order), as in the KD-tree over the distinct rows.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["nearest_other"]


@njit(cache=True, nogil=True)
def _scan(S, a, cx, cy, cz, r, n, start, order, best):  # pragma: no cover
    """The squared distance from the sorted point S[a] to the nearest other location among
    the cells of ring r around its cell (cx, cy, cz) (r = 1: the whole 3 x 3 x 3 block)
    and ``best`` so far; returns (best, False), or (best, True) where a point earlier in
    the input (``order``: input index of each sorted point) lies at S[a]'s very location."""
    x, y, z = S[a, 0], S[a, 1], S[a, 2]
    for ix in range(max(cx - r, 0), min(cx + r, n[0] - 1) + 1):
        for iy in range(max(cy - r, 0), min(cy + r, n[1] - 1) + 1):
            edge = r == 1 or abs(ix - cx) == r or abs(iy - cy) == r
            z0, z1 = max(cz - r, 0), min(cz + r, n[2] - 1)
            step = 1 if edge else 2 * r  # inside the ring's faces only its two z ends are new
            for iz in range(cz - r if not edge else z0, z1 + 1, step):
                if iz < z0:
                    continue
                cell = (ix * n[1] + iy) * n[2] + iz
                for b in range(start[cell], start[cell + 1]):
                    if b == a:
                        continue
                    dx, dy, dz = x - S[b, 0], y - S[b, 1], z - S[b, 2]
                    if dx == 0.0 and dy == 0.0 and dz == 0.0:
                        if order[b] < order[a]:
                            return best, True
                        continue
                    best = min(best, (dx * dx + dy * dy) + dz * dz)
    return best, False


@njit(cache=True, nogil=True)
def nearest_other(P):  # pragma: no cover
    """Distances (D,) from each distinct location of the finite points P (N >= 1, 3) to
    its nearest other location (in no particular order; inf where there is no other).
    The grid's cells are about the spacing of N points spread evenly over a square as
    wide as the cloud (grown where there would be more than 32 N + 4096 of them): any size
    gives the same distances, this one scans few cells of few points."""
    N = P.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(3):
        lo[c], hi[c] = P[:, c].min(), P[:, c].max()
    ext = max(hi[0] - lo[0], max(hi[1] - lo[1], hi[2] - lo[2]))
    cell = ext / math.sqrt(N) if ext > 0.0 else 1.0
    while True:
        cells = 1.0
        for c in range(3):
            cells *= math.floor((hi[c] - lo[c]) / cell) + 1.0
        if cells <= 16.0 * N + 64.0:
            break
        cell *= 1.25
    idx = np.empty((N, 3), np.int64)
    n = np.zeros(3, np.int64)
    for m in range(N):
        for c in range(3):
            idx[m, c] = np.int64(math.floor((P[m, c] - lo[c]) / cell))
            n[c] = max(n[c], idx[m, c] + 1)
    start = np.zeros(n[0] * n[1] * n[2] + 1, np.int64)
    key = np.empty(N, np.int64)
    for m in range(N):
        key[m] = (idx[m, 0] * n[1] + idx[m, 1]) * n[2] + idx[m, 2]
        start[key[m] + 1] += 1
    for c in range(start.shape[0] - 1):
        start[c + 1] += start[c]
    order = np.empty(N, np.int64)
    fill = start[:-1].copy()
    for m in range(N):
        order[fill[key[m]]] = m
        fill[key[m]] += 1
    S = np.empty((N, 3))  # the points cell by cell: a cell's neighbours' points stay in cache
    for t in range(N):
        S[t] = P[order[t]]
    out = np.empty(N)
    k = 0
    rmax = max(n[0], max(n[1], n[2]))
    for a in range(N):
        m = order[a]
        best, dup = np.inf, False
        r = 1
        while True:
            best, dup = _scan(S, a, idx[m, 0], idx[m, 1], idx[m, 2], r, n, start, order, best)
            # a point r cells out lies at least (r - rounding) cells away: the nearest is found
            if dup or best <= ((r - 1e-6) * cell) ** 2 or r >= rmax:
                break
            r += 1
        if not dup:
            out[k] = math.sqrt(best)  # sqrt is monotone and correctly rounded: the least distance
            k += 1
    return out[:k]
