"""Compiled robustness kernel: the gripper's boxes against points, under pose error (numba).

For each grasp i (wrist rotation R_i, position w_i in the object frame, pad gaps o_ie
for the jaw openings e) the kernel takes every obstacle point p into the wrist frame,
q = R_i^T (p - w_i), and computes its signed distance s_e(q) to the union of the
gripper's boxes (x centres moved by x_sign * o_ie / 2): negative inside. The grasp's
clearance at opening e is the smallest s_e over the first ``n_cloud`` points (the
observed cloud).

A perturbed pose is T_i D_k with D_k = (Rk, tk) in the wrist frame, so a point's
perturbed wrist coordinates are q' = Rk^T (q - tk). With the rotation turning about
the pivot c (the TCP), |q' - q| <= theta_k |q - c| + |pos_k| (theta_k: the rotation
angle, pos_k: the translation at the pivot), and s is 1-Lipschitz: a point with
s(q) > theta_k |q - c| + |pos_k| + margin cannot reach the gripper under D_k. Only
the points near enough for the largest perturbation are kept per grasp (with the boxes
each can reach), and each perturbation tests only those its own bound does not rule
out, against those boxes grown by ``margin`` (exact for margin 0; within margin x sqrt 3
at the boxes' corners otherwise) -- a few dozen points per grasp instead of thousands.
The pass over all points runs in float32 (tenths of a micrometre at object scale).

That pass skips whole blocks of points (the cells of a hashed grid, made once per
scoring call by :func:`graspsim.maps._robust_blocks.blocks`): a block whose bounding
sphere lies farther from every (swept) box than the reach of its farthest point, and --
for cloud points -- farther than the clearance the nearer blocks already attain, holds
no point the pass would keep, by more than float32 rounding (``BLOCK_SLACK``). The kept
points, and so the results, are those of the pass over every point. A caller that asks
only whether a pose holds a point (``with_clearance`` False: the planner's check of the
nominal poses, ``first_clear``) skips the cloud's farther blocks and keeps only the points
within reach: the flags are the same (a point out of reach sets none), the clearance is
not measured.

The openings share that pass over all points: the points go into the wrist frame once,
the boxes that do not move with the jaws (the housing) are measured once, and the moving
boxes once as swept along x over every opening of the grasp. A swept box contains the
box at each opening and lies within D (the sweep's length) of it, so s_swept <= s_e <=
s_swept + D: only the points that could lie within reach of a box, or attain the
cloud's clearance, at some opening are kept, and each opening measures those exactly
(the same float32 arithmetic as measuring every point: results do not change). The
openings are scored in order, and a grasp stops at the first opening ``allow`` admits
where every pose is feasible (nothing wider can score it higher), or at the first where
every pose holds a cloud point in a box that does not move with the jaws (no wider
opening frees it: none can score, and the score reports the narrowest opening of the
best; in a pile, most grasps the clear-first check passes over).

Per grasp, opening and perturbation the kernel writes a bit set (uint8): 1 a cloud point
closer than ``margin`` to a box (cloud collision), 2 the same for a primitive surface
sample, 4 a box below the table (lower than ``table[4]`` above the plane) or the gripper's
lowest point higher than ``table[5]`` (a low-profile grasp lifted off a thin part), 8 a contact
off its pad (outside the finger's width or the pad's length), 16 the closing axis
outside either contact's friction cone. 0 means feasible; 255: the opening was not
scored (the grasp stopped at a narrower one).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# compiled into robust_flags and cached with it: numba does not see edits to another file, so
# after changing _robust_blocks.py delete this module's cache (__pycache__/_robust_kernel.*.nb*)
from graspsim.maps._robust_blocks import BLOCK_SLACK, gather, near_blocks

__all__ = ["robust_flags", "CLOUD", "PRIMITIVE", "TABLE", "OFF_PAD", "NO_FC", "NOT_SCORED"]

CLOUD, PRIMITIVE, TABLE, OFF_PAD, NO_FC = 1, 2, 4, 8, 16
NOT_SCORED = 255
_BIG = 1e9
_SLACK = 1e-6  # [m] float32 rounding of the swept boxes' bounds (below 1e-7 at object scale)


@njit(cache=True, nogil=True, fastmath=True)
def _wrist_points(P, R, w, i, pivot, th4, pm4, idx, a, b, n_cloud, qx, qy, qz, rr, reach, cl):  # pragma: no cover
    """Points P[idx[a:b]] in grasp i's wrist frame (float32, rows a..b of the outputs),
    their distance to the pivot, how far the largest perturbation can move them, and
    whether each is a cloud point (index below ``n_cloud``)."""
    f4 = np.float32
    r00, r01, r02 = f4(R[i, 0, 0]), f4(R[i, 0, 1]), f4(R[i, 0, 2])
    r10, r11, r12 = f4(R[i, 1, 0]), f4(R[i, 1, 1]), f4(R[i, 1, 2])
    r20, r21, r22 = f4(R[i, 2, 0]), f4(R[i, 2, 1]), f4(R[i, 2, 2])
    wx, wy, wz = f4(w[i, 0]), f4(w[i, 1]), f4(w[i, 2])
    cx0, cy0, cz0 = f4(pivot[0]), f4(pivot[1]), f4(pivot[2])
    for j in range(a, b):
        m = idx[j]
        dx = P[m, 0] - wx
        dy = P[m, 1] - wy
        dz = P[m, 2] - wz
        x = r00 * dx + r10 * dy + r20 * dz
        y = r01 * dx + r11 * dy + r21 * dz
        z = r02 * dx + r12 * dy + r22 * dz
        qx[j], qy[j], qz[j] = x, y, z
        r = np.sqrt((x - cx0) * (x - cx0) + (y - cy0) * (y - cy0) + (z - cz0) * (z - cz0))
        rr[j] = r
        reach[j] = th4 * r + pm4
        cl[j] = m < n_cloud


@njit(cache=True, nogil=True, fastmath=True)
def _box(qx, qy, qz, a, n, cx, cy, cz, hx, hy, hz, reach, bit, sd, bits):  # pragma: no cover
    """Points a..n against one box (float32 centre and half extents): running minimum
    of the signed distance in sd, ``bit`` set in bits where within reach."""
    zero = np.float32(0.0)
    for m in range(a, n):
        ex = abs(qx[m] - cx) - hx
        ey = abs(qy[m] - cy) - hy
        ez = abs(qz[m] - cz) - hz
        ox, oy, oz = max(ex, zero), max(ey, zero), max(ez, zero)
        d = np.sqrt(ox * ox + oy * oy + oz * oz) + min(max(ex, max(ey, ez)), zero)
        sd[m] = min(sd[m], d)
        bits[m] |= bit * np.int32(d <= reach[m])


@njit(cache=True, nogil=True, fastmath=True)
def _distances(qx, qy, qz, a, b, reach, bc, bh, bs, ho_lo, ho_hi, sd0, bits0, lb, scratch):  # pragma: no cover
    """Points a..b: exact distance and reach bits of the boxes that do not move (sd0,
    bits0), a lower bound lb of every opening's distance (the moving boxes swept over
    [ho_lo, ho_hi])."""
    f4 = np.float32
    for m in range(a, b):
        sd0[m] = f4(_BIG)
        bits0[m] = 0
        lb[m] = f4(_BIG)
    for k in range(bc.shape[0]):
        cy, cz, hy, hz = f4(bc[k, 1]), f4(bc[k, 2]), f4(bh[k, 1]), f4(bh[k, 2])
        if bs[k] == 0:
            _box(qx, qy, qz, a, b, f4(bc[k, 0]), cy, cz, f4(bh[k, 0]), hy, hz, reach, np.int32(1 << k), sd0, bits0)
        else:  # no bits (scratch is rewritten afterwards)
            _box(qx, qy, qz, a, b, f4(bc[k, 0] + bs[k] * 0.5 * (ho_lo + ho_hi)), cy, cz,
                 f4(bh[k, 0] + 0.5 * (ho_hi - ho_lo)), hy, hz, reach, np.int32(0), lb, scratch)


@njit(cache=True, nogil=True, fastmath=True)
def _upper(cl, sd0, lb, sweep, a, b, upper):  # pragma: no cover
    """``upper`` lowered to the least bound min(sd0, lb + sweep) of the cloud points
    a..b: the cloud's clearance at any opening is at most that."""
    for m in range(a, b):
        if cl[m]:
            upper = min(upper, min(sd0[m], lb[m] + sweep))
    return upper


@njit(cache=True, nogil=True, fastmath=True)
def _keep(n, cl, reach, sd0, lb, upper, keep):  # pragma: no cover
    """keep: the points 0..n some opening needs (within reach of a box, or a cloud point
    that may attain the clearance). Returns their count."""
    slack = np.float32(_SLACK)
    k = 0
    for m in range(n):
        low = min(sd0[m], lb[m])
        keep[m] = (low <= reach[m] + slack) or (cl[m] and low <= upper + slack)
        k += keep[m]
    return k


@njit(cache=True, nogil=True, fastmath=True)
def _shared_pass(qx, qy, qz, M, cl, reach, bc, bh, bs, ho_lo, ho_hi, sd0, bits0, lb, keep):  # pragma: no cover
    """All M points once per grasp (cl (M,): which are cloud points): sd0, bits0, lb
    as :func:`_distances`; keep: the points any opening needs. Returns their count."""
    _distances(qx, qy, qz, 0, M, reach, bc, bh, bs, ho_lo, ho_hi, sd0, bits0, lb, keep)
    upper = _upper(cl, sd0, lb, np.float32(ho_hi - ho_lo), 0, M, np.float32(_BIG))
    return _keep(M, cl, reach, sd0, lb, upper, keep)


@njit(cache=True, nogil=True, fastmath=True)
def _contacts(i, qc, nq, sign, DR, Dt, pad, cos_fc, out):  # pragma: no cover
    """Per perturbation (K,): OFF_PAD and NO_FC bits of grasp i (any opening)."""
    for k in range(DR.shape[0]):
        f = 0
        for c in range(2):
            ax = qc[i, c, 0] - Dt[k, 0]
            ay = qc[i, c, 1] - Dt[k, 1]
            az = qc[i, c, 2] - Dt[k, 2]
            py = DR[k, 0, 1] * ax + DR[k, 1, 1] * ay + DR[k, 2, 1] * az
            pz = DR[k, 0, 2] * ax + DR[k, 1, 2] * ay + DR[k, 2, 2] * az
            if abs(py) > pad[0] or pz < pad[1] or pz > pad[2]:
                f |= OFF_PAD
            # closing axis (perturbed wrist x in the nominal frame) against -n (contact 0)
            # and +n (contact 1), oriented from contact 0 to contact 1
            d = sign[i] * (DR[k, 0, 0] * nq[i, c, 0] + DR[k, 1, 0] * nq[i, c, 1] + DR[k, 2, 0] * nq[i, c, 2])
            if (-d if c == 0 else d) < cos_fc:
                f |= NO_FC
        out[k] = f


@njit(cache=True, nogil=True, fastmath=True)
def _table(i, k, table, DR, Dt, bc, bh, bs, ho):  # pragma: no cover
    """TABLE when a box of grasp i under perturbation k lies lower than required
    (``table[i, 4]``), or when the gripper's lowest point rises higher than ``table[i, 5]``
    (a low-profile grasp whose pads would overlap a thin part too little)."""
    nx = DR[k, 0, 0] * table[i, 0] + DR[k, 1, 0] * table[i, 1] + DR[k, 2, 0] * table[i, 2]
    ny = DR[k, 0, 1] * table[i, 0] + DR[k, 1, 1] * table[i, 1] + DR[k, 2, 1] * table[i, 2]
    nz = DR[k, 0, 2] * table[i, 0] + DR[k, 1, 2] * table[i, 1] + DR[k, 2, 2] * table[i, 2]
    base = table[i, 3] + table[i, 0] * Dt[k, 0] + table[i, 1] * Dt[k, 1] + table[i, 2] * Dt[k, 2]
    lowest = 1e30
    for b in range(bc.shape[0]):
        h = (base + nx * (bc[b, 0] + bs[b] * ho) + ny * bc[b, 1] + nz * bc[b, 2]
             - bh[b, 0] * abs(nx) - bh[b, 1] * abs(ny) - bh[b, 2] * abs(nz))
        if h < table[i, 4]:
            return TABLE
        lowest = min(lowest, h)
    if lowest > table[i, 5]:  # the whole gripper above the ceiling: lifted off a thin part
        return TABLE
    return 0


@njit(cache=True, nogil=True, fastmath=True)
def _points_hit(near, ns, nr, nb, ncl, n, D, theta, tlen, margin, bc, bh, bs, ho, px, py, pz, live, inside,
                out, n0, fixed, fixed_in):  # pragma: no cover
    """CLOUD / PRIMITIVE bits per perturbation (out (K,)): a near point inside a box it
    can reach (grown by margin) under perturbation k. The loops over the K
    perturbations (D (12, K): DR[k] row-major, then Dt[k]) run in SIMD lanes.

    fixed (K,): a cloud point whose distance to the boxes that do not move with the jaws
    (n0, at every opening at least its distance ns here) is within the perturbation's
    reach lies inside one of those boxes (grown by margin) under perturbation k: the
    same arithmetic on the same numbers finds it there at every opening (conservative:
    a pose hit first by another point, or by a moving box, is not marked)."""
    K = theta.shape[0]
    for k in range(K):
        out[k] = 0
        fixed[k] = False
    for j in range(n):
        bit = CLOUD if ncl[j] else PRIMITIVE
        x, y, z, s, r = near[j, 0], near[j, 1], near[j, 2], ns[j], nr[j]
        alive = 0
        for k in range(K):  # perturbations that may bring the point to a box and lack its bit
            live[k] = (s <= theta[k] * r + tlen[k] + margin) & ((out[k] & bit) == 0)
            alive += live[k]
        if alive == 0:
            continue
        for k in range(K):
            ax = x - D[9, k]
            ay = y - D[10, k]
            az = z - D[11, k]
            px[k] = D[0, k] * ax + D[3, k] * ay + D[6, k] * az
            py[k] = D[1, k] * ax + D[4, k] * ay + D[7, k] * az
            pz[k] = D[2, k] * ax + D[5, k] * ay + D[8, k] * az
            inside[k] = False
            fixed_in[k] = False
        for b in range(bc.shape[0]):  # inside a reachable box grown by the margin
            if (nb[j] >> b) & 1:
                for k in range(K):
                    hit = ((abs(px[k] - bc[b, 0] - bs[b] * ho) < bh[b, 0] + margin)
                           & (abs(py[k] - bc[b, 1]) < bh[b, 1] + margin)
                           & (abs(pz[k] - bc[b, 2]) < bh[b, 2] + margin))
                    inside[k] |= hit
                    fixed_in[k] |= hit & (bs[b] == 0)
        s0 = n0[j]
        for k in range(K):
            out[k] |= bit * np.int32(live[k] & inside[k])
            fixed[k] |= ncl[j] & live[k] & fixed_in[k] & (s0 <= theta[k] * r + tlen[k] + margin)


@njit(cache=True, nogil=True, fastmath=True)
def _opening(i, e, ho, cqx, cqy, cqz, cr, creach, csd0, cbits0, ccl, nc, sd, bits, near, ns, nr, nb, ncl, cf,
             bc, bh, bs, DR, Dt, D, theta, tlen, table, margin, px, py, pz, live, inside, hits, clearance,
             flags, n0, fixed, fixed_in):  # pragma: no cover
    """Grasp i at opening e (half gap ho): the kept points' exact distances and reach
    bits with the moving boxes there, the clearance, and the flags of every pose
    (fixed: see :func:`_points_hit`)."""
    f4 = np.float32
    for j in range(nc):
        sd[j] = csd0[j]
        bits[j] = cbits0[j]
    for b in range(bc.shape[0]):
        if bs[b] != 0:
            _box(cqx, cqy, cqz, 0, nc, f4(bc[b, 0] + bs[b] * ho), f4(bc[b, 1]), f4(bc[b, 2]),
                 f4(bh[b, 0]), f4(bh[b, 1]), f4(bh[b, 2]), creach, np.int32(1 << b), sd, bits)
    clear = f4(_BIG)
    n = 0
    for j in range(nc):
        if ccl[j]:
            clear = min(clear, sd[j])
        if bits[j]:
            near[n, 0] = cqx[j]
            near[n, 1] = cqy[j]
            near[n, 2] = cqz[j]
            ns[n] = sd[j]
            n0[n] = csd0[j]
            nr[n] = cr[j]
            nb[n] = bits[j]
            ncl[n] = ccl[j]
            n += 1
    clearance[i, e] = clear
    _points_hit(near, ns, nr, nb, ncl, n, D, theta, tlen, margin, bc, bh, bs, ho, px, py, pz, live, inside, hits,
                n0, fixed, fixed_in)
    for k in range(DR.shape[0]):
        flags[i, e, k] = hits[k] | _table(i, k, table, DR, Dt, bc, bh, bs, ho) | cf[k]


@njit(cache=True, nogil=True, fastmath=True)
def _kept_points(P, n_cloud, R, w, i, pivot, th, pm, ho_lo, ho_hi, bc, bh, bs, blk, work, kept,
                 with_clearance):  # pragma: no cover
    """Grasp i's pass over the points: the blocks near enough first, then (``with_clearance``)
    the cloud's blocks that may hold its clearance; the points any opening needs go to
    ``kept`` (wrist coordinates, pivot distance, reach, sd0, bits0, cloud flag). Returns
    their count. Without the clearance only the points within reach of a box are kept:
    the flags are those of every point (a point out of reach sets no bit), the
    clearance is not measured."""
    order, start, centre, radius, cloud, low, near, take = blk
    idx, qx, qy, qz, rr, reach, cl, sd0, bits0, lb, keep = work
    f4 = np.float32
    th4, pm4 = f4(th), f4(pm)
    near_blocks(R, w, i, pivot, th, pm, bc, bh, bs, ho_lo, ho_hi, centre, radius, low, near)
    n = gather(order, start, near, idx, 0)
    _wrist_points(P, R, w, i, pivot, th4, pm4, idx, 0, n, n_cloud, qx, qy, qz, rr, reach, cl)
    _distances(qx, qy, qz, 0, n, reach, bc, bh, bs, ho_lo, ho_hi, sd0, bits0, lb, keep)
    if not with_clearance:  # no cloud point is kept for the clearance alone
        _keep(n, cl, reach, sd0, lb, f4(-_BIG), keep)
        return _compact(n, keep, qx, qy, qz, rr, reach, sd0, bits0, cl, kept)
    sweep = f4(ho_hi - ho_lo)
    upper = _upper(cl, sd0, lb, sweep, 0, n, f4(_BIG))
    for j in range(take.shape[0]):  # cloud blocks that may come closer than what the near ones attain
        take[j] = cloud[j] and not near[j] and not (low[j] > upper + BLOCK_SLACK)
    n1 = n
    n = gather(order, start, take, idx, n1)
    _wrist_points(P, R, w, i, pivot, th4, pm4, idx, n1, n, n_cloud, qx, qy, qz, rr, reach, cl)
    _distances(qx, qy, qz, n1, n, reach, bc, bh, bs, ho_lo, ho_hi, sd0, bits0, lb, keep)
    upper = _upper(cl, sd0, lb, sweep, n1, n, upper)
    _keep(n, cl, reach, sd0, lb, upper, keep)
    return _compact(n, keep, qx, qy, qz, rr, reach, sd0, bits0, cl, kept)


@njit(cache=True, nogil=True, fastmath=True)
def _compact(n, keep, qx, qy, qz, rr, reach, sd0, bits0, cl, kept):  # pragma: no cover
    """The points 0..n marked in ``keep`` copied to ``kept`` in order. Returns their count."""
    cqx, cqy, cqz, cr, creach, csd0, cbits0, ccl = kept
    nc = 0
    for m in range(n):
        if keep[m]:
            cqx[nc], cqy[nc], cqz[nc] = qx[m], qy[m], qz[m]
            cr[nc], creach[nc], csd0[nc], cbits0[nc], ccl[nc] = rr[m], reach[m], sd0[m], bits0[m], cl[m]
            nc += 1
    return nc


@njit(cache=True, nogil=True, fastmath=True)
def robust_flags(P, n_cloud, R, w, openings, allow, mask, bc, bh, bs, qc, nq, sign, DR, Dt, theta, tlen, pivot,
                 table, pad, cos_fc, margin, point_blocks, with_clearance, lo, hi, clearance,
                 flags):  # pragma: no cover
    """Grasps [lo, hi): clearance (N, E) to the cloud points P[:n_cloud] and flags
    (N, E, K) at the pad gaps ``openings`` (N, E) (in order) for perturbations DR
    (K, 3, 3), Dt (K, 3) (theta, tlen (K,): their bounds). A grasp stops after the
    first opening e with ``allow[i, e]`` where no flag has a bit of ``mask``, or -- with
    CLOUD in ``mask`` -- where every pose holds a cloud point in a box that does not move
    with the jaws (the housing, the arm's keep-out: it holds it at every wider opening,
    none of which can then be feasible); the wider ones get clearance inf and flags
    NOT_SCORED.

    qc, nq: (N, 2, 3) contacts and outward normals in each grasp's nominal wrist frame;
    sign (N,): +1 when contact 1 lies on the +x side of contact 0. table: (nr_x, nr_y,
    nr_z, height of the wrist origin, required height, ceiling of the lowest point) with nr
    (N, ...) given per grasp as table[i] (a row of zeros and a huge height: no table; a huge
    ceiling: none). pad: (half width, z_lo,
    z_hi) of the pads in the wrist frame. point_blocks: P's blocks, :func:`graspsim.maps._robust_blocks.blocks`'s
    (order, start, centre, radius, cloud) (any block size gives the same results; see
    the module docstring). with_clearance: False leaves ``clearance`` unmeasured (the
    flags are the same; a caller that asks only whether a pose holds a point skips the
    cloud's farther blocks)."""
    M = P.shape[0]
    K = DR.shape[0]
    E = openings.shape[1]
    f4 = np.float32
    order, start, centre, radius, cloud = point_blocks
    B = len(radius)
    blk = (order, start, centre, radius, cloud, np.empty(B), np.empty(B, np.bool_), np.empty(B, np.bool_))
    work = (np.empty(M, np.int64), np.empty(M, f4), np.empty(M, f4), np.empty(M, f4), np.empty(M, f4),
            np.empty(M, f4), np.empty(M, np.bool_), np.empty(M, f4), np.empty(M, np.int32), np.empty(M, f4),
            np.empty(M, np.int32))
    kept = (np.empty(M, f4), np.empty(M, f4), np.empty(M, f4), np.empty(M, f4), np.empty(M, f4), np.empty(M, f4),
            np.empty(M, np.int32), np.empty(M, np.bool_))
    cqx, cqy, cqz, cr, creach, csd0, cbits0, ccl = kept
    sd, bits = np.empty(M, f4), np.empty(M, np.int32)
    near, ns, nr, nb, ncl = np.empty((M, 3)), np.empty(M), np.empty(M), np.empty(M, np.int32), np.empty(M, np.bool_)
    n0, fixed, fixed_in = np.empty(M), np.empty(K, np.bool_), np.empty(K, np.bool_)
    cloud_masked = (mask & CLOUD) != 0
    cf, hits = np.empty(K, np.int32), np.empty(K, np.int32)
    px, py, pz, live, inside = np.empty(K), np.empty(K), np.empty(K), np.empty(K, np.bool_), np.empty(K, np.bool_)
    D = np.empty((12, K))  # the perturbations' rotations (row-major) and translations, one lane each
    for k in range(K):
        for r in range(3):
            for c in range(3):
                D[3 * r + c, k] = DR[k, r, c]
            D[9 + r, k] = Dt[k, r]
    thmax = 0.0
    pmax = 0.0
    for k in range(K):
        thmax = max(thmax, theta[k])
        pmax = max(pmax, tlen[k])
    for i in range(lo, hi):
        ho_lo, ho_hi = 0.5 * openings[i, 0], 0.5 * openings[i, 0]
        for e in range(E):
            ho_lo, ho_hi = min(ho_lo, 0.5 * openings[i, e]), max(ho_hi, 0.5 * openings[i, e])
        nc = _kept_points(P, n_cloud, R, w, i, pivot, thmax, pmax + margin, ho_lo, ho_hi, bc, bh, bs, blk, work,
                          kept, with_clearance)
        _contacts(i, qc, nq, sign, DR, Dt, pad, cos_fc, cf)
        done = False
        for e in range(E):
            if done:
                clearance[i, e] = np.inf
                for k in range(K):
                    flags[i, e, k] = NOT_SCORED
                continue
            _opening(i, e, 0.5 * openings[i, e], cqx, cqy, cqz, cr, creach, csd0, cbits0, ccl, nc, sd, bits, near,
                     ns, nr, nb, ncl, cf, bc, bh, bs, DR, Dt, D, theta, tlen, table, margin, px, py, pz, live, inside,
                     hits, clearance, flags, n0, fixed, fixed_in)
            done = allow[i, e]
            for k in range(K):
                done = done and (flags[i, e, k] & mask) == 0
            if cloud_masked and not done:  # every pose holds a cloud point in a box that does not move: at
                held = True  # every wider opening too, so no opening can score (the caller reports this one)
                for k in range(K):
                    held = held and fixed[k]
                done = held
