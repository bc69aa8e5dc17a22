"""Compiled assembly of a map's rows from the collision sweep's flags (numba): one
kernel of the set :mod:`graspsim.maps._kernel` compiles and caches (its ``SIGNATURES``)."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["assemble_rows"]


@njit(cache=True, nogil=True, fastmath=False)
def assemble_rows(free, u, e1, e2, gp, cos_r, sin_r, tcp, offsets, line_cols, pair_cols,
                  line_scalars, wrist, quat, rows_vec, rows_c, rows_n, rows_scalar, line0, line1):
    """Fill the map's row columns for every free pose of lines ``line0 <= l < line1``,
    in (line, roll, depth) order.

    free: (L, R, D) uint8; u, e1, e2, gp: (L, 3) line frames and grasp points; tcp: (D,)
    wrist-to-grasp-point distance along z per depth; offsets: (L + 1,) first row of each
    line. Per-line data copied to each of the line's rows: line_cols (L, 3) -> rows_vec
    (N, 3); pair_cols (L, 2, 2, 3) (contacts, normals) -> rows_c, rows_n (N, 2, 3);
    line_scalars (L, S) -> rows_scalar (S, N). Computes wrist (N, 3) and quat (N, 4)
    w,x,y,z of the wrist axes x = u, z = cos e1 + sin e2, y = z x x.
    """
    R, D = free.shape[1], free.shape[2]
    S = line_scalars.shape[1]
    for li in range(line0, line1):
        row = offsets[li]
        if offsets[li + 1] == row:
            continue
        ux, uy, uz = u[li, 0], u[li, 1], u[li, 2]
        for r in range(R):
            c, s = cos_r[r], sin_r[r]
            zx = c * e1[li, 0] + s * e2[li, 0]
            zy = c * e1[li, 1] + s * e2[li, 1]
            zz = c * e1[li, 2] + s * e2[li, 2]
            yx = zy * uz - zz * uy
            yy = zz * ux - zx * uz
            yz = zx * uy - zy * ux
            w, x, y, z = _quat(ux, yx, zx, uy, yy, zy, uz, yz, zz)
            for k in range(D):
                if free[li, r, k]:
                    wrist[row, 0] = gp[li, 0] - tcp[k] * zx
                    wrist[row, 1] = gp[li, 1] - tcp[k] * zy
                    wrist[row, 2] = gp[li, 2] - tcp[k] * zz
                    quat[row, 0] = w
                    quat[row, 1] = x
                    quat[row, 2] = y
                    quat[row, 3] = z
                    for j in range(3):
                        rows_vec[row, j] = line_cols[li, j]
                    for a in range(2):
                        for j in range(3):
                            rows_c[row, a, j] = pair_cols[li, 0, a, j]
                            rows_n[row, a, j] = pair_cols[li, 1, a, j]
                    for j in range(S):
                        rows_scalar[j, row] = line_scalars[li, j]
                    row += 1


@njit(cache=True)
def _quat(m00, m01, m02, m10, m11, m12, m20, m21, m22):
    """Rotation matrix -> unit quaternion w, x, y, z with w >= 0 (Shepperd's method)."""
    tr = m00 + m11 + m22
    if tr > 0.0:
        S = np.sqrt(tr + 1.0) * 2.0
        w, x, y, z = 0.25 * S, (m21 - m12) / S, (m02 - m20) / S, (m10 - m01) / S
    elif m00 > m11 and m00 > m22:
        S = np.sqrt(1.0 + m00 - m11 - m22) * 2.0
        w, x, y, z = (m21 - m12) / S, 0.25 * S, (m01 + m10) / S, (m02 + m20) / S
    elif m11 > m22:
        S = np.sqrt(1.0 + m11 - m00 - m22) * 2.0
        w, x, y, z = (m02 - m20) / S, (m01 + m10) / S, 0.25 * S, (m12 + m21) / S
    else:
        S = np.sqrt(1.0 + m22 - m00 - m11) * 2.0
        w, x, y, z = (m10 - m01) / S, (m02 + m20) / S, (m12 + m21) / S, 0.25 * S
    if w < 0.0:
        return -w, -x, -y, -z
    return w, x, y, z
