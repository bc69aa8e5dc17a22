"""The k best grasps at least a pose apart (non-maximum suppression).

A map's best grasps crowd together: neighbouring rows of one surface patch differ by a
surface step and a rotation step, and the ten best by grade or robust score are often
one grasp ten times over -- where that grasp is bad, all ten are (E09's single views:
ten start collisions on one occluded handle). Grasp planners that return "the k best"
(GPD, VGN) suppress non-maxima: walking the grasps best first, a grasp is kept only if
no grasp kept before it is a near-duplicate.

Two grasps are near-duplicates when their grasp points lie within ``distance`` of each
other *and* their wrist orientations differ by less than ``angle`` -- the orientation
of a two-jaw grasp counted modulo the half turn about the approach axis that swaps the
jaws (the same grasp with the fingers exchanged).
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.transforms import quat_to_matrix

__all__ = ["separated_rows"]


def _jaw_swap_angles(R_kept: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(K,) rotation angle [rad] between R (3, 3) and each of R_kept (K, 3, 3), the
    smaller of the angle to R and to R turned a half turn about its approach (z) axis."""
    swap = R * np.array([-1.0, -1.0, 1.0])  # x and y axes flipped: the half turn about z
    out = []
    for Q in (R, swap):
        tr = np.einsum("kij,ij->k", R_kept, Q)  # trace(R_kept^T Q)
        out.append(np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0)))
    return np.minimum(*out)


def separated_rows(grasp_point: np.ndarray, wrist_quat: np.ndarray, order: np.ndarray, k: int, *,
                   distance: float, angle: float) -> np.ndarray:
    """Indices (at most k) of the first grasps in ``order`` (best first) that are no
    near-duplicate of one kept before them (module docstring): grasp points (N, 3) [m],
    wrist quaternions (N, 4) (w, x, y, z); distance [m] >= 0, angle [rad] >= 0 (either
    0: nothing is a duplicate, the first k of ``order``)."""
    if k < 0:
        raise InvalidParameterError(f"k must be >= 0, got {k}")
    if not (np.isfinite(distance) and distance >= 0 and np.isfinite(angle) and angle >= 0):
        raise InvalidParameterError(f"separation must be finite and >= 0, got {distance!r} m, {angle!r} rad")
    order = np.asarray(order, np.int64)
    if distance == 0 or angle == 0:
        return order[:k]
    p = np.asarray(grasp_point, float)
    kept: list[int] = []
    R_kept = np.zeros((0, 3, 3))
    for i in order:
        if len(kept) >= k:
            break
        R = quat_to_matrix(np.asarray(wrist_quat[i], float))
        if kept:
            near = np.linalg.norm(p[kept] - p[i], axis=1) < distance
            if np.any(near & (_jaw_swap_angles(R_kept, R) < angle)):
                continue
        kept.append(int(i))
        R_kept = np.concatenate([R_kept, R[None]])
    return np.asarray(kept, np.int64)
