"""Minimal-sample model hypotheses from points with normals (as in efficient RANSAC,
Schnabel et al. 2007), vectorised over H samples.

Each solver takes the cloud, its normals and sample indices (H, m) and returns poses
and dims in the fit frames of :mod:`graspsim.primitives.sdf`, plus a validity mask.
Extents a minimal sample cannot see (a cylinder's height, a box's edges, a cone's cut
heights, which half of a torus is kept) are completed from the cloud: robust extremes
of the points consistent with the hypothesised surface.

Samples (one hypothesis each):

* sphere, 2 points: centre where the two normal lines meet;
* cylinder, 3 points: the pair whose normal cross product the third normal agrees
  with best (perpendicular: side point, parallel: cap point) gives the axis, the pair's
  normal lines projected along it meet on the axis;
* box, 3 points: the two most orthogonal normals give two edge directions; with no
  such pair (one face seen by a camera, a thin plate) the principal axes of the points
  projected along the first normal give the other two;
* cone, 4 points: side normals make the same angle with the axis, so for a triple
  ``(n1 - n2) x (n1 - n3)`` is the axis; the triple the fourth point agrees with best
  is used; the normal lines cross the axis; the profile slope comes from the normals;
* half-toroid, 4 points: tube centres ``p - r n`` lie on the ring circle and every
  normal lies in its meridian plane; for each triple and each r on a grid the circle
  through the triple's tube centres is scored by both conditions on all four points.

The cone solver orients normals away from the cluster's centroid (outward on
any convex body, also when only one side is seen); the torus uses the curvature-based
orientation of :mod:`graspsim.perception.normals`.
"""

from __future__ import annotations

import numpy as np

from graspsim.transforms import cross3, frame_from_axes, normalize

__all__ = ["SAMPLE_SIZE", "hypothesise", "plausible"]

SAMPLE_SIZE = {"sphere": 2, "cylinder": 3, "box": 3, "cone": 4, "half_toroid": 4}
_TRIM = 0.005  # quantile used for robust extremes of the completing points


def hypothesise(kind, points, normals, idx, noise):
    """(R (H, 3, 3), t (H, 3), dims (H, k), valid (H,)) from samples idx (H, m)."""
    p, n = points[idx], normals[idx]
    R, t, dims, valid = _SOLVERS[kind](p, n, points, noise)
    valid &= plausible(kind, dims, float(np.linalg.norm(np.ptp(points, axis=0))))
    return R, t, dims, valid


def plausible(kind: str, dims: np.ndarray, size: float) -> np.ndarray:
    """(H,) bool: dims (H, k) [m] possible for a cluster whose bounding-box diagonal is
    ``size`` [m]. Curved surfaces must curve within the cluster: a sphere or cylinder
    far larger than the points is a plane in disguise (a single face seen by a camera)."""
    dims = np.atleast_2d(dims)
    ok = np.all(np.isfinite(dims), axis=1) & np.all(dims >= 0.0, axis=1)
    if kind in ("sphere", "cylinder"):
        ok &= dims[:, 0] <= 0.6 * size
    elif kind == "cone":
        ok &= np.max(dims[:, :2], axis=1) <= 0.8 * size
    elif kind == "half_toroid":
        ok &= (dims[:, 0] > dims[:, 1]) & (dims[:, 0] <= size)
    return ok


def _any_perp(a: np.ndarray) -> np.ndarray:
    """Some unit vector perpendicular to each a (H, 3)."""
    ref = np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    return normalize(cross3(a, ref))


def _masked_extremes(z: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust low/high (H,) of z (H, N) over mask (the _TRIM and 1 - _TRIM quantiles,
    nearest rank); also whether at least 4 points support them."""
    cnt = mask.sum(axis=1)
    srt = np.sort(np.where(mask, z, np.inf), axis=1)
    last = np.maximum(cnt - 1, 0)
    rows = np.arange(len(z))
    lo = srt[rows, np.floor(_TRIM * last).astype(int)]
    hi = srt[rows, np.ceil((1.0 - _TRIM) * last).astype(int)]
    ok = cnt >= 4
    return np.where(ok, lo, 0.0), np.where(ok, hi, 0.0), ok


def _line_meet(p1, n1, p2, n2):
    """Point (H, 3) nearest to two lines p + s n (least squares, midpoint if parallel)."""
    eye = np.eye(3)
    M = (eye - n1[:, :, None] * n1[:, None, :]) + (eye - n2[:, :, None] * n2[:, None, :])
    b = np.einsum("hij,hj->hi", eye - n1[:, :, None] * n1[:, None, :], p1) + np.einsum(
        "hij,hj->hi", eye - n2[:, :, None] * n2[:, None, :], p2)
    eps = 1e-3
    mid = 0.5 * (p1 + p2)
    return np.linalg.solve(M + eps * eye, (b + eps * mid)[..., None])[..., 0]


def _sphere(p, n, cloud, noise):
    c = _line_meet(p[:, 0], n[:, 0], p[:, 1], n[:, 1])
    r = 0.5 * (np.linalg.norm(p[:, 0] - c, axis=1) + np.linalg.norm(p[:, 1] - c, axis=1))
    R = np.broadcast_to(np.eye(3), (len(c), 3, 3)).copy()
    return R, c, r[:, None], (r > 0) & np.isfinite(r)


def _cylinder(p, n, cloud, noise):
    H = len(p)
    pairs = [(0, 1, 2), (0, 2, 1), (1, 2, 0)]
    best = np.full(H, np.inf)
    axis = np.zeros((H, 3))
    i_sel = np.zeros(H, int)
    j_sel = np.zeros(H, int)
    for i, j, k in pairs:
        cr = cross3(n[:, i], n[:, j])
        s = np.linalg.norm(cr, axis=1)
        a = cr / np.maximum(s, 1e-12)[:, None]
        cosk = np.abs(np.sum(n[:, k] * a, axis=1))
        dev = np.minimum(cosk, np.sqrt(np.maximum(1.0 - cosk**2, 0.0)))  # k lateral or on a cap
        score = np.where(s > 0.2, dev - 0.05 * s, np.inf)
        better = score < best
        best = np.where(better, score, best)
        axis[better], i_sel[better], j_sel[better] = a[better], i, j
    rows = np.arange(H)
    p1, p2 = p[rows, i_sel], p[rows, j_sel]
    n1 = normalize(n[rows, i_sel] - np.sum(n[rows, i_sel] * axis, 1)[:, None] * axis)
    n2 = normalize(n[rows, j_sel] - np.sum(n[rows, j_sel] * axis, 1)[:, None] * axis)
    proj = lambda v: v - np.sum(v * axis, 1)[:, None] * axis  # noqa: E731
    c = _line_meet(proj(p1), n1, proj(p2), n2)
    r = 0.5 * (np.linalg.norm(proj(p1) - c, axis=1) + np.linalg.norm(proj(p2) - c, axis=1))
    rel = cloud[None, :, :] - c[:, None, :]
    z = np.einsum("hnj,hj->hn", rel, axis)
    rho = np.linalg.norm(rel - z[..., None] * axis[:, None, :], axis=2)
    lo, hi, ok = _masked_extremes(z, rho <= r[:, None] + 3.0 * noise)
    t = c + 0.5 * (lo + hi)[:, None] * axis
    R = frame_from_axes(_any_perp(axis), axis)
    valid = np.isfinite(best) & ok & (r > 0) & (hi > lo)
    return R, t, np.column_stack([r, hi - lo]), valid


def _box(p, n, cloud, noise):
    H = len(p)
    pairs = [(0, 1), (0, 2), (1, 2)]
    dots = np.stack([np.abs(np.sum(n[:, i] * n[:, j], axis=1)) for i, j in pairs], axis=1)
    pick = np.argmin(dots, axis=1)
    rows = np.arange(H)
    a1 = n[rows, np.array([pr[0] for pr in pairs])[pick]]
    a2 = n[rows, np.array([pr[1] for pr in pairs])[pick]]
    # no two faces in the sample (e.g. one face seen by a camera, or a thin plate's
    # two big faces): the other axes are the principal axes of the points projected
    # along the first normal (a rectangle's principal axes are along its sides)
    single = dots[rows, pick] >= np.cos(np.radians(45.0))
    if np.any(single):
        a = n[single, 0]
        P = np.eye(3) - a[:, :, None] * a[:, None, :]
        M = P @ np.cov(cloud.T) @ P
        a1[single], a2[single] = a, np.linalg.eigh(M)[1][:, :, 2]
    R = frame_from_axes(a2, a1)  # columns: a2 (orthogonalised), a1 x a2, a1
    local = np.einsum("nj,hji->hni", cloud, R)
    lo, hi = np.quantile(local, [_TRIM, 1.0 - _TRIM], axis=1)  # (H, 3) each
    t = np.einsum("hij,hj->hi", R, 0.5 * (lo + hi))
    valid = np.all(hi - lo > 0, axis=1)
    return R, t, hi - lo, valid


def _cone(p, n, cloud, noise):
    # outward normals of a surface of revolution with straight profile make the same
    # angle with the axis, so for three side points (n1 - n2) x (n1 - n3) is the axis.
    # The cone is convex: normals facing away from the cloud's centroid are outward.
    # Of the four triples of a 4-point sample, the one whose axis the remaining point
    # agrees with best (same angle: side; parallel: cap) is used.
    n = n * np.where(np.einsum("hkj,hkj->hk", n, p - cloud.mean(axis=0)) < 0, -1.0, 1.0)[..., None]
    H = len(p)
    best = np.full(H, np.inf)
    a = np.zeros((H, 3))
    trip = np.zeros((H, 3), int)
    for out in range(4):
        tri = [k for k in range(4) if k != out]
        cr = cross3(n[:, tri[1]] - n[:, tri[0]], n[:, tri[2]] - n[:, tri[0]])
        s = np.linalg.norm(cr, axis=1)
        ax = cr / np.maximum(s, 1e-12)[:, None]
        sin_a = np.mean(np.einsum("hkj,hj->hk", n[:, tri], ax), axis=1)
        c4 = np.sum(n[:, out] * ax, axis=1)
        dev = np.minimum(np.abs(np.abs(c4) - np.abs(sin_a)), 1.0 - np.abs(c4))
        score = np.where(s > 1e-2, dev, np.inf)
        better = score < best
        best = np.where(better, score, best)
        a[better] = ax[better]
        trip[better] = tri
    good = np.isfinite(best)
    rows = np.arange(H)[:, None]
    p, n = p[rows, trip], n[rows, trip]
    # axis position: the normal lines of a surface of revolution all cross its axis
    proj = lambda v: v - np.einsum("hkj,hj->hk", v, a)[..., None] * a[:, None, :]  # noqa: E731
    pp, nn = proj(p), normalize(proj(n))
    eye = np.eye(3)
    P = eye - nn[..., :, None] * nn[..., None, :] - a[:, None, :, None] * a[:, None, None, :]
    M = P.sum(axis=1) + 1e-9 * eye
    c = np.linalg.solve(M + a[:, :, None] * a[:, None, :], np.einsum("hkij,hkj->hi", P, pp)[..., None])[..., 0]
    # profile rho(z) = b0 + s z in the meridian plane; slope from the normals, whose
    # sign is fixed by making each point outward from the axis
    rel = p - c[:, None, :]
    z = np.einsum("hkj,hj->hk", rel, a)
    radial = rel - z[..., None] * a[:, None, :]
    rho = np.linalg.norm(radial, axis=2)
    n_r = np.einsum("hkj,hkj->hk", n, radial) / np.maximum(rho, 1e-12)
    n_a = np.einsum("hkj,hj->hk", n, a) * np.sign(n_r)
    slope = -np.mean(n_a / np.maximum(np.abs(n_r), 1e-3), axis=1)
    b0 = np.mean(rho - slope[:, None] * z, axis=1)
    relc = cloud[None, :, :] - c[:, None, :]
    zc = np.einsum("hnj,hj->hn", relc, a)
    rhoc = np.linalg.norm(relc - zc[..., None] * a[:, None, :], axis=2)
    prof = b0[:, None] + slope[:, None] * zc
    lo, hi, ok = _masked_extremes(zc, (prof > -3.0 * noise) & (rhoc <= prof + 3.0 * noise))
    r_lo = np.maximum(b0 + slope * lo, 0.0)
    r_hi = np.maximum(b0 + slope * hi, 0.0)
    t = c + 0.5 * (lo + hi)[:, None] * a
    R = frame_from_axes(_any_perp(a), a)  # z from the lo end (bottom) to the hi end
    valid = good & ok & (hi > lo) & (np.abs(slope) < 6.0) & (np.maximum(r_lo, r_hi) > 0)
    return R, t, np.column_stack([r_lo, r_hi, hi - lo]), valid


def _circle3(q1, q2, q3):
    """Circle through three points (..., 3): centre, radius, plane normal."""
    A, B = q1 - q3, q2 - q3
    axb = cross3(A, B)
    nn = np.sum(axb * axb, axis=-1)
    num = cross3(np.sum(A * A, -1)[..., None] * B - np.sum(B * B, -1)[..., None] * A, axb)
    c = q3 + num / (2.0 * np.maximum(nn, 1e-300))[..., None]
    return c, np.linalg.norm(q1 - c, axis=-1), normalize(axb), nn


def _half_toroid(p, n, cloud, noise):
    # Tube centres are q_i = p_i - r n_i (outward normals) and lie on the ring circle;
    # each normal lies in its meridian plane (normal to the circle's tangent there).
    # For every triple of the 4-point sample and every r on a grid, the circle through
    # the triple's q_i is scored on all four points by both conditions.
    size = float(np.linalg.norm(np.ptp(cloud, axis=0)))
    grid = np.geomspace(max(2.0 * noise, 1e-3), 0.3 * size, 40)  # candidate tube radii
    H = len(p)
    q = p[:, None, :, :] - grid[None, :, None, None] * n[:, None, :, :]  # (H, G, 4, 3)
    best = np.full(H, np.inf)
    c_b, R_b, a_b, r_b = np.zeros((H, 3)), np.zeros(H), np.zeros((H, 3)), np.zeros(H)
    rows = np.arange(H)
    for out in range(4):
        t0, t1, t2 = [k for k in range(4) if k != out]
        c, Rr, a, nn = _circle3(q[:, :, t0], q[:, :, t1], q[:, :, t2])  # (H, G, ...)
        rel = q - c[:, :, None, :]
        tang = normalize(cross3(a[:, :, None, :], rel))
        g = np.einsum("hgkj,hkj->hgk", tang, n)
        za = np.einsum("hgkj,hgj->hgk", rel, a)
        rho = np.linalg.norm(rel - za[..., None] * a[:, :, None, :], axis=3)
        off = np.hypot(rho - Rr[..., None], za) / grid[None, :, None]
        cost = np.sum(g**2, axis=2) + off[:, :, out] ** 2
        cost = np.where((nn > 1e-12) & (Rr > grid[None, :]) & (Rr < size), cost, np.inf)
        gi = np.argmin(cost, axis=1)
        cb = cost[rows, gi]
        better = cb < best
        best = np.where(better, cb, best)
        c_b[better], R_b[better], a_b[better] = c[rows, gi][better], Rr[rows, gi][better], a[rows, gi][better]
        r_b[better] = grid[gi][better]
    c, R_major, a, r = c_b, R_b, a_b, r_b
    rel = cloud[None, :, :] - c[:, None, :]
    z = np.einsum("hnj,hj->hn", rel, a)
    inplane = rel - z[..., None] * a[:, None, :]
    rho = np.linalg.norm(inplane, axis=2)
    near = np.abs(np.hypot(rho - R_major[:, None], z) - r[:, None]) < 3.0 * noise + 0.1 * r[:, None]
    u = inplane / np.maximum(rho, 1e-12)[..., None]
    d = normalize(np.einsum("hn,hnj->hj", near.astype(float), u))
    R = frame_from_axes(cross3(d, a), a)  # x = y cross z with y = d, z = a
    valid = np.isfinite(best) & (near.sum(1) >= 4) & (R_major > r)
    return R, c, np.column_stack([R_major, r]), valid


_SOLVERS = {"sphere": _sphere, "cylinder": _cylinder, "box": _box, "cone": _cone,
            "half_toroid": _half_toroid}
