"""Rectangular box (cuboid). Object frame: centred, edges along x, y, z."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from graspsim.primitives._sampling import assemble, rect_part
from graspsim.primitives.base import Primitive
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["Box"]


@dataclass(frozen=True)
class Box(Primitive):
    """Box with full edge lengths ``x``, ``y``, ``z`` [m]. By convention (docs/design.md §3)
    ``z`` is the longest edge when the box comes from identification."""

    x: float
    y: float
    z: float

    kind: ClassVar[str] = "box"
    dim_names: ClassVar[tuple[str, ...]] = ("x", "y", "z")

    @property
    def half(self) -> np.ndarray:
        return 0.5 * np.array([self.x, self.y, self.z])

    @property
    def volume(self) -> float:
        return self.x * self.y * self.z

    @property
    def circumradius(self) -> float:
        return float(np.linalg.norm(self.half))

    @property
    def min_cross_section(self) -> float:
        return float(min(self.x, self.y, self.z))

    def _inertia_geo_unit(self) -> np.ndarray:
        x2, y2, z2 = self.x**2, self.y**2, self.z**2
        return np.diag([y2 + z2, x2 + z2, x2 + y2]) / 12.0

    def _sdf_geo(self, p: np.ndarray) -> np.ndarray:
        q = np.abs(p) - self.half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
        inside = np.minimum(np.max(q, axis=-1), 0.0)
        return outside + inside

    def _ray_exit_geo(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.sign(d) * self.half - o) / d
        t = np.where(np.abs(d) > 1e-15, t, np.inf)
        return np.min(t, axis=1)

    def _unit_axes(self) -> np.ndarray:
        return self.half

    def _samples_geo(self, step: float) -> SurfaceSamples:
        h = self.half
        e = np.eye(3)
        parts = []
        for k in range(3):
            i, j = (k + 1) % 3, (k + 2) % 3
            L = [self.x, self.y, self.z]
            for sgn in (1.0, -1.0):
                # u x v must be the outward normal sgn * e_k
                u, v = (e[i], e[j]) if sgn > 0 else (e[j], e[i])
                lu, lv = (L[i], L[j]) if sgn > 0 else (L[j], L[i])
                parts.append(rect_part(sgn * h[k] * e[k], u, v, lu, lv, step))
        return assemble(parts)

    def _aabb_geo(self) -> np.ndarray:
        return np.stack([-self.half, self.half])

    def _mesh_geo(self, sections: int):
        import trimesh  # only meshes need it: keeps it out of plain imports

        return trimesh.creation.box(extents=[self.x, self.y, self.z])
