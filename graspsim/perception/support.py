"""Support of a fitted model by its cluster: how far the model extends beyond its
points, and how much of its surface has points near it.

A fit rate says how many *points* a model explains; it does not say whether the
model is the shape the points come from. A model much larger than its cluster (a
24 cm half-toroid through a brush's 30 cm cloud, a 47 cm box along a 25 cm handle)
can explain most points of a sparse or thin cluster while most of its surface is
empty. One camera sees about half of a convex body (less where other parts occlude
it, as little as a sixth of a thin plate seen edge-on), so low coverage alone is no
proof; but empty surface that also reaches beyond the cluster's extent is surface the
camera would have seen.

* :func:`extent_ratio`: along each axis of its fit frame, the model's extent over the
  cluster's (1-99 % quantiles) plus 4 noise sigmas; the largest of the three. One view
  sees at least half of a convex body along any axis, so about 2 at most.
* :func:`surface_coverage`: area fraction of the model's surface with a cluster point
  near it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from graspsim.errors import GraspsimError
from graspsim.primitives.sdf import fit_to_object, model_extents, to_local

__all__ = ["extent_ratio", "surface_coverage"]


def extent_ratio(kind: str, R: np.ndarray, t: np.ndarray, dims: np.ndarray, points: np.ndarray,
                 noise: float, *, max_points: int = 256) -> np.ndarray:
    """(H,) largest ratio, over the axes of each model's fit frame, of the extent of
    the model (R (H, 3, 3), t (H, 3), dims (H, k)) to that of the points (N, 3) [m]
    plus 4 ``noise`` [m]; the points are subsampled to ``max_points``."""
    if len(R) == 0:
        return np.zeros(0)
    p = points if len(points) <= max_points else points[np.linspace(0, len(points) - 1, max_points).astype(int)]
    q = np.sort(to_local(R, t, p), axis=1)  # (H, M, 3)
    lo, hi = q[:, int(0.01 * (len(p) - 1))], q[:, int(np.ceil(0.99 * (len(p) - 1)))]
    return np.max(model_extents(kind, dims) / (hi - lo + 4.0 * noise), axis=1)


def surface_coverage(kind: str, R: np.ndarray, t: np.ndarray, dims: np.ndarray, tree: cKDTree,
                     *, radius: float, steps: int = 25) -> float:
    """Area fraction in [0, 1] of the surface of one fitted model (``T_world_fit`` =
    (R (3, 3), t (3,)), dims (k,)) that has a cluster point (``tree`` over the points,
    world frame) within ``radius`` [m]; samples on a deterministic surface grid with
    ``steps`` steps along the model's size scale (not finer than radius / 4)."""
    try:
        prim, T = fit_to_object(kind, R, t, dims)
        step = min(max(prim.size_scale / steps, 0.25 * radius), 0.5 * prim.size_scale)
        s = prim.surface_samples(step)
    except GraspsimError:  # degenerate dims (zero radius or height): no surface to cover
        return 0.0
    world = s.points @ T[:3, :3].T + T[:3, 3]
    d, _ = tree.query(world, distance_upper_bound=radius)
    w = s.areas
    return float(np.sum(w[np.isfinite(d)]) / max(np.sum(w), 1e-300))
