"""Triangle meshes of axis-aligned boxes (:func:`box_mesh`), for the gripper's wireframe
and the viewer's glyphs."""

from __future__ import annotations

import numpy as np

__all__ = ["box_mesh"]


def box_mesh(centers: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned boxes (B, 3) centres and half extents as one triangle mesh:
    vertices (8B, 3), faces (12B, 3), outward winding."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    verts = (np.asarray(centers, float)[:, None] + np.asarray(half, float)[:, None] * signs).reshape(-1, 3)
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                      [1, 5, 7, 3]])
    tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    faces = (tri[None] + 8 * np.arange(len(centers))[:, None, None]).reshape(-1, 3)
    return verts.astype(np.float32), faces.astype(np.int32)
