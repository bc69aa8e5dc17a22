"""Compiled patch measurement of the collision sample hierarchy (numba): each child
sample's offset from its parent, split along the parent's normal, in one pass.

The arithmetic is that of the numpy expressions it replaced (the same operations in the
same order, no fast-math; ``tests/test_maps_hierarchy.py`` keeps them as the reference),
so the patches are the same to the bit: it only saves the (K, 3) temporaries and a sort.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["patch_extents"]


@njit(cache=True, nogil=True)
def patch_extents(parents, children, parent_normals, grow, parent, order, RT, HN):  # pragma: no cover
    """For child i (K of them) of parent ``parent[i]``: h = (c - q) . n, the tangential
    offset |c - q - h n| and |h|, each plus ``grow[i]``; RT, HN (P,) zero-initialised
    get each parent's largest. ``order`` (K,) gets the children sorted by parent,
    stable (a counting sort). float64 throughout."""
    K = children.shape[0]
    P = parents.shape[0]
    start = np.zeros(P + 1, np.int64)
    for i in range(K):
        start[parent[i] + 1] += 1
    for p in range(P):
        start[p + 1] += start[p]
    fill = start[:-1].copy()
    for i in range(K):
        p = parent[i]
        order[fill[p]] = i
        fill[p] += 1
        d0 = children[i, 0] - parents[p, 0]
        d1 = children[i, 1] - parents[p, 1]
        d2 = children[i, 2] - parents[p, 2]
        n0, n1, n2 = parent_normals[p, 0], parent_normals[p, 1], parent_normals[p, 2]
        h = d0 * n0 + d1 * n1 + d2 * n2
        t0 = d0 - h * n0
        t1 = d1 - h * n1
        t2 = d2 - h * n2
        rt = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) + grow[i]
        hn = abs(h) + grow[i]
        if rt > RT[p]:
            RT[p] = rt
        if hn > HN[p]:
            HN[p] = hn
    return start


@njit(cache=True, nogil=True)
def _extent(points, order, lo, hi, a):  # pragma: no cover
    """Least and largest coordinate ``a`` of the points ``order[lo:hi]`` (lo < hi)."""
    mn, mx = points[order[lo], a], points[order[lo], a]
    for i in range(lo + 1, hi):
        v = points[order[i], a]
        mn = min(mn, v)
        mx = max(mx, v)
    return mn, mx


@njit(cache=True, nogil=True)
def cluster_tree(points, reach, size):  # pragma: no cover
    """The spatial clusters of :func:`graspsim.maps.hierarchy.clusters`, compiled: the
    same halving (the widest extent's first axis, a stable sort, the lower half first),
    so the same order, leaves, centres, radii and reaches to the bit (float64, no
    fast-math; the squared distances summed x, y, z in that order, as numpy sums a
    row). Returns (order, start, centre, radius, reach_max) before the margin."""
    N = points.shape[0]
    order = np.arange(N)
    lo_stack = np.empty(N + 1, np.int64)
    hi_stack = np.empty(N + 1, np.int64)
    starts = np.empty(N + 1, np.int64)
    top = 0
    lo_stack[0], hi_stack[0] = 0, N
    n_leaves = 0
    while top >= 0:
        lo, hi = lo_stack[top], hi_stack[top]
        top -= 1
        n = hi - lo
        if n <= size:
            if n > 0:
                starts[n_leaves] = lo
                n_leaves += 1
            continue
        ax, widest = 0, -1.0
        for a in range(3):
            mn, mx = _extent(points, order, lo, hi, a)
            if a == 0 or mx - mn > widest:
                ax, widest = a, mx - mn
        key = np.empty(n)
        for i in range(n):
            key[i] = points[order[lo + i], ax]
        half = np.argsort(key, kind="mergesort")
        ids = order[lo:hi].copy()
        for i in range(n):
            order[lo + i] = ids[half[i]]
        m = lo + n // 2
        top += 1  # the upper half waits; the lower half is split first
        lo_stack[top], hi_stack[top] = m, hi
        top += 1
        lo_stack[top], hi_stack[top] = lo, m
    start = np.empty(n_leaves + 1, np.int64)
    start[:n_leaves] = starts[:n_leaves]
    start[n_leaves] = N
    centre = np.empty((n_leaves, 3))
    radius = np.empty(n_leaves)
    reach_max = np.empty(n_leaves)
    for c in range(n_leaves):
        a0, a1 = start[c], start[c + 1]
        for a in range(3):
            mn, mx = _extent(points, order, a0, a1, a)
            centre[c, a] = 0.5 * (mn + mx)
        r2, rm = -1.0, reach[order[a0]]
        for i in range(a0, a1):
            p = order[i]
            dx = points[p, 0] - centre[c, 0]
            dy = points[p, 1] - centre[c, 1]
            dz = points[p, 2] - centre[c, 2]
            r2 = max(r2, dx * dx + dy * dy + dz * dz)
            rm = max(rm, reach[p])
        radius[c] = np.sqrt(r2)
        reach_max[c] = rm
    return order, start, centre, radius, reach_max


@njit(cache=True, nogil=True)
def regroup(order, start, parent_order, points, normals, tangent, height):  # pragma: no cover
    """Children grouped by parent (``order`` with CSR offsets ``start``, from
    :func:`patch_extents`) put in the parents' new order ``parent_order``: their points,
    normals, tangent radii and normal heights copied out in that order, and the new
    offsets. Plain copies (the values a gather by the same indices gives)."""
    P = parent_order.shape[0]
    new_start = np.zeros(P + 1, np.int64)
    for q in range(P):
        m = parent_order[q]
        new_start[q + 1] = new_start[q] + (start[m + 1] - start[m])
    K = new_start[P]
    F, NF = np.empty((K, 3)), np.empty((K, 3))
    RTF, HNF = np.empty(K), np.empty(K)
    j = 0
    for q in range(P):
        m = parent_order[q]
        for i in range(start[m], start[m + 1]):
            src = order[i]
            for a in range(3):
                F[j, a] = points[src, a]
                NF[j, a] = normals[src, a]
            RTF[j] = tangent[src]
            HNF[j] = height[src]
            j += 1
    return F, NF, RTF, HNF, new_start
