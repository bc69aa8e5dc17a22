"""SE(3) helpers on batches of poses.

Conventions (docs/design.md §3): quaternions are ``w, x, y, z`` (MuJoCo's order); a transform
``T_a_b`` is the pose of frame ``b`` expressed in frame ``a`` as a 4x4 homogeneous
matrix, so ``p_a = T_a_b @ p_b``. All functions accept batches with leading dimensions.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "quat_to_matrix",
    "matrix_to_quat",
    "make_transform",
    "invert_transform",
    "transform_points",
    "split_transform",
    "frame_from_axes",
    "random_rotation",
    "angle_between",
    "normalize",
    "cross3",
    "quat_multiply",
]


def normalize(v: np.ndarray, axis: int = -1, eps: float = 1e-12) -> np.ndarray:
    """Unit vectors along ``axis``; zero vectors stay zero."""
    v = np.asarray(v, dtype=float)
    n = np.sqrt(np.add.reduce(v * v, axis=axis, keepdims=True))  # np.linalg.norm's sum, without its checks
    return v / np.maximum(n, eps)


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products (..., 3) of 3-vectors along the last axis (broadcast): ``np.cross``'s
    products and differences in its order, so its values to the bit, without its
    Python overhead (tens of microseconds on a small batch)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def quat_to_matrix(q_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions w, x, y, z -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q_wxyz, dtype=float)
    flat = q.reshape(-1, 4)
    mats = Rotation.from_quat(flat[:, [1, 2, 3, 0]]).as_matrix()
    return mats.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions w, x, y, z with w >= 0."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    xyzw = Rotation.from_matrix(flat).as_quat()
    wxyz = xyzw[:, [3, 0, 1, 2]]
    wxyz *= np.where(wxyz[:, :1] < 0.0, -1.0, 1.0)
    return wxyz.reshape(R.shape[:-2] + (4,))


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (..., 4) w, x, y, z (the rotation b, then
    a); the result has w >= 0."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    q = np.stack([aw * bw - ax * bx - ay * by - az * bz,
                  aw * bx + ax * bw + ay * bz - az * by,
                  aw * by - ax * bz + ay * bw + az * bx,
                  aw * bz + ax * by - ay * bx + az * bw], axis=-1)
    return q * np.where(q[..., :1] < 0.0, -1.0, 1.0)


def make_transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Rotation (..., 3, 3) and translation (..., 3) -> (..., 4, 4) homogeneous transform."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    lead = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros(lead + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def split_transform(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., 4, 4) -> rotation (..., 3, 3), translation (..., 3)."""
    T = np.asarray(T, dtype=float)
    return T[..., :3, :3], T[..., :3, 3]


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4): ``T_b_a`` from ``T_a_b``."""
    R, p = split_transform(T)
    Rt = np.swapaxes(R, -1, -2)
    return make_transform(Rt, -np.einsum("...ij,...j->...i", Rt, p))


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply one transform (4, 4) to points (N, 3), or batches elementwise."""
    R, p = split_transform(T)
    return np.einsum("...ij,...j->...i", R, np.asarray(points, dtype=float)) + p


def frame_from_axes(x_axis: np.ndarray, z_axis: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) whose columns are x, y = z × x, z.

    ``x_axis`` and ``z_axis`` must be (nearly) orthogonal unit vectors; ``x`` is
    re-orthogonalised against ``z``.
    """
    z = normalize(z_axis)
    x = np.asarray(x_axis, dtype=float)
    x = normalize(x - np.sum(x * z, axis=-1, keepdims=True) * z)
    y = cross3(z, x)
    return np.stack([x, y, z], axis=-1)


def random_rotation(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Uniformly random rotation matrices, (3, 3) or (n, 3, 3), drawn from ``rng``."""
    R = Rotation.random(1 if n is None else n, random_state=rng).as_matrix()
    return R[0] if n is None else R


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle [rad] between vectors along the last axis, robust near 0 and pi."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.arctan2(cross, dot)
