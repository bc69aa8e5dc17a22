"""A point cloud's spacing: the median distance from each point to its nearest other
location (:func:`median_spacing`), which identification, the robust score's occlusion term
and the compiled kernels' warm-up all read."""

from __future__ import annotations

import numpy as np

from graspsim.errors import PointCloudError

__all__ = ["median_spacing"]


def median_spacing(points: np.ndarray) -> float:
    """The median distance [m] from each point of (N, 3) to its nearest *other location*:
    repeated points (a fixed-size cloud sampled with replacement) count once, so they
    do not read as zero spacing. 0 for fewer than two distinct points; a
    :class:`~graspsim.errors.PointCloudError` for NaN or inf coordinates."""
    P = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    if not np.isfinite(P).all():
        raise PointCloudError(f"point spacing needs finite coordinates; {int(np.sum(~np.isfinite(P).all(axis=1)))} "
                              f"of {len(P)} points have NaN or inf ones")
    from graspsim.geometry.spacing_kernel import nearest_other  # compiled: a few times faster than a KD-tree

    d = nearest_other(P) if len(P) else P[:, 0]
    return float(np.median(d)) if len(d) >= 2 else 0.0
