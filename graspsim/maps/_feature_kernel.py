"""Compiled chords (numba) for :func:`~graspsim.maps.feature_grasps.feature_columns`: at one
seed and closing axis, for every approach and contact depth, the run of observed points the
pads would close on and the height of its contacts.

The same rule as the module docstring of :mod:`~graspsim.maps.feature_grasps` states, in the
same arithmetic (the points' coordinates along the closing axis sorted, their differences
against ``gap``, the median of the end points' heights as numpy takes it: the middle value,
or half the sum of the two middle ones), so the grasps are the same numbers as a loop in
numpy gives; only the loops are compiled.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["seed_chords"]


@njit(cache=True, nogil=True)
def seed_chords(x, Y, Z, depths, half_w, pad_length, gap, end_band, margin, widest):  # pragma: no cover
    """For approach j (columns of ``Y``, ``Z``: the points' coordinates across the finger
    width and along approach j) and contact depth k (``depths``), flattened as j * K + k:
    (ok, lo, hi, zc) -- whether the pads' footprint (|Y| <= half_w, depth - pad_length <= Z
    <= depth) holds a run of points along the closing axis (``x``) through 0, or nearest it,
    with gaps up to ``gap`` and at most ``widest`` long; its ends lo <= hi; and the contacts'
    height along the approach, the median of Z over the footprint's points within
    ``end_band`` of either end, at most depth - ``margin``."""
    M = x.shape[0]
    J = Y.shape[1]
    K = depths.shape[0]
    ok = np.zeros(J * K, np.bool_)
    lo = np.zeros(J * K)
    hi = np.zeros(J * K)
    zc = np.zeros(J * K)
    buf = np.empty(M)
    zb = np.empty(M)
    foot = np.empty(M, np.int64)  # the footprint's points
    for j in range(J):
        for k in range(K):
            d = depths[k]
            n = 0
            for i in range(M):
                if abs(Y[i, j]) <= half_w and Z[i, j] <= d and Z[i, j] >= d - pad_length:
                    foot[n] = i
                    buf[n] = x[i]
                    n += 1
            if n == 0:
                continue
            xs = np.sort(buf[:n])
            i0 = min(np.searchsorted(xs, 0.0), n - 1)
            a, b = 0, n - 1
            for t in range(n - 1):  # the breaks (gaps over ``gap``): the last before i0, the first from it
                if xs[t + 1] - xs[t] > gap:
                    if t < i0:
                        a = t + 1
                    else:
                        b = t
                        break
            r0, r1 = xs[a], xs[b]
            if not r1 - r0 <= widest:
                continue
            m = 0
            for t in range(n):  # its points at either end, in input order
                i = foot[t]
                if abs(x[i] - r0) <= end_band or abs(x[i] - r1) <= end_band:
                    zb[m] = Z[i, j]
                    m += 1
            f = j * K + k
            ok[f] = True
            lo[f] = r0
            hi[f] = r1
            zc[f] = min(np.median(zb[:m]), d - margin)
    return ok, lo, hi, zc
