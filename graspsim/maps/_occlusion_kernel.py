"""Compiled occlusion term of the robust score (numba): the fraction of each wrist
pose's finger samples that lie in occluded space (:func:`graspsim.maps.occlusion.finger_occlusion`).

One pass per finger sample, nothing held between them: the sample moved by its jaw's
half gap, taken into the view's frame, projected to its pixel and compared with the
depth image there -- what :meth:`~graspsim.maps.occlusion.ViewDepth.occluded` does with
numpy over (poses x samples, 3) arrays it makes first. The arithmetic is the same
formulas in float64 (no fast-math), summed in a fixed order where numpy's matrix
products may sum in another: a sample within a rounding error of a pixel edge or of the
occlusion depth may fall the other way (``tests/test_robust_execution.py`` holds the
two to agree on every sample of a real scene's grasps).
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["occluded_fraction"]


@njit(cache=True, nogil=True)
def occluded_fraction(R, w, half_gap, q, x_sign, viewpoint, basis, origin, pixel, depth, tolerance,
                      out):  # pragma: no cover
    """out (n,): the fraction of finger samples q (S, 3) (wrist frame at zero gap; sample
    k moved along x by x_sign[k] x half_gap[i]) of wrist pose i (R (n, 3, 3), w (n, 3),
    the view's frame) more than ``tolerance`` behind the depth image ``depth`` (I, J)
    (pixels ``pixel`` wide from ``origin`` (2,) in the tangent plane of the view
    ``basis`` (3, 3) rows from ``viewpoint`` (3,)). Samples behind the viewpoint or
    outside the image are not occluded."""
    n = R.shape[0]
    S = q.shape[0]
    I, J = depth.shape
    for i in range(n):
        hits = 0
        for k in range(S):
            lx = q[k, 0] + x_sign[k] * half_gap[i]
            ly = q[k, 1]
            lz = q[k, 2]
            x = R[i, 0, 0] * lx + R[i, 0, 1] * ly + R[i, 0, 2] * lz + w[i, 0] - viewpoint[0]
            y = R[i, 1, 0] * lx + R[i, 1, 1] * ly + R[i, 1, 2] * lz + w[i, 1] - viewpoint[1]
            z = R[i, 2, 0] * lx + R[i, 2, 1] * ly + R[i, 2, 2] * lz + w[i, 2] - viewpoint[2]
            d0 = x * basis[0, 0] + y * basis[0, 1] + z * basis[0, 2]
            d1 = x * basis[1, 0] + y * basis[1, 1] + z * basis[1, 2]
            d2 = x * basis[2, 0] + y * basis[2, 1] + z * basis[2, 2]
            if not d2 > 1e-9:
                continue
            a = math.floor((d0 / d2 - origin[0]) / pixel)
            b = math.floor((d1 / d2 - origin[1]) / pixel)
            if a < 0 or a >= I or b < 0 or b >= J:
                continue
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > depth[int(a), int(b)] + tolerance:
                hits += 1
        out[i] = hits / S
