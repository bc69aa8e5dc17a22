"""Compiled robustness kernel: the gripper's boxes against points, under pose error (numba).

For each grasp i (wrist rotation R_i, position w_i in the object frame, pad gap o_i)
the kernel takes every obstacle point p into the wrist frame, q = R_i^T (p - w_i),
and computes its signed distance s(q) to the union of the gripper's boxes (x centres
moved by x_sign * o_i / 2): negative inside. The grasp's clearance is the smallest
s over the first ``n_cloud`` points (the observed cloud).

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

Per grasp and perturbation the kernel writes a bit set (uint8): 1 a cloud point
closer than ``margin`` to a box (cloud collision), 2 the same for a primitive surface
sample, 4 a box below the table (lower than ``table[4]`` above the plane), 8 a contact
off its pad (outside the finger's width or the pad's length), 16 the closing axis
outside either contact's friction cone. 0 means feasible.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["robust_flags", "CLOUD", "PRIMITIVE", "TABLE", "OFF_PAD", "NO_FC"]

CLOUD, PRIMITIVE, TABLE, OFF_PAD, NO_FC = 1, 2, 4, 8, 16
_BIG = 1e9


@njit(cache=True, nogil=True, fastmath=True)
def robust_flags(P, n_cloud, R, w, opening, bc, bh, bs, qc, nq, sign, DR, Dt, theta, tlen, pivot,
                 table, pad, cos_fc, margin, lo, hi, clearance, flags):  # pragma: no cover
    """Grasps [lo, hi): clearance (N,) to the cloud points P[:n_cloud] and flags (N, K)
    for perturbations DR (K, 3, 3), Dt (K, 3) (theta, tlen (K,): their bounds).

    qc, nq: (N, 2, 3) contacts and outward normals in each grasp's nominal wrist frame;
    sign (N,): +1 when contact 1 lies on the +x side of contact 0. table: (nr_x, nr_y,
    nr_z, height of the wrist origin, required height) with nr (N, ...) given per grasp
    as table[i] (a row of zeros and a huge height: no table). pad: (half width, z_lo,
    z_hi) of the pads in the wrist frame."""
    M = P.shape[0]
    K = DR.shape[0]
    B = bc.shape[0]
    f4 = np.float32
    zero = f4(0.0)
    qx = np.empty(M, f4)
    qy = np.empty(M, f4)
    qz = np.empty(M, f4)
    sd = np.empty(M, f4)
    rr = np.empty(M, f4)
    reach = np.empty(M, f4)
    bits = np.empty(M, np.int32)
    near = np.empty((M, 3))
    ns = np.empty(M)
    nr = np.empty(M)
    nb = np.empty(M, np.int32)
    ncl = np.empty(M, np.bool_)
    thmax = 0.0
    pmax = 0.0
    for k in range(K):
        thmax = max(thmax, theta[k])
        pmax = max(pmax, tlen[k])
    th4, pm4 = f4(thmax), f4(pmax + margin)
    cx0, cy0, cz0 = f4(pivot[0]), f4(pivot[1]), f4(pivot[2])
    for i in range(lo, hi):
        ho = 0.5 * opening[i]
        # branch-free float32 loops over the points (vectorised): wrist coordinates and
        # how far the largest perturbation can move them, then the signed distance to
        # each box (running minimum) and which boxes they can reach
        r00, r01, r02 = f4(R[i, 0, 0]), f4(R[i, 0, 1]), f4(R[i, 0, 2])
        r10, r11, r12 = f4(R[i, 1, 0]), f4(R[i, 1, 1]), f4(R[i, 1, 2])
        r20, r21, r22 = f4(R[i, 2, 0]), f4(R[i, 2, 1]), f4(R[i, 2, 2])
        wx, wy, wz = f4(w[i, 0]), f4(w[i, 1]), f4(w[i, 2])
        for m in range(M):
            dx = P[m, 0] - wx
            dy = P[m, 1] - wy
            dz = P[m, 2] - wz
            x = r00 * dx + r10 * dy + r20 * dz
            y = r01 * dx + r11 * dy + r21 * dz
            z = r02 * dx + r12 * dy + r22 * dz
            qx[m], qy[m], qz[m] = x, y, z
            r = np.sqrt((x - cx0) * (x - cx0) + (y - cy0) * (y - cy0) + (z - cz0) * (z - cz0))
            rr[m] = r
            reach[m] = th4 * r + pm4
            sd[m] = f4(_BIG)
            bits[m] = 0
        for b in range(B):
            cx, cy, cz = f4(bc[b, 0] + bs[b] * ho), f4(bc[b, 1]), f4(bc[b, 2])
            hx, hy, hz = f4(bh[b, 0]), f4(bh[b, 1]), f4(bh[b, 2])
            bit = np.int32(1 << b)
            for m in range(M):
                ex = abs(qx[m] - cx) - hx
                ey = abs(qy[m] - cy) - hy
                ez = abs(qz[m] - cz) - hz
                ox, oy, oz = max(ex, zero), max(ey, zero), max(ez, zero)
                d = np.sqrt(ox * ox + oy * oy + oz * oz) + min(max(ex, max(ey, ez)), zero)
                sd[m] = min(sd[m], d)
                bits[m] |= bit * np.int32(d <= reach[m])
        clear = f4(_BIG)
        for m in range(n_cloud):
            clear = min(clear, sd[m])
        clearance[i] = clear
        n = 0
        for m in range(M):
            if bits[m]:
                near[n, 0] = qx[m]
                near[n, 1] = qy[m]
                near[n, 2] = qz[m]
                ns[n] = sd[m]
                nr[n] = rr[m]
                nb[n] = bits[m]
                ncl[n] = m < n_cloud
                n += 1
        for k in range(K):
            f = 0
            for j in range(n):
                bit = CLOUD if ncl[j] else PRIMITIVE
                if f & bit or ns[j] > theta[k] * nr[j] + tlen[k] + margin:
                    continue
                ax = near[j, 0] - Dt[k, 0]
                ay = near[j, 1] - Dt[k, 1]
                az = near[j, 2] - Dt[k, 2]
                px = DR[k, 0, 0] * ax + DR[k, 1, 0] * ay + DR[k, 2, 0] * az
                py = DR[k, 0, 1] * ax + DR[k, 1, 1] * ay + DR[k, 2, 1] * az
                pz = DR[k, 0, 2] * ax + DR[k, 1, 2] * ay + DR[k, 2, 2] * az
                for b in range(B):  # inside a reachable box grown by the margin
                    if (nb[j] >> b) & 1 and (abs(px - bc[b, 0] - bs[b] * ho) < bh[b, 0] + margin
                                             and abs(py - bc[b, 1]) < bh[b, 1] + margin
                                             and abs(pz - bc[b, 2]) < bh[b, 2] + margin):
                        f |= bit
                        break
                if f & (CLOUD | PRIMITIVE) == (CLOUD | PRIMITIVE):
                    break
            # table: the lowest box corner along the plane's normal
            nx = DR[k, 0, 0] * table[i, 0] + DR[k, 1, 0] * table[i, 1] + DR[k, 2, 0] * table[i, 2]
            ny = DR[k, 0, 1] * table[i, 0] + DR[k, 1, 1] * table[i, 1] + DR[k, 2, 1] * table[i, 2]
            nz = DR[k, 0, 2] * table[i, 0] + DR[k, 1, 2] * table[i, 1] + DR[k, 2, 2] * table[i, 2]
            base = table[i, 3] + table[i, 0] * Dt[k, 0] + table[i, 1] * Dt[k, 1] + table[i, 2] * Dt[k, 2]
            for b in range(bc.shape[0]):
                h = (base + nx * (bc[b, 0] + bs[b] * ho) + ny * bc[b, 1] + nz * bc[b, 2]
                     - bh[b, 0] * abs(nx) - bh[b, 1] * abs(ny) - bh[b, 2] * abs(nz))
                if h < table[i, 4]:
                    f |= TABLE
                    break
            # contacts on the pads, closing axis inside both friction cones
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
            flags[i, k] = f
