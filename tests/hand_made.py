"""Hand-made grasps and maps for tests and examples (no map generator needed).

``grasp_pose`` places the wrist so that the TCP at contact ``depth`` from the fingertips
lies on a grasp point, approaching along ``approach`` and closing along ``closing`` (both
object frame). ``hand_made_map`` wraps such poses in a :class:`GraspabilityMap` whose
contacts lie on the closing line at +-width/2.
"""

from __future__ import annotations

import numpy as np

from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.maps import GraspabilityMap, MapMeta
from graspsim.transforms import frame_from_axes, make_transform, matrix_to_quat

__all__ = ["grasp_pose", "hand_made_map"]


def grasp_pose(grasp_point, approach, closing, depth: float = 0.02,
               gripper: GripperSpec = HGPL_25_60_A) -> np.ndarray:
    """T_obj_wrist (4, 4) of a grasp at ``grasp_point`` (3,) [m] approaching along the
    unit vector ``approach`` with jaws closing along ``closing`` (orthogonal to it)."""
    a = np.asarray(approach, dtype=float)
    R = frame_from_axes(np.asarray(closing, dtype=float), a)
    p = gripper.wrist_from_grasp_point(np.asarray(grasp_point, dtype=float), a / np.linalg.norm(a), depth)
    return make_transform(R, p)


def hand_made_map(shape, T_obj_wrist: np.ndarray, widths, *, gripper: GripperSpec = HGPL_25_60_A,
                  grades=None, depth: float = 0.02, mass: float | None = None,
                  friction: float = 0.5, extra: dict | None = None) -> GraspabilityMap:
    """A map of the given poses (N, 4, 4) and contact widths (N,) [m] on ``shape``."""
    T = np.asarray(T_obj_wrist, float).reshape(-1, 4, 4)
    w = np.asarray(widths, float).reshape(-1)
    n = len(T)
    gp = gripper.grasp_point_from_wrist(T[:, :3, 3], T[:, :3, 2], depth)
    x = T[:, :3, 0]
    contacts = np.stack([gp - 0.5 * w[:, None] * x, gp + 0.5 * w[:, None] * x], axis=1)
    normals = np.stack([-x, x], axis=1)
    grade = np.ones(n) if grades is None else np.asarray(grades, float)
    obj = dict(shape.to_dict(), com=[0.0, 0.0, 0.0], mass=float("nan") if mass is None else mass)
    meta = MapMeta(object=obj, gripper=gripper.to_dict(), quality={"friction": friction, "threshold": 0.7},
                   resolution={"surface_step": 0.005}, method="hand_made", extra=extra or {})
    zeros = np.zeros(n)
    return GraspabilityMap(
        wrist_position=T[:, :3, 3], wrist_quat=matrix_to_quat(T[:, :3, :3]), grasp_point=gp,
        contacts=contacts, normals=normals, width=w, fc_angle=zeros, q_fc=grade,
        stability_distance=zeros, q_st=grade, grade=grade, part=np.zeros(n, int), meta=meta)
