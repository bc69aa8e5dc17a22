"""Half-toroid: a torus cut in two by a plane through its symmetry axis (a handle).

Geometric frame: ring centred on the origin in the x-y plane, symmetry axis z, the
kept half is y >= 0 (ring angle 0..pi from +x). The two cut faces are disks in the
plane y = 0 centred at (+R, 0, 0) and (-R, 0, 0), facing -y. Object frame: shifted so
the centre of mass (on +y) is the origin; z stays the symmetry axis (docs/design.md §3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from graspsim.errors import PrimitiveError
from graspsim.primitives._sampling import assemble, disk_part, revolution_part
from graspsim.primitives.base import Primitive, orient_outward
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["HalfToroid"]


@dataclass(frozen=True)
class HalfToroid(Primitive):
    """Half of a torus with ring radius ``major_radius`` (axis to tube centre) and tube
    radius ``minor_radius`` [m]; requires major > minor."""

    major_radius: float
    minor_radius: float

    kind: ClassVar[str] = "half_toroid"
    dim_names: ClassVar[tuple[str, ...]] = ("major_radius", "minor_radius")

    def _validate(self) -> None:
        super()._validate()
        if self.major_radius <= self.minor_radius:
            raise PrimitiveError(
                "half_toroid needs major_radius > minor_radius (else the ring "
                f"self-intersects), got major={self.major_radius!r}, minor={self.minor_radius!r}"
            )

    @property
    def volume(self) -> float:
        return math.pi**2 * self.major_radius * self.minor_radius**2

    @property
    def com_geo(self) -> np.ndarray:
        R, r = self.major_radius, self.minor_radius
        return np.array([0.0, 2.0 * (R * R + 0.25 * r * r) / (math.pi * R), 0.0])

    @property
    def min_cross_section(self) -> float:
        return 2.0 * self.minor_radius  # across the tube

    @property
    def circumradius(self) -> float:
        # the far ends of the outer ring, (+-(R + r), 0, 0), seen from the COM on +y
        return math.hypot(self.major_radius + self.minor_radius, float(self.com_geo[1]))

    def _inertia_geo_unit(self) -> np.ndarray:
        R2, r2 = self.major_radius**2, self.minor_radius**2
        ixx = 0.5 * R2 + 0.625 * r2
        return np.diag([ixx, ixx, R2 + 0.75 * r2])

    def _sdf_geo(self, p: np.ndarray) -> np.ndarray:
        R, r = self.major_radius, self.minor_radius
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        torus = np.hypot(np.hypot(x, y) - R, z) - r
        upper = np.where(torus < 0.0, np.maximum(torus, -y), torus)
        # y < 0: nearest point is on one of the two cut disks
        dists = []
        for cx in (R, -R):
            q = np.hypot(x - cx, z)
            dists.append(np.hypot(np.maximum(q - r, 0.0), y))
        lower = np.minimum(*dists)
        return np.where(y >= 0.0, upper, lower)

    def _to_unit_geo(self, p: np.ndarray) -> np.ndarray:
        # (ring angle, radial and axial offsets from the tube centre in tube radii)
        R, r = self.major_radius, self.minor_radius
        rho = np.hypot(p[:, 0], p[:, 1])
        return np.column_stack([np.arctan2(p[:, 1], p[:, 0]), (rho - R) / r, p[:, 2] / r])

    def _from_unit_geo(self, q: np.ndarray) -> np.ndarray:
        R, r = self.major_radius, self.minor_radius
        rho = R + r * q[:, 1]
        return np.column_stack([rho * np.cos(q[:, 0]), rho * np.sin(q[:, 0]), r * q[:, 2]])

    def _samples_geo(self, step: float) -> SurfaceSamples:
        R, r = self.major_radius, self.minor_radius

        def profile(s):
            psi = s / r
            return R + r * np.cos(psi), r * np.sin(psi), np.cos(psi), np.sin(psi)

        tube = revolution_part(profile, 2.0 * math.pi * r, step, sweep=math.pi)
        ex, ez = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
        # u x v = x x z = -y: both cut faces look towards -y
        caps = [disk_part(np.array([c, 0.0, 0.0]), ex, ez, r, step) for c in (R, -R)]
        return assemble([tube, *caps])

    def _aabb_geo(self) -> np.ndarray:
        R, r = self.major_radius, self.minor_radius
        return np.array([[-R - r, 0.0, -r], [R + r, R + r, r]])

    def _mesh_geo(self, sections: int):
        import trimesh  # only meshes need it: keeps it out of plain imports

        R, r = self.major_radius, self.minor_radius
        nt, npsi = max(8, sections // 2), max(8, sections // 2)
        th = np.linspace(0.0, math.pi, nt + 1)
        psi = np.linspace(0.0, 2.0 * math.pi, npsi, endpoint=False)
        T, P = np.meshgrid(th, psi, indexing="ij")
        rho = R + r * np.cos(P)
        ring = np.stack([rho * np.cos(T), rho * np.sin(T), r * np.sin(P)], axis=-1).reshape(-1, 3)
        centers = np.array([[R, 0.0, 0.0], [-R, 0.0, 0.0]])
        verts = np.vstack([ring, centers])
        idx = np.arange((nt + 1) * npsi).reshape(nt + 1, npsi)
        a, b = idx[:-1], idx[1:]
        a1, b1 = np.roll(a, -1, axis=1), np.roll(b, -1, axis=1)
        faces = [np.stack([a, b, b1], -1).reshape(-1, 3), np.stack([a, b1, a1], -1).reshape(-1, 3)]
        c0, c1 = len(ring), len(ring) + 1
        j, j1 = np.arange(npsi), np.roll(np.arange(npsi), -1)
        faces.append(np.column_stack([np.full(npsi, c0), idx[0, j1], idx[0, j]]))
        faces.append(np.column_stack([np.full(npsi, c1), idx[-1, j], idx[-1, j1]]))
        return orient_outward(trimesh.Trimesh(verts, np.vstack(faces), process=True), self._sdf_geo)
