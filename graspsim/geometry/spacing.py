"""A point cloud's spacing: the median distance from each point to its nearest other
location (:func:`median_spacing`), which identification, the robust score's occlusion term
and the compiled kernels' warm-up all read.

One identification asks about the same points more than once (a cluster's continuity
check, then the decomposition's context of the same cloud): the last
:data:`REMEMBERED` answers are kept, keyed by the points' bytes (a digest of every
coordinate: the same points give the same spacing, computed once; any other points are
measured afresh)."""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np

from graspsim.errors import PointCloudError

__all__ = ["median_spacing", "REMEMBERED"]

#: how many clouds' spacings :func:`median_spacing` keeps (a float each)
REMEMBERED = 64
_memo: OrderedDict[tuple, float] = OrderedDict()
_memo_lock = threading.Lock()


def median_spacing(points: np.ndarray) -> float:
    """The median distance [m] from each point of (N, 3) to its nearest *other location*:
    repeated points (a fixed-size cloud sampled with replacement) count once, so they
    do not read as zero spacing. 0 for fewer than two distinct points; a
    :class:`~graspsim.errors.PointCloudError` for NaN or inf coordinates."""
    P = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    if not np.isfinite(P).all():
        raise PointCloudError(f"point spacing needs finite coordinates; {int(np.sum(~np.isfinite(P).all(axis=1)))} "
                              f"of {len(P)} points have NaN or inf ones")
    key = (P.shape, hashlib.blake2b(P.tobytes(), digest_size=20).digest())
    with _memo_lock:
        if key in _memo:
            _memo.move_to_end(key)
            return _memo[key]
    from graspsim.geometry.spacing_kernel import nearest_other  # compiled: a few times faster than a KD-tree

    d = nearest_other(P) if len(P) else P[:, 0]
    out = float(np.median(d)) if len(d) >= 2 else 0.0
    with _memo_lock:
        _memo[key] = out
        while len(_memo) > REMEMBERED:
            _memo.popitem(last=False)
    return out
