"""Primitive models as the fitters see them: batched signed distances in a *fit frame*.

A model hypothesis is a pose ``(R, t)`` = ``T_world_fit`` and a dims vector in the
primitive's ``dim_names`` order. The fit frame is the primitive's object frame up to a
shift along its axis, chosen so the formulas are simple and the fit well conditioned:

* box, cylinder, sphere: centred (= object frame);
* cone: on the axis at mid-height, z from the bottom face towards the top face;
* half-toroid: the ring centre (the geometric frame), symmetry axis z, kept half +y.

Every function here is vectorised over H hypotheses and N points: distances are
(H, N) arrays for points (N, 3) and poses (H, 3, 3), (H, 3), dims (H, k).
"""

from __future__ import annotations

import sys

import numpy as np

from graspsim.primitives import make_primitive
from graspsim.transforms import make_transform

__all__ = ["KINDS", "DIM_NAMES", "to_local", "sdf_local", "model_sdf", "sdf_function", "model_extents",
           "fit_to_object"]

#: Model kinds in the order of their simplicity (ties go to the earlier one).
KINDS: tuple[str, ...] = ("sphere", "cylinder", "box", "cone", "half_toroid")
DIM_NAMES: dict[str, tuple[str, ...]] = {
    "sphere": ("radius",),
    "cylinder": ("radius", "height"),
    "box": ("x", "y", "z"),
    "cone": ("bottom_radius", "top_radius", "height"),
    "half_toroid": ("major_radius", "minor_radius"),
}


def to_local(R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """World points (N, 3) into H fit frames: (H, N, 3) = (p - t_h) R_h.

    Written as three broadcast products: a BLAS matmul with an inner dimension of 3
    is slower, and much slower when OpenBLAS threads compete for busy cores."""
    d = points[None, :, :] - t[:, None, :]
    return (d[..., 0, None] * R[:, None, 0, :] + d[..., 1, None] * R[:, None, 1, :]
            + d[..., 2, None] * R[:, None, 2, :])


def sdf_local(kind: str, q: np.ndarray, dims: np.ndarray) -> np.ndarray:
    """Signed distance (H, N) [m] of fit-frame points q (H, N, 3) to models dims (H, k)."""
    d = [dims[:, i, None] for i in range(dims.shape[1])]
    x, y, z = q[..., 0], q[..., 1], q[..., 2]
    if kind == "sphere":
        return np.sqrt(x * x + y * y + z * z) - d[0]
    if kind == "box":
        qq = np.abs(q) - 0.5 * dims[:, None, :]
        out = np.sqrt(np.sum(np.maximum(qq, 0.0) ** 2, axis=-1))
        return out + np.minimum(np.max(qq, axis=-1), 0.0)
    if kind == "cylinder":
        dr = np.sqrt(x * x + y * y) - d[0]
        dz = np.abs(z) - 0.5 * d[1]
        return np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(np.maximum(dr, dz), 0.0)
    if kind == "cone":
        r0, r1, h = d
        rho = np.sqrt(x * x + y * y)
        zb = z + 0.5 * h  # base at 0
        d_bot = np.hypot(rho - np.minimum(rho, r0), zb)
        d_top = np.hypot(rho - np.minimum(rho, r1), zb - h)
        ex, ez = r1 - r0, h
        s = np.clip(((rho - r0) * ex + zb * ez) / np.maximum(ex * ex + ez * ez, 1e-30), 0.0, 1.0)
        d_side = np.hypot(rho - (r0 + s * ex), zb - s * ez)
        dist = np.minimum(np.minimum(d_bot, d_top), d_side)
        inside = (zb >= 0.0) & (zb <= h) & (rho * h <= r0 * h + (r1 - r0) * zb)
        return np.where(inside, -dist, dist)
    if kind == "half_toroid":
        R, r = d
        torus = np.hypot(np.hypot(x, y) - R, z) - r
        upper = np.where(torus < 0.0, np.maximum(torus, -y), torus)
        caps = np.minimum(
            np.hypot(np.maximum(np.hypot(x - R, z) - r, 0.0), y),
            np.hypot(np.maximum(np.hypot(x + R, z) - r, 0.0), y),
        )
        return np.where(y >= 0.0, upper, caps)
    raise ValueError(f"unknown model kind {kind!r}; valid: {KINDS}")


def model_extents(kind: str, dims: np.ndarray) -> np.ndarray:
    """Extents (H, 3) [m] of models dims (H, k) along the x, y, z axes of their fit frames."""
    d = np.atleast_2d(np.asarray(dims, float))
    if kind == "sphere":
        return np.repeat(2.0 * d[:, :1], 3, axis=1)
    if kind == "box":
        return d.copy()
    if kind == "cylinder":
        return np.column_stack([2.0 * d[:, 0], 2.0 * d[:, 0], d[:, 1]])
    if kind == "cone":
        r = np.maximum(d[:, 0], d[:, 1])
        return np.column_stack([2.0 * r, 2.0 * r, d[:, 2]])
    if kind == "half_toroid":  # the kept half is y >= 0
        return np.column_stack([2.0 * (d[:, 0] + d[:, 1]), d[:, 0] + d[:, 1], 2.0 * d[:, 1]])
    raise ValueError(f"unknown model kind {kind!r}; valid: {KINDS}")


def model_sdf(kind: str, R: np.ndarray, t: np.ndarray, dims: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Signed distances (H, N) of world points (N, 3) to H posed models. In a process
    that has numba loaded already (planning loads it for the map kernels) float64
    input goes through the compiled twin (:mod:`~graspsim.primitives.sdf_kernel`,
    the same values to the bit, a few times faster); elsewhere (identifying alone)
    importing the compiler would cost more than it saves."""
    if "numba" in sys.modules and _kernel_fits(kind, R, t, dims, points):
        from graspsim.primitives.sdf_kernel import model_sdf as compiled

        return compiled(kind, R, t, dims, points)
    return sdf_local(kind, to_local(R, t, points), dims)


def sdf_function(kind: str, points: np.ndarray):
    """``f(R, t, dims)``: :func:`model_sdf` of ``kind`` to the fixed points (N, 3), for a
    caller that evaluates many models on the same points (float64 R (H, 3, 3), t (H, 3),
    dims (H, k)): the path is chosen once, and the compiled one is called directly."""
    if "numba" in sys.modules and isinstance(points, np.ndarray) and points.dtype == np.float64 \
            and points.ndim == 2 and points.shape[1] == 3 and kind in DIM_NAMES:
        from graspsim.primitives.sdf_kernel import KIND_IDS, model_sdf_into

        code, n, k, pts = KIND_IDS[kind], len(points), len(DIM_NAMES[kind]), np.ascontiguousarray(points)

        def compiled(R, t, dims):
            H = len(R)
            if R.dtype == t.dtype == dims.dtype == np.float64 and R.shape == (H, 3, 3) and t.shape == (H, 3) \
                    and dims.shape == (H, k):
                c = np.ascontiguousarray
                return model_sdf_into(code, c(R), c(t), c(dims), pts, np.empty((len(R), n)))
            return model_sdf(kind, R, t, dims, points)

        return compiled
    return lambda R, t, dims: model_sdf(kind, R, t, dims, points)


def _kernel_fits(kind: str, R, t, dims, points) -> bool:
    """Whether the compiled distances take these inputs (float64 arrays of the shapes
    :func:`model_sdf` documents; anything else takes numpy's path and its errors)."""
    arrays = (R, t, dims, points)
    if kind not in DIM_NAMES or not all(isinstance(a, np.ndarray) and a.dtype == np.float64 for a in arrays):
        return False
    H = R.shape[0] if R.ndim == 3 else -1
    return (R.shape == (H, 3, 3) and t.shape == (H, 3) and dims.shape == (H, len(DIM_NAMES[kind]))
            and points.ndim == 2 and points.shape[1] == 3)


def fit_to_object(kind: str, R: np.ndarray, t: np.ndarray, dims: np.ndarray):
    """One fit (R (3, 3), t (3,), dims (k,)) -> (primitive, T_world_obj (4, 4)), after
    canonicalising: box edges sorted so z is the longest; cone bottom_radius >= top."""
    R, t, dims = np.array(R, float), np.array(t, float), np.array(dims, float)
    if kind == "box":
        order = np.argsort(dims, kind="stable")
        dims, R = dims[order], R[:, order]
        if np.linalg.det(R) < 0:
            R[:, 0] = -R[:, 0]
    elif kind == "cone" and dims[1] > dims[0]:
        dims = dims[[1, 0, 2]]
        R = R @ np.diag([1.0, -1.0, -1.0])
    elif kind == "sphere":
        R = np.eye(3)
    prim = make_primitive(kind, **dict(zip(DIM_NAMES[kind], map(float, dims))))
    shift = np.zeros(3)
    if kind == "cone":
        shift = prim.com_geo - np.array([0.0, 0.0, 0.5 * dims[2]])
    elif kind == "half_toroid":
        shift = prim.com_geo
    return prim, make_transform(R, t + R @ shift)
