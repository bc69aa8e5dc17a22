"""Refinement of one model hypothesis: soft-L1 least squares (scipy) of the signed
distances of (a stride subsample of) its inliers over pose and dims.

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
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from graspsim.perception.shapes import sdf_function

__all__ = ["refine_model", "rodrigues"]

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
        sol = least_squares(fun, x0, jac=jac, loss="soft_l1", f_scale=2.0, max_nfev=max_nfev,
                            ftol=1e-3, xtol=1e-3, method="trf")
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(sol.x)):
        return None
    return unpack(sol.x[None])
