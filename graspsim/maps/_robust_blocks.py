"""Blocks of points for the robust kernel (:mod:`graspsim.maps._robust_kernel`) to pass
over whole: a grasp measures the points of the blocks that can come near its gripper.

:func:`blocks` puts the points into the cells of a grid (hashed, so a block may hold
several cells) with each block's bounding sphere; :func:`near_blocks` bounds, per block,
how close its points come to the gripper's boxes in a grasp's wrist frame (float64,
from the sphere: conservative), and whether the largest perturbation could bring one of
them within reach. A block is skipped only when that bound exceeds what the kernel
keeps by ``BLOCK_SLACK``, far more than float32 rounding of the points' distances.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["blocks", "near_blocks", "gather", "BLOCK_SLACK", "BLOCK_CELL"]

_BIG = 1e9
BLOCK_SLACK = 1e-4  # [m] a skipped block's margin over float32 rounding of its points' distances (< 1e-6 m)
BLOCK_CELL = 0.02  # [m] the grid the points are blocked on (a gripper's finger is ~1-2 cm: blocks that size cull well)


@njit(cache=True, nogil=True)
def _cell_hash(i, j, k, H):  # pragma: no cover
    """A cell's bucket in 0..H-1 (H a power of two): the cell's integer coordinates mixed
    over all 64 bits (splitmix64's finaliser), so that a scene's few hundred cells share a
    bucket rarely (cells sharing one make a block as wide as both: near every grasp)."""
    u8 = np.uint64
    h = u8(i) * u8(0x9E3779B97F4A7C15) + u8(j) * u8(0xC2B2AE3D27D4EB4F) + u8(k) * u8(0x165667B19E3779F9)
    h = (h ^ (h >> u8(30))) * u8(0xBF58476D1CE4E5B9)
    h = (h ^ (h >> u8(27))) * u8(0x94D049BB133111EB)
    h = h ^ (h >> u8(31))
    return np.int64(h & u8(H - 1))


@njit(cache=True, nogil=True)
def blocks(P, n_cloud, cell):  # pragma: no cover
    """The points P (M, 3) in blocks: the cells of a grid ``cell`` [m] wide (hashed; a
    block may hold several cells). Returns order (M,) (block by block), start (B + 1,),
    centre (B, 3), radius (B,) (every point of block j within radius[j] of centre[j])
    and cloud (B,) (the block holds a point below ``n_cloud``)."""
    M = P.shape[0]
    H = 16
    while H < 2 * M:
        H *= 2
    key = np.empty(M, np.int64)
    count = np.zeros(H + 1, np.int64)
    for m in range(M):
        key[m] = _cell_hash(np.int64(np.floor(P[m, 0] / cell)), np.int64(np.floor(P[m, 1] / cell)),
                            np.int64(np.floor(P[m, 2] / cell)), H)
        count[key[m] + 1] += 1
    B = 0
    for h in range(H):
        B += count[h + 1] > 0
        count[h + 1] += count[h]
    order = np.empty(M, np.int64)
    fill = count[:H].copy()
    for m in range(M):
        order[fill[key[m]]] = m
        fill[key[m]] += 1
    start = np.empty(B + 1, np.int64)
    j = 0
    for h in range(H):
        if count[h + 1] > count[h]:
            start[j] = count[h]
            j += 1
    start[B] = M
    centre, radius, cloud = np.empty((B, 3)), np.empty(B), np.zeros(B, np.bool_)
    for j in range(B):
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for t in range(start[j], start[j + 1]):
            for c in range(3):
                lo[c] = min(lo[c], np.float64(P[order[t], c]))
                hi[c] = max(hi[c], np.float64(P[order[t], c]))
            cloud[j] |= order[t] < n_cloud
        r2 = 0.0
        for c in range(3):
            centre[j, c] = 0.5 * (lo[c] + hi[c])
        for t in range(start[j], start[j + 1]):
            d2 = 0.0
            for c in range(3):
                d2 += (np.float64(P[order[t], c]) - centre[j, c]) ** 2
            r2 = max(r2, d2)
        radius[j] = np.sqrt(r2)
    return order, start, centre, radius, cloud


@njit(cache=True, nogil=True)
def near_blocks(R, w, i, pivot, th, pm, bc, bh, bs, ho_lo, ho_hi, centre, radius, low, near):  # pragma: no cover
    """Per block (float64): low, a lower bound of its points' distance to the boxes
    (the moving ones swept over [ho_lo, ho_hi]) in grasp i's wrist frame; near: some
    point of it may lie within the largest perturbation's reach of a box."""
    for j in range(centre.shape[0]):
        dx, dy, dz = centre[j, 0] - w[i, 0], centre[j, 1] - w[i, 1], centre[j, 2] - w[i, 2]
        x = R[i, 0, 0] * dx + R[i, 1, 0] * dy + R[i, 2, 0] * dz
        y = R[i, 0, 1] * dx + R[i, 1, 1] * dy + R[i, 2, 1] * dz
        z = R[i, 0, 2] * dx + R[i, 1, 2] * dy + R[i, 2, 2] * dz
        d = _BIG
        for k in range(bc.shape[0]):
            cx, hx = bc[k, 0], bh[k, 0]
            if bs[k] != 0:
                cx, hx = cx + bs[k] * 0.5 * (ho_lo + ho_hi), hx + 0.5 * (ho_hi - ho_lo)
            ex = max(abs(x - cx) - hx, 0.0)
            ey = max(abs(y - bc[k, 1]) - bh[k, 1], 0.0)
            ez = max(abs(z - bc[k, 2]) - bh[k, 2], 0.0)
            d = min(d, np.sqrt(ex * ex + ey * ey + ez * ez))
        low[j] = d - radius[j]
        r = np.sqrt((x - pivot[0]) ** 2 + (y - pivot[1]) ** 2 + (z - pivot[2]) ** 2) + radius[j]
        near[j] = not (low[j] > th * r + pm + BLOCK_SLACK)  # a block with NaN or inf points: measured


@njit(cache=True, nogil=True)
def gather(order, start, take, idx, n):  # pragma: no cover
    """Append the points of the blocks ``take`` (bool (B,)) to idx from row n; returns the new count."""
    for j in range(take.shape[0]):
        if take[j]:
            for t in range(start[j], start[j + 1]):
                idx[n] = order[t]
                n += 1
    return n
