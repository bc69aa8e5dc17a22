"""Solid right circular cylinder. Object frame: centred, axis z."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from graspsim.primitives._sampling import assemble, disk_part, revolution_part
from graspsim.primitives.base import Primitive
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["Cylinder"]

_X, _Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Cylinder(Primitive):
    """Cylinder of ``radius`` and ``height`` [m] along z."""

    radius: float
    height: float

    kind: ClassVar[str] = "cylinder"
    dim_names: ClassVar[tuple[str, ...]] = ("radius", "height")

    @property
    def volume(self) -> float:
        return math.pi * self.radius**2 * self.height

    @property
    def circumradius(self) -> float:
        return math.hypot(self.radius, 0.5 * self.height)

    @property
    def min_cross_section(self) -> float:
        return min(2.0 * self.radius, self.height)

    def _inertia_geo_unit(self) -> np.ndarray:
        r2, h2 = self.radius**2, self.height**2
        ixx = (3.0 * r2 + h2) / 12.0
        return np.diag([ixx, ixx, 0.5 * r2])

    def _sdf_geo(self, p: np.ndarray) -> np.ndarray:
        dr = np.linalg.norm(p[..., :2], axis=-1) - self.radius
        dz = np.abs(p[..., 2]) - 0.5 * self.height
        outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
        return outside + np.minimum(np.maximum(dr, dz), 0.0)

    def _ray_exit_geo(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        a = d[:, 0] ** 2 + d[:, 1] ** 2
        b = o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]
        c = o[:, 0] ** 2 + o[:, 1] ** 2 - self.radius**2
        with np.errstate(divide="ignore", invalid="ignore"):
            side = (-b + np.sqrt(np.maximum(b * b - a * c, 0.0))) / a
            cap = (np.sign(d[:, 2]) * 0.5 * self.height - o[:, 2]) / d[:, 2]
        side = np.where(a > 1e-15, side, np.inf)
        cap = np.where(np.abs(d[:, 2]) > 1e-15, cap, np.inf)
        return np.minimum(side, cap)

    def _unit_axes(self) -> np.ndarray:
        return np.array([self.radius, self.radius, 0.5 * self.height])

    def _samples_geo(self, step: float) -> SurfaceSamples:
        r, h = self.radius, self.height

        def profile(s):
            one = np.ones_like(s)
            return r * one, s - h / 2, one, 0.0 * one

        side = revolution_part(profile, h, step)
        top = disk_part(np.array([0.0, 0.0, h / 2]), _X, _Y, r, step)
        bottom = disk_part(np.array([0.0, 0.0, -h / 2]), _Y, _X, r, step)
        return assemble([side, top, bottom])

    def _aabb_geo(self) -> np.ndarray:
        r, h = self.radius, self.height / 2
        return np.array([[-r, -r, -h], [r, r, h]])

    def _mesh_geo(self, sections: int):
        import trimesh  # only meshes need it: keeps it out of plain imports

        return trimesh.creation.cylinder(radius=self.radius, height=self.height, sections=sections)
