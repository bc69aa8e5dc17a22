"""The gripper drawn as line segments: the edges of its collision boxes at wrist poses and
openings (:func:`gripper_wireframe`), for the viewer and the clutter-removal figures."""

from __future__ import annotations

import numpy as np

from graspsim.geometry.boxes import box_mesh

__all__ = ["gripper_wireframe"]


_EDGES = np.array([[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5],
                   [2, 6], [3, 7]])


def gripper_wireframe(gripper, T_obj_wrist: np.ndarray, opening) -> np.ndarray:
    """Edge segments [m] of the gripper's collision boxes (arm keep-out included) at
    wrist poses ``T_obj_wrist`` (4, 4) or (N, 4, 4) with pad gaps ``opening`` (scalar or
    (N,)) [m]: (12B, 2, 3) for one pose, (N * 12B, 2, 3) for N."""
    T = np.asarray(T_obj_wrist, float)
    single = T.ndim == 2
    T = T.reshape(-1, 4, 4)
    opening = np.clip(np.broadcast_to(np.asarray(opening, float), (len(T),)), gripper.min_opening,
                      gripper.max_opening)
    b = gripper.collision_boxes()
    verts, _ = box_mesh(b.centers, b.half_extents)  # (8B, 3) at opening 0
    shift = np.repeat(b.x_sign, 8) * 0.5  # each vertex's x moves with its box
    local = np.repeat(verts[None].astype(float), len(T), axis=0)
    local[:, :, 0] += shift[None] * opening[:, None]
    world = np.einsum("nij,nvj->nvi", T[:, :3, :3], local) + T[:, None, :3, 3]
    idx = (_EDGES[None] + 8 * np.arange(len(b.names))[:, None, None]).reshape(-1, 2)
    seg = world[:, idx].reshape(-1, 2, 3).astype(np.float32)
    return seg if not single else seg.reshape(-1, 2, 3)
