"""The table under a scene: its plane found by MLESAC, the points on it removed.

A depth camera looking at a table sees mostly table. :func:`fit_table` draws planes
through random point triples and scores them, a block at a time, with the
Gaussian/uniform mixture likelihood of :func:`~graspsim.perception.mlesac.mixture_loglik`
(the identification's MLESAC, on a fixed subsample of the points); it stops once as
many have been scored as the standard RANSAC bound asks for at the best plane's inlier
share (:func:`ransac_bound`: with that share, one all-inlier triple among them is
drawn with probability ``confidence``; a table that fills most of the view is found
after a few dozen, not the ``repetitions`` drawn). It refines the best by
least squares on its inliers (twice, re-selecting them) and orients its normal
upwards: towards the side most off-plane points lie on (objects stand on the table),
or along ``up`` when the caller knows it. The result becomes graspsim's
:class:`~graspsim.maps.table_clearance.TablePlane` (normal . p = height, cloud frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graspsim.errors import InvalidParameterError, PointCloudError
from graspsim.geometry.table import TablePlane
from graspsim.perception.mlesac import mixture_loglik

__all__ = ["PlaneFit", "fit_table", "ransac_bound"]

#: Plane hypotheses scored at once (the stopping rule is checked after each block).
PLANE_BLOCK = 25


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """normal (3,): the table's upward unit normal; height: its offset [m] (points p on
    it have normal . p = height); inliers (N,) bool: the input points on it (within
    3 sigma); rms: RMS distance of the inliers to it [m]; share: inliers / points."""

    normal: np.ndarray
    height: float
    inliers: np.ndarray
    rms: float
    share: float

    def heights(self, points: np.ndarray) -> np.ndarray:
        """(N,) signed height of points (N, 3) [m] above the plane."""
        return np.asarray(points, float) @ self.normal - self.height

    def table(self, clearance: float = 0.002) -> TablePlane:
        """The plane as the planner's :class:`~graspsim.maps.table_clearance.TablePlane`."""
        return TablePlane(normal=tuple(self.normal), height=self.height, clearance=clearance)

    def to_dict(self) -> dict:
        return {"normal": self.normal.tolist(), "height": self.height, "rms": self.rms, "share": self.share,
                "inliers": int(self.inliers.sum())}


def _refine(points: np.ndarray, normal: np.ndarray, height: float, band: float,
            max_points: int) -> tuple[np.ndarray, float]:
    """Least-squares plane (normal, height) of the points within ``band`` of the given
    one (at most ``max_points`` of them, evenly spread)."""
    near = np.flatnonzero(np.abs(points @ normal - height) < band)
    if len(near) < 3:
        return normal, height
    near = near[np.linspace(0, len(near) - 1, min(len(near), max_points)).astype(int)]
    p = points[near]
    c = p.mean(axis=0)
    n = np.linalg.svd(p - c, full_matrices=False)[2][2]
    n = n if n @ normal >= 0 else -n
    return n, float(n @ c)


def ransac_bound(share: float, sample: int, confidence: float) -> float:
    """Hypotheses to draw so that, with ``confidence``, at least one ``sample``-point
    draw is all inliers when a fraction ``share`` of the points are inliers:
    log(1 - confidence) / log(1 - share^sample) (inf for no inliers, 1 for all)."""
    w = float(np.clip(share, 0.0, 1.0)) ** sample
    if w >= 1.0:
        return 1.0
    if w <= 0.0:
        return float("inf")
    return float(np.log1p(-confidence) / np.log1p(-w))


def _best_plane(sub: np.ndarray, nrm: np.ndarray, d: np.ndarray, sigma: float, confidence: float | None) -> int:
    """Index of the most likely plane (the first best), scored a block at a time and
    stopping once the RANSAC bound at the best plane's mixing weight is met
    (``confidence`` None: every plane)."""
    nu = float(np.linalg.norm(np.ptp(sub, axis=0))) + 10.0 * sigma
    best, best_ll = 0, -np.inf
    for lo in range(0, len(nrm), PLANE_BLOCK):
        hi = min(lo + PLANE_BLOCK, len(nrm))
        loglik, gamma, _ = mixture_loglik(np.abs(nrm[lo:hi] @ sub.T - d[lo:hi, None]), sigma, nu)
        b = int(np.argmax(loglik))
        if loglik[b] > best_ll:
            best, best_ll, share = lo + b, float(loglik[b]), float(gamma[b])
        if confidence is not None and hi >= ransac_bound(share, 3, confidence):
            break
    return best


def fit_table(points: np.ndarray, rng: np.random.Generator, *, sigma: float = 0.002,
              repetitions: int = 200, score_points: int = 2000, min_share: float = 0.15,
              up: np.ndarray | None = None, confidence: float | None = 0.999) -> PlaneFit:
    """The dominant plane of a scene cloud (N, 3) [m] (see the module docstring).

    sigma: inlier noise [m]; repetitions: plane hypotheses drawn (at most scored);
    score_points: points they are scored on; min_share: the fewest points (a fraction)
    the table must hold, else :class:`PointCloudError` (no table in view); up: (3,) a
    direction the normal must point along (e.g. the world's z), or None; confidence:
    the RANSAC bound's (None: score all ``repetitions``). The draws do not depend on
    it: every triple is drawn first, so the generator is left in the same state."""
    pts = np.asarray(points, float)
    if not (sigma > 0 and repetitions >= 1 and score_points >= 3 and 0 < min_share < 1):
        raise InvalidParameterError(f"fit_table needs sigma > 0, repetitions >= 1, score_points >= 3 and "
                                    f"0 < min_share < 1; got {sigma!r}, {repetitions!r}, {score_points!r}, "
                                    f"{min_share!r}")
    if confidence is not None and not 0 < confidence < 1:
        raise InvalidParameterError(f"fit_table's confidence must be in (0, 1) or None, got {confidence!r}")
    n_pts = len(pts)
    sub = pts[np.sort(rng.choice(n_pts, size=min(score_points, n_pts), replace=False))]
    tri = pts[rng.integers(0, n_pts, size=(repetitions, 3))]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(nrm, axis=1)
    ok = length > 1e-12
    if not np.any(ok):
        raise PointCloudError("no table plane: every sampled point triple is collinear")
    nrm = nrm[ok] / length[ok, None]
    d = np.einsum("hi,hi->h", nrm, tri[ok, 0])
    best = _best_plane(sub, nrm, d, sigma, confidence)
    normal, height = nrm[best], float(d[best])
    for band in (3.0 * sigma, 3.0 * sigma):
        normal, height = _refine(pts, normal, height, band, 20_000)
    dist = pts @ normal - height
    inliers = np.abs(dist) < 3.0 * sigma
    share = float(inliers.mean())
    if share < min_share:
        raise PointCloudError(
            f"no table plane in view: the best plane holds {100 * share:.1f} % of the {n_pts} points (at least "
            f"{100 * min_share:.0f} % needed); is the table in the camera's view, and the cloud in metres?")
    if up is not None:
        flip = float(np.asarray(up, float) @ normal) < 0
    else:
        off = dist[~inliers]
        flip = bool(len(off)) and int(np.sum(off < 0)) > int(np.sum(off > 0))
    if flip:
        normal, height = -normal, -height
    rms = float(np.sqrt(np.mean(dist[inliers] ** 2))) if inliers.any() else 0.0
    return PlaneFit(normal, height, inliers, rms, share)
