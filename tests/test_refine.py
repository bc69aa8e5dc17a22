"""The refinement's residuals and Jacobian are the plain batched formulas to the bit
(its shortcuts -- cached residuals, the Jacobian's rotations made once -- change no
number the solver sees), and its rotations are rotations."""

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import graspsim.perception.refine as refine_mod
from graspsim.perception.refine import refine_model, rodrigues
from graspsim.perception.shapes import DIM_NAMES, KINDS, model_sdf, sdf_function


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

    def checked(fun, x0, jac, **kw):
        def f(x):
            out = fun(x)
            seen.append(out.tobytes() == reference(x)[0].tobytes())
            return out

        def j(x):
            out = jac(x)
            seen.append(out.tobytes() == reference(x)[1].tobytes())
            return out
        return least_squares(f, x0, jac=j, **kw)

    monkeypatch.setattr(refine_mod, "least_squares", checked)
    out = refine_model(kind, R0, t0, d0, pts, inliers, sigma, 150)
    assert out is not None and len(seen) > 4 and all(seen)
    assert [a.shape for a in out] == [(1, 3, 3), (1, 3), (1, len(DIM_NAMES[kind]))]


def test_too_few_inliers_are_not_refined():
    R0, t0, d0, pts = _problem("cylinder")
    inliers = np.zeros(len(pts), bool)
    inliers[:10] = True
    assert refine_model("cylinder", R0, t0, d0, pts, inliers, 0.002, 150) is None
