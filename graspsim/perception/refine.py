"""Refinement of one model hypothesis: soft-L1 least squares of the signed distances
of (a stride subsample of) its inliers over pose and dims.

The unknowns are a rotation vector w (a turn of the hypothesis' own frame), a shift of
its position and the dims, each scaled by the model's size. The Jacobian is forward
differences, one batched SDF call over all perturbations. The solver calls the
residuals and the Jacobian thousands of times per cloud on a few hundred points, so
their Python overhead is kept small: the perturbation steps, the distance function and
the rotation of the unperturbed unknowns are made once, the three turns are the only
rotations the Jacobian makes, and the residuals at the point the Jacobian is taken at
(the solver has just evaluated them there) are reused. Every value is computed with the
same operations as one batched evaluation of all rows would (each row is computed
independently of the others), so the solver sees the same numbers to the bit.

The solver (:func:`soft_l1_trf`) is the trust-region method of scipy's
``least_squares(method="trf", loss="soft_l1")`` for a problem without bounds, taken
step for step with the same arithmetic, less scipy's general-purpose wrapping (its
argument checks, memoised function object and result object cost more than the
residuals of a few hundred points), and without the Jacobian scipy evaluates after the
last step, whose result it does not use. It follows scipy's ``trf_no_bounds`` and
``solve_lsq_trust_region`` (scipy.optimize._lsq, BSD-3-Clause; Branch, Coleman & Li 1999
and Moré 1978 for the methods), so that identification gives the numbers it gave with
scipy's solver; ``tests/test_refine.py`` holds it to scipy's iterates.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import LinAlgError, get_lapack_funcs

from graspsim.primitives.sdf import sdf_function

__all__ = ["refine_model", "rodrigues", "soft_l1_trf"]

_EPS = 1e-7  # the forward-difference step
_EYE3 = np.eye(3)
# the cross-product matrix K of w, row-major, as entries of (w0, w1, w2, 0) and signs
_K_INDEX = np.array([3, 2, 1, 2, 3, 0, 1, 0, 3])
_K_SIGN = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])


def rodrigues(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (H, 3, 3) of rotation vectors w (H, 3) [rad]."""
    th = np.sqrt(np.add.reduce(w * w, axis=1))
    K = (np.concatenate([w, np.zeros((len(w), 1))], axis=1)[:, _K_INDEX] * _K_SIGN).reshape(-1, 3, 3)
    small = th < 1e-6
    if small.any():  # the series' limits there (np.where: the other values as they are)
        ths = np.where(small, 1.0, th)
        a = np.where(small, 1.0, np.sin(ths) / ths)
        b = np.where(small, 0.5, (1.0 - np.cos(ths)) / ths**2)
    else:
        a, b = np.sin(th) / th, (1.0 - np.cos(th)) / th**2
    return _EYE3 + a[:, None, None] * K + b[:, None, None] * (K @ K)


def refine_model(kind: str, R0: np.ndarray, t0: np.ndarray, d0: np.ndarray, points: np.ndarray,
                 inliers: np.ndarray, sigma: float, max_points: int, max_nfev: int = 12):
    """The refined model of hypothesis (R0 (3, 3), t0 (3,), dims d0 (k,)) on its
    ``inliers`` (N,) bool of ``points`` (N, 3) [m] (at most ``max_points`` of them, a
    stride subsample) with noise ``sigma`` [m]: batched (R, t, dims) with H = 1, or
    None (too few inliers; the solver failed or left the finite numbers)."""
    sel = np.flatnonzero(inliers)
    if len(sel) < 2 * (6 + len(d0)):
        return None
    if len(sel) > max_points:
        sel = sel[np.linspace(0, len(sel) - 1, max_points).astype(int)]
    p = points[sel]
    scale = max(float(np.max(d0)), 10.0 * sigma)
    sdf = sdf_function(kind, p)
    steps = _EPS * np.eye(6 + len(d0))
    turns = np.r_[0, 1, 2, np.full(len(steps) - 3, 3)]  # the rotation of each perturbed row
    last = [None, None]  # the unknowns the residuals were last evaluated at, and those

    def unpack(X):  # X (H, 6 + k)
        R = np.einsum("ij,hjk->hik", R0, rodrigues(X[:, :3]))
        return R, t0 + X[:, 3:6] * scale, np.abs(X[:, 6:]) * scale

    def fun(x):
        f = sdf(*unpack(x[None]))[0] / sigma
        last[:] = x.tobytes(), f.copy()  # the solver scales its residuals in place
        return f

    def jac(x):
        f0 = last[1] if last[0] == x.tobytes() else fun(x)
        X = x + steps
        R = np.einsum("ij,hjk->hik", R0, rodrigues(X[:4, :3]))[turns]  # rows 3..: x + 0, unturned
        F = sdf(R, t0 + X[:, 3:6] * scale, np.abs(X[:, 6:]) * scale) / sigma
        return ((F - f0) / _EPS).T

    x0 = np.concatenate([np.zeros(6), d0 / scale])
    try:
        x = soft_l1_trf(fun, jac, x0, f_scale=2.0, ftol=1e-3, xtol=1e-3, max_nfev=max_nfev)
    except (ValueError, LinAlgError):
        return None
    if not np.all(np.isfinite(x)):
        return None
    return unpack(x[None])


_EPS_F = np.finfo(float).eps
_GTOL = 1e-8  # scipy's default gradient tolerance
_lapack: dict[tuple[int, int], tuple] = {}  # (m, n) -> (gesdd, its optimal lwork)


def _svd(A: np.ndarray):
    """U, s, V^T of A (m, n), m >= n, thin: LAPACK's gesdd with its optimal work size,
    as ``scipy.linalg.svd(A, full_matrices=False)`` calls it (the same numbers)."""
    if not np.isfinite(A).all():
        raise ValueError("array must not contain infs or NaNs")
    key = A.shape
    if key not in _lapack:
        gesdd, gesdd_lwork = get_lapack_funcs(("gesdd", "gesdd_lwork"), (A,), ilp64="preferred")
        work, info = gesdd_lwork(A.shape[0], A.shape[1], compute_uv=1, full_matrices=0)
        if info != 0:
            raise ValueError(f"gesdd work size query failed: {info}")
        _lapack[key] = gesdd, int(work.real)
    gesdd, lwork = _lapack[key]
    u, s, vt, info = gesdd(A, compute_uv=1, lwork=lwork, full_matrices=0, overwrite_a=0)
    if info > 0:
        raise LinAlgError("SVD did not converge")
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of gesdd")
    return u, s, vt


def _norm(v: np.ndarray) -> float:
    return math.sqrt(v.dot(v))  # numpy.linalg.norm's arithmetic for a real vector


def _soft_l1(f: np.ndarray, f_scale: float, rho: np.ndarray, cost_only: bool = False):
    """The soft-L1 loss of residuals f scaled by f_scale: its cost, or rho (3, m) (the
    loss and its first two derivatives in f**2, scaled back)."""
    t = 1 + (f / f_scale) ** 2
    rho[0] = 2 * (t**0.5 - 1)
    if cost_only:
        return 0.5 * f_scale**2 * np.sum(rho[0])
    rho[1] = t**-0.5
    rho[2] = -0.5 * t**-1.5
    rho[0] *= f_scale**2
    rho[2] /= f_scale**2
    return rho


def _robust_scaled(J: np.ndarray, f: np.ndarray, rho: np.ndarray) -> None:
    """J and f scaled in place so that the loss is least squares to second order."""
    s = rho[1] + 2 * rho[2] * f**2
    s[s < _EPS_F] = _EPS_F
    s **= 0.5
    f *= rho[1] / s
    J *= s[:, np.newaxis]


def _trust_region_step(n: int, m: int, uf: np.ndarray, s: np.ndarray, V: np.ndarray, Delta: float,
                       alpha: float, rtol: float = 0.01, max_iter: int = 10) -> tuple[np.ndarray, float]:
    """The step p minimising |J p + f| within |p| <= Delta (J = U diag(s) V^T, uf =
    U^T f) and its Levenberg-Marquardt parameter: the Gauss-Newton step where J has
    full rank and it fits, else Moré's (1978) iteration on alpha from ``alpha``."""
    suf = s * uf

    def phi_and_derivative(a):
        denom = s**2 + a
        p_norm = _norm(suf / denom)
        return p_norm - Delta, -np.sum(suf**2 / denom**3) / p_norm

    full_rank = m >= n and s[-1] > _EPS_F * m * s[0]
    if full_rank:
        p = -V.dot(uf / s)
        if _norm(p) <= Delta:
            return p, 0.0
    alpha_upper = _norm(suf) / Delta
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if not full_rank and alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
    for _ in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
        phi, phi_prime = phi_and_derivative(alpha)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + Delta) * ratio / Delta
        if np.abs(phi) < rtol * Delta:
            break
    p = -V.dot(suf / (s**2 + alpha))
    p *= Delta / _norm(p)
    return p, alpha


def soft_l1_trf(fun, jac, x0: np.ndarray, *, f_scale: float, ftol: float, xtol: float, max_nfev: int
                ) -> np.ndarray:
    """The unknowns minimising the soft-L1 cost of residuals ``fun(x)`` (m,) with
    Jacobian ``jac(x)`` (m, n), from ``x0``: the trust-region reflective method without
    bounds, with the exact trust-region solver and unit variable scale, as
    ``scipy.optimize.least_squares(fun, x0, jac=jac, method="trf", loss="soft_l1",
    f_scale=f_scale, ftol=ftol, xtol=xtol, max_nfev=max_nfev)`` takes it (its ``x``).
    ``fun`` returns a new array each call (it is scaled in place). Raises ValueError
    when the residuals at x0, or a Jacobian it factors, are not finite."""
    x = np.array(x0, float)
    f = fun(x)
    if not np.all(np.isfinite(f)):
        raise ValueError("Residuals are not finite in the initial point.")
    J = jac(x)
    m, n = J.shape
    rho = np.empty((3, m))
    nfev = 1
    _soft_l1(f, f_scale, rho)
    cost = 0.5 * np.sum(rho[0])
    _robust_scaled(J, f, rho)
    g = J.T.dot(f)
    Delta = _norm(x)
    if Delta == 0:
        Delta = 1.0
    alpha = 0.0
    while not np.max(np.abs(g)) < _GTOL and nfev < max_nfev:  # NaN goes on (the SVD refuses it)
        U, s, Vt = _svd(J)
        V = Vt.T
        uf = U.T.dot(f)
        reduction, done = -1, False
        while reduction <= 0 and nfev < max_nfev:
            step, alpha = _trust_region_step(n, m, uf, s, V, Delta, alpha)
            Js = J.dot(step)
            predicted = -(0.5 * np.dot(Js, Js) + np.dot(step, g))
            x_new = x + step
            f_new = fun(x_new)
            nfev += 1
            step_norm = _norm(step)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_norm
                continue
            cost_new = _soft_l1(f_new, f_scale, rho, cost_only=True)
            reduction = cost - cost_new
            if predicted > 0:
                ratio = reduction / predicted
            elif predicted == reduction == 0:
                ratio = 1
            else:
                ratio = 0
            if ratio < 0.25:
                Delta_new = 0.25 * step_norm
            elif ratio > 0.75 and step_norm > 0.95 * Delta:
                Delta_new = 2.0 * Delta
            else:
                Delta_new = Delta
            # scipy's termination test: the cost barely falls on a good step, or the step is small
            done = ((reduction < ftol * cost and ratio > 0.25)
                    or step_norm < xtol * (xtol + _norm(x)))
            if done:
                break
            alpha *= Delta / Delta_new
            Delta = Delta_new
        if reduction <= 0 or done:
            return x_new if reduction > 0 else x
        x, f, cost = x_new, f_new, cost_new
        if nfev == max_nfev:
            return x  # scipy evaluates the Jacobian here, and stops
        J = jac(x)
        _soft_l1(f, f_scale, rho)
        _robust_scaled(J, f, rho)
        g = J.T.dot(f)
    return x
