"""Reference gripper-object collision checks (python-fcl) and penetration depths.

The map generator's compiled sweep is the fast path; this module is the independent,
slow, per-pose reference it is tested against, and a convenience for one-off checks
(e.g. of hand-made poses). Objects become native fcl shapes where fcl has them (box,
sphere, cylinder) and fine triangle meshes otherwise.
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import DependencyNotInstalled
from graspsim.grippers.spec import GripperSpec

__all__ = ["FclChecker", "penetration_depth"]


def _fcl():
    try:
        import fcl
    except ImportError as err:  # pragma: no cover - core dependency
        raise DependencyNotInstalled("python-fcl is needed: pip install python-fcl") from err
    return fcl


def _object_geometries(shape, sections: int):
    """[(fcl geometry, 4x4 pose in the object frame)] for a Primitive or Compound."""
    fcl = _fcl()
    from graspsim.primitives import Box, Compound, Cylinder, Sphere

    if isinstance(shape, Compound):
        out = []
        for part, T in zip(shape.parts, shape.poses):
            out += [(g, T @ Tp) for g, Tp in _object_geometries(part, sections)]
        return out
    if isinstance(shape, Box):
        return [(fcl.Box(shape.x, shape.y, shape.z), np.eye(4))]
    if isinstance(shape, Sphere):
        return [(fcl.Sphere(shape.radius), np.eye(4))]
    if isinstance(shape, Cylinder):
        return [(fcl.Cylinder(shape.radius, shape.height), np.eye(4))]
    mesh = shape.mesh(sections=sections)
    bvh = fcl.BVHModel()
    bvh.beginModel(len(mesh.vertices), len(mesh.faces))
    bvh.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
    bvh.endModel()
    return [(bvh, np.eye(4))]


def _tf(T: np.ndarray):
    fcl = _fcl()
    return fcl.Transform(np.asarray(T[:3, :3], float), np.asarray(T[:3, 3], float))


class FclChecker:
    """Collision of the gripper (all parts, including the arm keep-out) with an object.

    ``collides(T_obj_wrist, opening)`` for one pose, ``collides_many`` for arrays.
    """

    def __init__(self, shape, gripper: GripperSpec, *, sections: int = 256):
        fcl = _fcl()
        self.gripper = gripper
        self._objs = [fcl.CollisionObject(g, _tf(T)) for g, T in _object_geometries(shape, sections)]
        b = gripper.collision_boxes()
        self._half = b.half_extents
        self._boxes = [fcl.Box(*(2 * h)) for h in b.half_extents]

    def _parts(self, T_obj_wrist: np.ndarray, opening: float):
        fcl = _fcl()
        c, _ = self.gripper.boxes_at(opening)
        R, p = T_obj_wrist[:3, :3], T_obj_wrist[:3, 3]
        return [fcl.CollisionObject(box, fcl.Transform(R, R @ ci + p)) for box, ci in zip(self._boxes, c)]

    def collides(self, T_obj_wrist: np.ndarray, opening: float) -> bool:
        fcl = _fcl()
        req = fcl.CollisionRequest()
        for part in self._parts(np.asarray(T_obj_wrist, float), float(opening)):
            for obj in self._objs:
                if fcl.collide(part, obj, req, fcl.CollisionResult()):
                    return True
        return False

    def distance(self, T_obj_wrist: np.ndarray, opening: float) -> float:
        """Smallest distance between gripper and object [m] (<= 0 when touching)."""
        fcl = _fcl()
        best = np.inf
        for part in self._parts(np.asarray(T_obj_wrist, float), float(opening)):
            for obj in self._objs:
                res = fcl.DistanceResult()
                best = min(best, fcl.distance(part, obj, fcl.DistanceRequest(), res))
        return float(best)

    def collides_many(self, T_obj_wrist: np.ndarray, opening: np.ndarray) -> np.ndarray:
        return np.array([self.collides(T, o) for T, o in zip(T_obj_wrist, opening)], bool)


def penetration_depth(shape, gripper: GripperSpec, T_obj_wrist: np.ndarray, opening: float,
                      step: float = 2e-4) -> float:
    """Deepest point of the gripper's boxes inside the object [m] (0 if none), from the
    object's exact SDF on a grid of the boxes' volumes at ``step`` spacing."""
    c, h = gripper.boxes_at(opening)
    R, p = T_obj_wrist[:3, :3], T_obj_wrist[:3, 3]
    deepest = 0.0
    bb = shape.aabb
    for ci, hi in zip(c, h):
        axes = [np.arange(-hi[k], hi[k] + step / 2, step) if hi[k] < 0.02 else
                np.linspace(-hi[k], hi[k], 101) for k in range(3)]
        g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + ci
        w = g @ R.T + p
        inside = np.all((w >= bb[0] - 1e-9) & (w <= bb[1] + 1e-9), axis=1)
        if np.any(inside):
            deepest = max(deepest, float(-np.min(shape.sdf(w[inside]))))
    return max(deepest, 0.0)
