"""MLESAC (Torr & Zisserman 2000): maximum-likelihood sample consensus.

Residuals e of a hypothesis are modelled as a mixture of Gaussian inliers and uniform
outliers::

    p(e) = gamma * N(e; 0, sigma^2) + (1 - gamma) / nu

with the mixing weight gamma estimated per hypothesis by EM and the hypothesis scored
by its log-likelihood. All hypotheses of a model are scored at once ((H, N) arrays).
The best one is then refined by robust least squares (scipy, soft-L1) on its inliers;
the refined model replaces it only if its likelihood is higher.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.perception.hypotheses import SAMPLE_SIZE, hypothesise, plausible
from graspsim.perception.refine import refine_model
from graspsim.perception.support import extent_ratio
from graspsim.primitives.sdf import KINDS, model_sdf

__all__ = ["ModelFit", "mixture_loglik", "fit_model", "fit_from", "rescore", "residual_sigma"]

_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


@dataclass(frozen=True)
class ModelFit:
    """Best fit of one model kind to a cloud.

    R (3, 3), t (3,): ``T_world_fit`` (see :mod:`shapes`); dims (k,) [m];
    loglik: mixture log-likelihood of all points; gamma: inlier mixing weight;
    fit_rate: fraction of points whose inlier posterior exceeds 1/2 (paper eq. 2);
    rms: RMS residual of those inliers [m]; inliers: (N,) bool;
    n_hypotheses / n_valid: samples drawn / non-degenerate; refined: LSQ kept.
    """

    kind: str
    R: np.ndarray
    t: np.ndarray
    dims: np.ndarray
    loglik: float
    gamma: float
    fit_rate: float
    rms: float
    inliers: np.ndarray
    n_hypotheses: int
    n_valid: int
    refined: bool


#: Values per (hypotheses x points) array that :func:`fit_model` works on at once (its
#: memory bound, about 16 MiB each): hypotheses are made and scored in blocks this size.
SCORE_BLOCK = 1 << 21


def mixture_loglik(residuals: np.ndarray, sigma: float, nu: float, *, em_iters: int = 5):
    """Log-likelihood (H,), mixing weight gamma (H,) and inlier posteriors (H, N) of
    residuals (H, N) [m] under the Gaussian/uniform mixture; gamma by EM from 1/2."""
    e2 = (np.asarray(residuals, float) / sigma) ** 2
    log_g = -0.5 * e2 - _LOG_SQRT_2PI - np.log(sigma)
    g = np.exp(log_g)
    u = 1.0 / nu
    gamma = np.full(e2.shape[0], 0.5)
    pin, post = np.empty_like(g), np.empty_like(g)  # the EM's (H, N) buffers
    for _ in range(em_iters):  # the mean and clip as numpy's, without their wrappers
        np.multiply(gamma[:, None], g, out=pin)
        np.divide(pin, np.add(pin, (1.0 - gamma[:, None]) * u, out=post), out=post)
        gamma = np.minimum(np.maximum(np.add.reduce(post, axis=1) / e2.shape[1], 1e-6), 1.0 - 1e-6)
    pin = gamma[:, None] * g
    total = pin + (1.0 - gamma[:, None]) * u
    return np.add.reduce(np.log(total), axis=1), gamma, pin / total


def fit_model(
    kind: str,
    points: np.ndarray,
    normals: np.ndarray,
    rng: np.random.Generator,
    *,
    repetitions: int,
    sigma: float,
    candidates: np.ndarray | None = None,
    refine: bool = True,
    max_refine_points: int = 150,
    max_extent_ratio: float | None = None,
) -> ModelFit | None:
    """MLESAC fit of one model ``kind`` to points (N, 3) with unit normals (N, 3).

    repetitions: minimal samples drawn (one hypothesis each); sigma: inlier noise [m];
    candidates: indices of the points samples are drawn from (default all; e.g. the
    points with the most reliable normals). Scoring always uses all points.
    max_extent_ratio: if given, hypotheses that extend along an axis more than this
    many times as far as the cluster (see :func:`~graspsim.perception.support.extent_ratio`)
    are not valid.
    Returns None when no sample gave a valid hypothesis.
    """
    if kind not in KINDS:
        raise InvalidParameterError(f"unknown model kind {kind!r}; valid: {KINDS}")
    if repetitions < 1:
        raise InvalidParameterError(f"repetitions must be >= 1, got {repetitions!r}")
    n = len(points)
    nu = float(np.linalg.norm(np.ptp(points, axis=0))) + 10.0 * sigma
    pool = np.arange(n) if candidates is None else np.asarray(candidates)
    if len(pool) < SAMPLE_SIZE[kind]:
        pool = np.arange(n)
    idx = pool[rng.integers(0, len(pool), size=(repetitions, SAMPLE_SIZE[kind]))]
    R, t, dims, valid = _hypotheses(kind, points, normals, idx, sigma, max_extent_ratio)
    if not np.any(valid):
        return None
    best = _best(kind, points, R[valid], t[valid], dims[valid], sigma, nu)
    if kind == "half_toroid":
        best = _best_spin(points, best, sigma, nu)
    return _finish(kind, points, best, sigma, nu, refine, max_refine_points, repetitions,
                   int(valid.sum()), max_extent_ratio)


def _blocks(h: int, n: int):
    """Slices of ``h`` hypotheses whose (hypotheses x ``n`` points) arrays hold at most
    :data:`SCORE_BLOCK` values: identification's memory does not grow with repetitions."""
    step = max(1, SCORE_BLOCK // max(n, 1))
    return (slice(s, s + step) for s in range(0, h, step))


def _hypotheses(kind, points, normals, idx, sigma, max_extent_ratio):
    """Hypotheses (R, t, dims, valid) from samples ``idx`` (H, m), block by block."""
    out = []
    for sl in _blocks(len(idx), len(points)):
        R, t, dims, valid = hypothesise(kind, points, normals, idx[sl], sigma)
        valid &= np.all(np.isfinite(dims), axis=1) & np.all(dims >= 0, axis=1)
        valid &= np.all(np.isfinite(t), axis=1) & np.all(np.isfinite(R), axis=(1, 2))
        if max_extent_ratio is not None and np.any(valid):
            valid[valid] = extent_ratio(kind, R[valid], t[valid], dims[valid], points, sigma) <= max_extent_ratio
        out.append((R, t, dims, valid))
    return tuple(np.concatenate(parts) for parts in zip(*out))


def _best(kind, points, R, t, dims, sigma, nu):
    """The most likely hypothesis (R, t, dims, loglik, gamma, posteriors), scored block
    by block (the first best, as one argmax over all of them would pick)."""
    best = None
    for sl in _blocks(len(R), len(points)):
        ll, gamma, post = mixture_loglik(np.nan_to_num(model_sdf(kind, R[sl], t[sl], dims[sl], points), nan=nu),
                                         sigma, nu)
        b = int(np.argmax(ll))
        if best is None or ll[b] > best[3]:
            best = (R[sl][b], t[sl][b], dims[sl][b], ll[b], gamma[b], post[b])
    return best


def _best_spin(points, best, sigma, nu, steps: int = 36, max_points: int = 256):
    """A half-toroid's ring and tube are well fixed by a hypothesis, but where the half
    starts about its axis is not (it is aimed at the mean direction of the points near
    the ring, which one view biases): the most likely of ``steps`` turns about the axis,
    scored on a stride subsample of ``max_points`` (the refinement that follows polishes
    the angle), kept if it beats the hypothesis on all points."""
    R0, t0, d0 = best[:3]
    a = 2 * np.pi * np.arange(steps) / steps
    c, s = np.cos(a), np.sin(a)
    Rz = np.zeros((steps, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    Rs = np.einsum("ij,hjk->hik", R0, Rz)
    sub = points[np.linspace(0, len(points) - 1, min(len(points), max_points)).astype(int)]
    ll = mixture_loglik(model_sdf("half_toroid", Rs, np.repeat(t0[None], steps, 0),
                                  np.repeat(d0[None], steps, 0), sub), sigma, nu)[0]
    R1 = Rs[int(np.argmax(ll))]
    ll1, gamma1, post1 = mixture_loglik(model_sdf("half_toroid", R1[None], t0[None], d0[None], points), sigma, nu)
    return (R1, t0, d0, ll1[0], gamma1[0], post1[0]) if ll1[0] > best[3] else best


def fit_from(kind: str, points: np.ndarray, R: np.ndarray, t: np.ndarray, dims: np.ndarray, *,
             sigma: float, refine: bool = True, max_refine_points: int = 150,
             max_extent_ratio: float | None = None) -> ModelFit:
    """Score (and refine) one given hypothesis ``(R (3, 3), t (3,), dims (k,))`` of model
    ``kind`` on points (N, 3), e.g. a cylinder seeded from a cone's axis and radii."""
    if kind not in KINDS:
        raise InvalidParameterError(f"unknown model kind {kind!r}; valid: {KINDS}")
    nu = float(np.linalg.norm(np.ptp(points, axis=0))) + 10.0 * sigma
    R, t, dims = np.asarray(R, float), np.asarray(t, float), np.asarray(dims, float)
    ll, gamma, post = mixture_loglik(model_sdf(kind, R[None], t[None], dims[None], points), sigma, nu)
    return _finish(kind, points, (R, t, dims, ll[0], gamma[0], post[0]), sigma, nu, refine,
                   max_refine_points, 1, 1, max_extent_ratio)


def _finish(kind, points, best, sigma, nu, refine, max_refine_points, n_hyp, n_valid,
            max_extent_ratio=None) -> ModelFit:
    """Refine the best hypothesis (kept if more likely) and summarise it."""
    refined = False
    if refine:
        cand = refine_model(kind, best[0], best[1], best[2], points, best[5] > 0.5, sigma,
                             max_refine_points)
        if cand is not None:  # the refinement may have moved an unseen end anywhere
            trim = _trim_to_support(kind, cand[0][0], cand[1][0], cand[2][0], points[best[5] > 0.5], sigma)
            if trim is not None:
                cand = (cand[0], trim[0][None], trim[1][None])
        if cand is not None and plausible(kind, cand[2], nu - 10.0 * sigma)[0] and (
                max_extent_ratio is None
                or extent_ratio(kind, *cand, points, sigma)[0] <= max_extent_ratio):
            res = model_sdf(kind, *cand, points)
            r_ll, r_gamma, r_post = mixture_loglik(res, sigma, nu)
            if r_ll[0] > best[3]:
                best = (cand[0][0], cand[1][0], cand[2][0], r_ll[0], r_gamma[0], r_post[0], res[0])
                refined = True
    Rb, tb, db, llb, gb, pb = best[:6]
    res = best[6] if len(best) > 6 else None  # the residuals of the model, where made already
    trimmed = _trim_to_support(kind, Rb, tb, db, points[pb > 0.5], sigma)
    if trimmed is not None:
        res = model_sdf(kind, Rb[None], trimmed[0][None], trimmed[1][None], points)
        ll, gamma, post = mixture_loglik(res, sigma, nu)
        tb, db, llb, gb, pb, res = trimmed[0], trimmed[1], ll[0], gamma[0], post[0], res[0]
    inl = pb > 0.5
    if res is None:
        res = model_sdf(kind, Rb[None], tb[None], db[None], points)[0]
    rms = float(np.sqrt(np.mean(res[inl] ** 2))) if inl.any() else float("inf")
    return ModelFit(kind, Rb, tb, db, float(llb), float(gb), float(inl.mean()), rms, inl,
                    n_hyp, n_valid, refined)


def _trim_to_support(kind, R, t, dims, inliers, sigma):
    """A box, cylinder or cone cut back to the extent of its inliers (0.5-99.5 %
    quantiles) along its axis (cylinder, cone) or each of its edges (box) where it
    reaches more than 2 sigma beyond it, as (t, dims); else None. Nothing in the
    likelihood holds the end of a side nobody saw (the bottom of an object on a table,
    the far end of a box seen along its length): hypotheses and refinement may leave it
    anywhere beyond (a 153 mm box hypothesis refined to 376 mm on 156 mm of points)."""
    if len(inliers) < 10:
        return None
    if kind == "box":
        return _trim_box(R, t, dims, inliers, sigma)
    if kind not in ("cylinder", "cone"):
        return None
    a = R[:, 2]
    z = (inliers - t) @ a
    lo, hi = np.quantile(z, [0.005, 0.995])
    h = dims[-1]
    lo, hi = max(lo, -0.5 * h), min(hi, 0.5 * h)
    if lo - (-0.5 * h) <= 2.0 * sigma and 0.5 * h - hi <= 2.0 * sigma or hi - lo <= 0:
        return None
    t2 = t + 0.5 * (lo + hi) * a
    if kind == "cylinder":
        return t2, np.array([dims[0], hi - lo])
    r0, r1 = dims[0], dims[1]
    rad = lambda zz: r0 + (r1 - r0) * (zz + 0.5 * h) / h  # noqa: E731
    return t2, np.array([max(rad(lo), 0.0), max(rad(hi), 0.0), hi - lo])


def _trim_box(R, t, dims, inliers, sigma):
    """:func:`_trim_to_support` for a box: each face that lies more than 2 sigma beyond
    its inliers' extent along its edge moves in to that extent; the other faces stay."""
    t2, d2, changed = np.array(t, float), np.array(dims, float), False
    for i in range(3):
        z = (inliers - t) @ R[:, i]
        lo, hi = np.quantile(z, [0.005, 0.995])
        h = dims[i]
        lo = lo if lo + 0.5 * h > 2.0 * sigma else -0.5 * h
        hi = hi if 0.5 * h - hi > 2.0 * sigma else 0.5 * h
        if (lo > -0.5 * h or hi < 0.5 * h) and hi > lo:
            t2, d2[i], changed = t2 + 0.5 * (lo + hi) * R[:, i], hi - lo, True
    return (t2, d2) if changed else None


def residual_sigma(fit: ModelFit, points: np.ndarray) -> float:
    """Robust standard deviation (1.4826 MAD) of a fit's inlier residuals [m]."""
    res = model_sdf(fit.kind, fit.R[None], fit.t[None], fit.dims[None], points)[0][fit.inliers]
    return float(1.4826 * np.median(np.abs(res))) if len(res) else float("nan")


def rescore(fit: ModelFit, points: np.ndarray, sigma: float) -> ModelFit:
    """The same model scored with another noise sigma [m] (fit rate, gamma, inliers)."""
    nu = float(np.linalg.norm(np.ptp(points, axis=0))) + 10.0 * sigma
    res = model_sdf(fit.kind, fit.R[None], fit.t[None], fit.dims[None], points)
    ll, gamma, post = mixture_loglik(res, sigma, nu)
    inl = post[0] > 0.5
    rms = float(np.sqrt(np.mean(res[0][inl] ** 2))) if inl.any() else float("inf")
    return replace(fit, loglik=float(ll[0]), gamma=float(gamma[0]), fit_rate=float(inl.mean()),
                   rms=rms, inliers=inl)
