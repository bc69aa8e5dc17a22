"""Sphere. Object frame: centred."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from graspsim.primitives._sampling import assemble, revolution_part
from graspsim.primitives.base import Primitive
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["Sphere"]


@dataclass(frozen=True)
class Sphere(Primitive):
    """Sphere of ``radius`` [m]."""

    radius: float

    kind: ClassVar[str] = "sphere"
    dim_names: ClassVar[tuple[str, ...]] = ("radius",)

    @property
    def volume(self) -> float:
        return 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def circumradius(self) -> float:
        return float(self.radius)

    @property
    def min_cross_section(self) -> float:
        return 2.0 * self.radius

    def _inertia_geo_unit(self) -> np.ndarray:
        return np.eye(3) * 0.4 * self.radius**2

    def _sdf_geo(self, p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(p, axis=-1) - self.radius

    def _ray_exit_geo(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        b = np.sum(o * d, axis=1)
        c = np.sum(o * o, axis=1) - self.radius**2
        return -b + np.sqrt(np.maximum(b * b - c, 0.0))

    def _unit_axes(self) -> float:
        return self.radius

    def _samples_geo(self, step: float) -> SurfaceSamples:
        r = self.radius

        def profile(s):
            a = s / r
            return r * np.sin(a), -r * np.cos(a), np.sin(a), -np.cos(a)

        return assemble([revolution_part(profile, math.pi * r, step)])

    def _aabb_geo(self) -> np.ndarray:
        return np.array([[-1.0] * 3, [1.0] * 3]) * self.radius

    def _mesh_geo(self, sections: int):
        import trimesh  # only meshes need it: keeps it out of plain imports

        sub = 2 if sections <= 32 else 3 if sections <= 64 else 4
        return trimesh.creation.icosphere(subdivisions=sub, radius=self.radius)
