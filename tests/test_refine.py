"""The refinement's residuals and Jacobian are the plain batched formulas to the bit
(its shortcuts -- cached residuals, the Jacobian's rotations made once -- change no
number the solver sees), its rotations are rotations, and its solver takes scipy's
soft-L1 trust-region steps (``least_squares(method="trf")``)."""

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import graspsim.perception.refine as refine_mod
from graspsim.perception.refine import refine_model, rodrigues, soft_l1_trf
from graspsim.primitives.sdf import DIM_NAMES, KINDS, model_sdf, sdf_function


def _rodrigues_reference(w):
    """The textbook batched formula, written out entry by entry."""
    th = np.linalg.norm(w, axis=1)
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0, np.sin(ths) / ths)[:, None, None]
    b = np.where(small, 0.5, (1.0 - np.cos(ths)) / ths**2)[:, None, None]
    return np.eye(3) + a * K + b * (K @ K)


def test_rodrigues_is_the_reference_formula_and_a_rotation():
    rng = np.random.default_rng(0)
    w = np.concatenate([rng.normal(0, 0.3, (200, 3)), rng.normal(0, 1e-8, (20, 3)), np.zeros((2, 3)),
                        -np.zeros((1, 3))])
    R = rodrigues(w)
    assert R.tobytes() == _rodrigues_reference(w).tobytes()
    np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), atol=1e-12)


def _problem(kind, seed=1):
    rng = np.random.default_rng(seed)
    dims = {"sphere": [0.03], "cylinder": [0.03, 0.1], "box": [0.04, 0.06, 0.1],
            "cone": [0.04, 0.02, 0.1], "half_toroid": [0.05, 0.01]}[kind]
    R0 = Rotation.from_rotvec(rng.normal(0, 0.5, 3)).as_matrix()
    t0 = rng.normal(0, 0.05, 3)
    pts = rng.normal(0, 0.06, (4000, 3)) + t0
    return R0, t0, np.array(dims, float), pts


@pytest.mark.parametrize("kind", KINDS)
def test_sdf_function_is_model_sdf_to_the_bit(kind):
    R0, t0, d0, pts = _problem(kind)
    rng = np.random.default_rng(2)
    R = Rotation.from_rotvec(rng.normal(0, 0.5, (7, 3))).as_matrix()
    t = t0 + rng.normal(0, 0.01, (7, 3))
    dims = d0 * rng.uniform(0.8, 1.2, (7, len(d0)))
    pytest.importorskip("numba")  # loaded: the compiled path, as in planning
    f = sdf_function(kind, pts)
    assert f(R, t, dims).tobytes() == model_sdf(kind, R, t, dims, pts).tobytes()
    R32 = R.astype(np.float32)  # not the kernel's input: numpy's path, as model_sdf's
    assert f(R32, t, dims).tobytes() == model_sdf(kind, R32, t, dims, pts).tobytes()


@pytest.mark.parametrize("kind", ["cylinder", "cone", "half_toroid"])
def test_solver_sees_the_plain_batched_residuals_and_jacobian(kind, monkeypatch):
    R0, t0, d0, pts = _problem(kind)
    sigma, eps = 0.002, 1e-7
    res = model_sdf(kind, R0[None], t0[None], d0[None], pts)[0]
    inliers = np.abs(res) < 0.02  # a fixed set of points to refine on
    sel = np.flatnonzero(inliers)
    assert len(sel) > 150  # subsampled by the refinement's stride
    sel = sel[np.linspace(0, len(sel) - 1, 150).astype(int)]
    p = pts[sel]
    scale = max(float(np.max(d0)), 10.0 * sigma)

    def reference(x):  # the plain formulas: every row unpacked and evaluated together
        X = np.vstack([x, x + eps * np.eye(len(x))])
        R = np.einsum("ij,hjk->hik", R0, _rodrigues_reference(X[:, :3]))
        F = model_sdf(kind, R, t0 + X[:, 3:6] * scale, np.abs(X[:, 6:]) * scale, p) / sigma
        return F[0], ((F[1:] - F[0]) / eps).T

    seen = []

    def checked(fun, jac, x0, **kw):
        def f(x):
            out = fun(x)
            seen.append(out.tobytes() == reference(x)[0].tobytes())
            return out

        def j(x):
            out = jac(x)
            seen.append(out.tobytes() == reference(x)[1].tobytes())
            return out
        return soft_l1_trf(f, j, x0, **kw)

    monkeypatch.setattr(refine_mod, "soft_l1_trf", checked)
    out = refine_model(kind, R0, t0, d0, pts, inliers, sigma, 150)
    assert out is not None and len(seen) > 4 and all(seen)
    assert [a.shape for a in out] == [(1, 3, 3), (1, 3), (1, len(DIM_NAMES[kind]))]


def test_too_few_inliers_are_not_refined():
    R0, t0, d0, pts = _problem("cylinder")
    inliers = np.zeros(len(pts), bool)
    inliers[:10] = True
    assert refine_model("cylinder", R0, t0, d0, pts, inliers, 0.002, 150) is None


def _curve(seed, outliers=0.2):
    """A smooth nonlinear least-squares problem (m residuals, n unknowns) with a share
    of gross outliers, its Jacobian and a start."""
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(40, 200)), int(rng.integers(2, 9))
    A = rng.normal(size=(m, n))
    x_true = rng.normal(0, 0.3, n)
    b = np.tanh(A @ x_true) * 3 + 0.1 * (A @ x_true) ** 2
    bad = rng.random(m) < outliers
    b[bad] += rng.choice([-1, 1], bad.sum()) * rng.uniform(5, 20, bad.sum())

    def fun(x):
        return np.tanh(A @ x) * 3 + 0.1 * (A @ x) ** 2 - b

    def jac(x):
        u = A @ x
        return (3 * (1 - np.tanh(u) ** 2) + 0.2 * u)[:, None] * A
    return fun, jac, x_true + rng.normal(0, 0.2, n), x_true, bad


@pytest.mark.parametrize("seed", range(12))
def test_solver_follows_scipy_trust_region_reflective(seed):
    """Where both run to convergence, the solver lands where scipy's does (the same
    method; to the bit with the scipy it was written against, 1.17), and it stays
    inside the evaluation budget."""
    fun, jac, x0, _, _ = _curve(seed)
    kw = {"f_scale": 2.0, "ftol": 1e-10, "xtol": 1e-10}
    ref = least_squares(fun, x0, jac=jac, loss="soft_l1", method="trf", max_nfev=200, **kw)
    calls = []
    x = soft_l1_trf(lambda v: calls.append(1) or fun(v), jac, x0, max_nfev=200, **kw)
    assert len(calls) <= 200
    np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-7)
    # within a small budget, as the refinement runs it (12 evaluations, tolerances 1e-3): the
    # same iterates, step for step; from the start and from near 0 (a small first trust
    # region, which must grow)
    near0 = np.full_like(x0, 0.01)
    for start, budget in [(x0, 3), (x0, 7), (x0, 12), (near0, 7), (near0, 12)]:
        lim = {"f_scale": 2.0, "ftol": 1e-3, "xtol": 1e-3, "max_nfev": budget}
        ref = least_squares(fun, start, jac=jac, loss="soft_l1", method="trf", **lim)
        capped = []

        def counted(v, capped=capped):
            capped.append(1)
            return fun(v)
        x = soft_l1_trf(counted, jac, start, **lim)
        assert len(capped) == ref.nfev <= budget
        np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-12)


def test_solver_resists_outliers_and_refuses_bad_starts():
    fun, jac, x0, x_true, bad = _curve(3, outliers=0.25)
    assert bad.sum() > 5
    x = soft_l1_trf(fun, jac, x0, f_scale=0.5, ftol=1e-12, xtol=1e-12, max_nfev=500)
    assert np.abs(x - x_true).max() < 0.05  # the outliers barely pull the robust fit
    with pytest.raises(ValueError):
        soft_l1_trf(lambda v: np.full(10, np.nan), lambda v: np.ones((10, 2)), np.zeros(2), f_scale=1.0,
                    ftol=1e-3, xtol=1e-3, max_nfev=5)
    with pytest.raises(ValueError):  # a Jacobian it cannot factor
        soft_l1_trf(lambda v: np.ones(10) + v.sum(), lambda v: np.full((10, 2), np.nan), np.zeros(2),
                    f_scale=1.0, ftol=1e-3, xtol=1e-3, max_nfev=5)
