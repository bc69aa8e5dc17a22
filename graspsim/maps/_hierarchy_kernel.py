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
