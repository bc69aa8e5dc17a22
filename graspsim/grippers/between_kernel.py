"""Compiled count of the points between a gripper's pads (numba), for
:meth:`graspsim.grippers.spec.GripperSpec.points_between`.

One pass per (pose, point), nothing held between them: the point taken into the wrist
frame, ``R^T (p - t)``, one axis at a time, and tested against the closing region's
faces, the next axis computed only while the point is still inside. numpy's version made
a (poses, points, 3) array first -- a few tens of MB per chunk for a scene's segment,
most of its time spent making and reducing it (20x the kernel's per call). The arithmetic
is the same sums in float64 (no fast-math), but einsum may add the three terms in another
order: a point within a rounding error of a face may fall the other way in principle.
``tests/test_seen_between.py`` holds the two to the same counts, and scene planning's
results were the same to the bit (``experiments/scene_fingerprint.py``).
"""

from __future__ import annotations

from numba import njit

__all__ = ["count_between"]


@njit(cache=True, nogil=True)
def count_between(R, t, half, P, y_half, z_lo, z_hi, out):  # pragma: no cover
    """out (n,): how many points P (M, 3) lie strictly inside the closing region of wrist
    pose i (R (n, 3, 3), t (n, 3), the points' frame): |x| < half[i], |y| < y_half,
    z_lo < z < z_hi in the wrist frame."""
    n = R.shape[0]
    M = P.shape[0]
    for i in range(n):
        tx, ty, tz, h = t[i, 0], t[i, 1], t[i, 2], half[i]
        c = 0
        for m in range(M):
            dx, dy, dz = P[m, 0] - tx, P[m, 1] - ty, P[m, 2] - tz
            lx = (R[i, 0, 0] * dx + R[i, 1, 0] * dy) + R[i, 2, 0] * dz
            if not abs(lx) < h:
                continue
            ly = (R[i, 0, 1] * dx + R[i, 1, 1] * dy) + R[i, 2, 1] * dz
            if not abs(ly) < y_half:
                continue
            lz = (R[i, 0, 2] * dx + R[i, 1, 2] * dy) + R[i, 2, 2] * dz
            if z_lo < lz < z_hi:
                c += 1
        out[i] = c
