"""Compiled pad-contact kernel: where flat finger pads first touch the object (numba).

For each grasp (wrist pose R, p in the object frame) and each of the two fingers, the
object's surface samples are taken into the wrist frame (x = closing axis, y = pad
width, z = approach). A sample lies in a finger's *footprint* when |y| <= half_width
and fingertip_z - face_length <= z <= fingertip_z. Closing along x, the negative
finger first touches the footprint sample with the smallest x and the positive finger
the one with the largest x; the *patch* of a finger is every footprint sample within
``tol`` of that extreme. The kernel returns, per grasp and finger, the patch's area,
area-weighted mean outward normal (wrist frame, not normalised) and mean distance to
the footprint's border, and the extreme x.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["SERIAL_BELOW", "pad_patches", "pad_patches_serial", "run_pad_patches", "serial_only"]


@njit(cache=True, inline="always")
def _in_footprint(R, p, P, i, m, half_width, tip_z, z_lo):  # pragma: no cover
    """Sample m in grasp i's wrist frame: (inside a finger's footprint, x, y, z); the
    cheap tests first (y, then z), x only for samples inside."""
    dx = P[m, 0] - p[i, 0]
    dy = P[m, 1] - p[i, 1]
    dz = P[m, 2] - p[i, 2]
    y = R[i, 0, 1] * dx + R[i, 1, 1] * dy + R[i, 2, 1] * dz
    if y > half_width or y < -half_width:
        return False, 0.0, y, 0.0
    z = R[i, 0, 2] * dx + R[i, 1, 2] * dy + R[i, 2, 2] * dz
    if z > tip_z or z < z_lo:
        return False, 0.0, y, z
    return True, R[i, 0, 0] * dx + R[i, 1, 0] * dy + R[i, 2, 0] * dz, y, z


@njit(cache=True, inline="always")
def _one_grasp(P, N, A, R, p, i, half_width, tip_z, z_lo, tol, out):  # pragma: no cover
    """Grasp i's two patches into out[i] (see :func:`pad_patches`)."""
    M = P.shape[0]
    xmin = 1e300
    xmax = -1e300
    for m in range(M):
        inside, x, y, z = _in_footprint(R, p, P, i, m, half_width, tip_z, z_lo)
        if not inside:
            continue
        if x < xmin:
            xmin = x
        if x > xmax:
            xmax = x
    for k in range(2):
        for j in range(7):
            out[i, k, j] = 0.0
    out[i, 0, 5] = xmin
    out[i, 1, 5] = xmax
    if xmax < xmin:
        return
    for m in range(M):
        inside, x, y, z = _in_footprint(R, p, P, i, m, half_width, tip_z, z_lo)
        if not inside:
            continue
        k = -1
        if x <= xmin + tol:
            k = 0
        elif x >= xmax - tol:
            k = 1
        if k < 0:
            continue
        a = A[m]
        border = min(half_width - abs(y), min(tip_z - z, z - z_lo))
        out[i, k, 0] += a
        for c in range(3):
            out[i, k, 1 + c] += a * (R[i, 0, c] * N[m, 0] + R[i, 1, c] * N[m, 1]
                                     + R[i, 2, c] * N[m, 2])
        out[i, k, 4] += a * border
        out[i, k, 6] += 1.0


@njit(parallel=True, cache=True)
def pad_patches(P, N, A, R, p, half_width, tip_z, face_length, tol, out):  # pragma: no cover
    """P, N (M, 3) samples and outward normals, A (M,) areas, object frame.
    R (n, 3, 3) wrist rotations, p (n, 3) wrist positions, object frame.
    out (n, 2, 7) float64, per finger (0: -x, 1: +x): area, normal xyz (sum of
    area x normal), border-distance sum (area-weighted), extreme x, sample count."""
    z_lo = tip_z - face_length
    for i in prange(R.shape[0]):
        _one_grasp(P, N, A, R, p, i, half_width, tip_z, z_lo, tol, out)
    return out


@njit(cache=True)
def pad_patches_serial(P, N, A, R, p, half_width, tip_z, face_length, tol, out):  # pragma: no cover
    """:func:`pad_patches` on the calling thread only, without numba's thread pool (the
    same arithmetic per grasp, so the same results): for a few grasps, and in processes
    that may not start the pool (:func:`serial_only`). Its own function, not
    ``njit(pad_patches.py_func)``: numba's on-disk cache would hand that the parallel
    build of the same source."""
    z_lo = tip_z - face_length
    for i in range(R.shape[0]):
        _one_grasp(P, N, A, R, p, i, half_width, tip_z, z_lo, tol, out)
    return out


_serial_only = False


def serial_only() -> None:
    """Run the kernel on the calling thread only from now on, in this process: for a
    child forked after the parent ran the parallel kernel, where GNU OpenMP would
    terminate it (the scene's worker processes, :mod:`graspsim.planning.scene_workers`)."""
    global _serial_only
    _serial_only = True


def run_pad_patches(points: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                    R: np.ndarray, p: np.ndarray, half_width: float, tip_z: float,
                    face_length: float, tol: float) -> np.ndarray:
    """Typed wrapper of :func:`pad_patches`; returns (n, 2, 7). A few grasps run on the
    calling thread only (:data:`pad_patches_serial`): waking the thread pool costs more
    than they do (tens of milliseconds on a busy machine, where a streaming planner
    scores its first grasp)."""
    f = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    out = np.zeros((len(R), 2, 7))
    if len(R):
        kernel = pad_patches_serial if _serial_only or len(R) < SERIAL_BELOW else pad_patches
        kernel(f(points), f(normals), f(areas), f(R), f(p), float(half_width), float(tip_z),
               float(face_length), float(tol), out)
    return out


#: Fewer grasps than this are scored on the calling thread.
SERIAL_BELOW = 64
