"""Compiled signed distances of posed primitive models (numba): :func:`model_sdf` of
:mod:`graspsim.primitives.sdf` in one pass per point, without its (H, N, 3)
temporaries -- the fitters call it thousands of times per cloud on a few hundred points.

Every value is computed with the numpy expressions' operations in the same order (no
fast-math; numpy's ``maximum``/``minimum``/``clip`` NaN and signed-zero rules), so the
distances are the same to the bit; ``tests/test_perception_shapes_kernel.py`` checks
them against the numpy formulas.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["KIND_IDS", "model_sdf_into"]

#: The kernel's kind codes.
KIND_IDS = {"sphere": 0, "cylinder": 1, "box": 2, "cone": 3, "half_toroid": 4}


@njit(cache=True, inline="always")
def _max(a, b):  # pragma: no cover - numpy.maximum: the first NaN, else a on ties
    return a if (a >= b or a != a) else b


@njit(cache=True, inline="always")
def _min(a, b):  # pragma: no cover - numpy.minimum
    return a if (a <= b or a != a) else b


@njit(cache=True, inline="always")
def _clip01(a):  # pragma: no cover - numpy.clip(a, 0, 1): NaN kept, else a > lo ? a : lo, then a < hi ? a : hi
    if a != a:
        return a
    a = a if a > 0.0 else 0.0
    return a if a < 1.0 else 1.0


@njit(cache=True, nogil=True)
def model_sdf_into(kind, R, t, dims, points, out):  # pragma: no cover
    """out (H, N) = signed distances of points (N, 3) to H models: rotations R (H, 3, 3),
    positions t (H, 3), dims (H, k); ``kind`` a :data:`KIND_IDS` code. float64."""
    H = R.shape[0]
    N = points.shape[0]
    for h in range(H):
        for i in range(N):
            d0 = points[i, 0] - t[h, 0]
            d1 = points[i, 1] - t[h, 1]
            d2 = points[i, 2] - t[h, 2]
            x = d0 * R[h, 0, 0] + d1 * R[h, 1, 0] + d2 * R[h, 2, 0]
            y = d0 * R[h, 0, 1] + d1 * R[h, 1, 1] + d2 * R[h, 2, 1]
            z = d0 * R[h, 0, 2] + d1 * R[h, 1, 2] + d2 * R[h, 2, 2]
            if kind == 0:
                out[h, i] = math.sqrt(x * x + y * y + z * z) - dims[h, 0]
            elif kind == 1:
                dr = math.sqrt(x * x + y * y) - dims[h, 0]
                dz = abs(z) - 0.5 * dims[h, 1]
                out[h, i] = math.hypot(_max(dr, 0.0), _max(dz, 0.0)) + _min(_max(dr, dz), 0.0)
            elif kind == 2:
                qx = abs(x) - 0.5 * dims[h, 0]
                qy = abs(y) - 0.5 * dims[h, 1]
                qz = abs(z) - 0.5 * dims[h, 2]
                mx, my, mz = _max(qx, 0.0), _max(qy, 0.0), _max(qz, 0.0)
                top = _max(_max(qx, qy), qz)
                out[h, i] = math.sqrt(mx * mx + my * my + mz * mz) + _min(top, 0.0)
            elif kind == 3:
                r0, r1, hh = dims[h, 0], dims[h, 1], dims[h, 2]
                rho = math.sqrt(x * x + y * y)
                zb = z + 0.5 * hh
                d_bot = math.hypot(rho - _min(rho, r0), zb)
                d_top = math.hypot(rho - _min(rho, r1), zb - hh)
                ex, ez = r1 - r0, hh
                s = _clip01(((rho - r0) * ex + zb * ez) / _max(ex * ex + ez * ez, 1e-30))
                d_side = math.hypot(rho - (r0 + s * ex), zb - s * ez)
                dist = _min(_min(d_bot, d_top), d_side)
                inside = (zb >= 0.0) and (zb <= hh) and (rho * hh <= r0 * hh + (r1 - r0) * zb)
                out[h, i] = -dist if inside else dist
            else:
                Rm, r = dims[h, 0], dims[h, 1]
                if y >= 0.0:
                    torus = math.hypot(math.hypot(x, y) - Rm, z) - r
                    out[h, i] = _max(torus, -y) if torus < 0.0 else torus
                else:
                    out[h, i] = _min(math.hypot(_max(math.hypot(x - Rm, z) - r, 0.0), y),
                                     math.hypot(_max(math.hypot(x + Rm, z) - r, 0.0), y))
    return out


def model_sdf(kind: str, R: np.ndarray, t: np.ndarray, dims: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(H, N) signed distances (all inputs float64 arrays of the shapes above)."""
    out = np.empty((R.shape[0], points.shape[0]))
    c = np.ascontiguousarray
    return model_sdf_into(KIND_IDS[kind], c(R), c(t), c(dims), c(points), out)
