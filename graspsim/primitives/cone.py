"""Cone frustum (a full cone when one radius is 0). Object frame: origin at the centre
of mass, z along the axis from the bottom face towards the top face."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.polynomial import Polynomial

from graspsim.errors import PrimitiveError
from graspsim.primitives._sampling import assemble, disk_part, revolution_part
from graspsim.primitives.base import MIN_DIM, Primitive
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["Cone"]

_X, _Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Cone(Primitive):
    """Frustum with ``bottom_radius`` at the base, ``top_radius`` (0 allowed: a cone)
    at the top, and ``height`` [m]. The geometric frame has the base at z = 0."""

    bottom_radius: float
    top_radius: float
    height: float

    kind: ClassVar[str] = "cone"
    dim_names: ClassVar[tuple[str, ...]] = ("bottom_radius", "top_radius", "height")

    def _validate(self) -> None:
        self._check_floor("height")
        if self.bottom_radius < 0.0 or self.top_radius < 0.0:
            raise PrimitiveError(
                f"cone radii must be >= 0 m, got bottom={self.bottom_radius!r}, top={self.top_radius!r}"
            )
        if max(self.bottom_radius, self.top_radius) < MIN_DIM:
            raise PrimitiveError(
                f"cone needs a radius >= {MIN_DIM:g} m (thinner is a line, not a solid); got "
                f"bottom={self.bottom_radius!r}, top={self.top_radius!r}")

    @property
    def min_cross_section(self) -> float:
        # the narrow end (0 for a full cone's apex) or across the height
        return min(2.0 * min(self.bottom_radius, self.top_radius), self.height)

    # ------------------------------------------------------------------ helpers
    @property
    def _slope(self) -> float:
        return (self.top_radius - self.bottom_radius) / self.height

    def _profile_poly(self) -> Polynomial:
        return Polynomial([self.bottom_radius, self._slope])

    @property
    def volume(self) -> float:
        r0, r1, h = self.bottom_radius, self.top_radius, self.height
        return math.pi * h * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0

    @property
    def com_geo(self) -> np.ndarray:
        r0, r1, h = self.bottom_radius, self.top_radius, self.height
        zc = h * (r0 * r0 + 2 * r0 * r1 + 3 * r1 * r1) / (4 * (r0 * r0 + r0 * r1 + r1 * r1))
        return np.array([0.0, 0.0, zc])

    @property
    def circumradius(self) -> float:
        zc = float(self.com_geo[2])
        return max(math.hypot(self.bottom_radius, zc), math.hypot(self.top_radius, self.height - zc))

    def _inertia_geo_unit(self) -> np.ndarray:
        rho = self._profile_poly()
        z = Polynomial([0.0, 1.0])
        h = self.height

        def integral(p: Polynomial) -> float:
            ip = p.integ()
            return float(ip(h) - ip(0.0))

        izz = integral(0.5 * math.pi * rho**4)
        ixx = integral(0.25 * math.pi * rho**4 + math.pi * rho**2 * z**2)
        return np.diag([ixx, ixx, izz]) / self.volume

    # ------------------------------------------------------------------ geometry
    def _sdf_geo(self, p: np.ndarray) -> np.ndarray:
        r0, r1, h = self.bottom_radius, self.top_radius, self.height
        q = np.linalg.norm(p[..., :2], axis=-1)
        z = p[..., 2]
        d_bot = np.hypot(q - np.minimum(q, r0), z)
        d_top = np.hypot(q - np.minimum(q, r1), z - h)
        # side segment (r0, 0) -> (r1, h)
        ex, ez = r1 - r0, h
        t = np.clip(((q - r0) * ex + z * ez) / (ex * ex + ez * ez), 0.0, 1.0)
        d_side = np.hypot(q - (r0 + t * ex), z - t * ez)
        dist = np.minimum(np.minimum(d_bot, d_top), d_side)
        inside = (z >= 0.0) & (z <= h) & (q <= r0 + self._slope * z)
        return np.where(inside, -dist, dist)

    def _ray_exit_geo(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        m, r0, h = self._slope, self.bottom_radius, self.height
        rz = r0 + m * o[:, 2]
        A = d[:, 0] ** 2 + d[:, 1] ** 2 - (m * d[:, 2]) ** 2
        B = o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1] - rz * m * d[:, 2]
        C = o[:, 0] ** 2 + o[:, 1] ** 2 - rz**2
        disc = np.sqrt(np.maximum(B * B - A * C, 0.0))
        eps = 1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            # f(t) = A t^2 + 2 B t + C <= 0 inside the (double) cone. For A > 0 the
            # ray leaves at the larger root; for A < 0 at the smaller one, if it lies
            # ahead (otherwise only a cap stops it); A ~ 0 is the linear case.
            root = (-B + disc) / A
            side = np.where(
                A > eps,
                root,
                np.where(A < -eps, root, np.where(B > 0, -C / (2.0 * B), np.inf)),
            )
            cap = np.where(d[:, 2] > 0, (h - o[:, 2]) / d[:, 2], -o[:, 2] / d[:, 2])
        cap = np.where(np.abs(d[:, 2]) > 1e-15, cap, np.inf)
        side = np.where(np.isfinite(side) & (side > eps), side, np.inf)
        return np.minimum(side, cap)

    def _radius_at(self, zeta: np.ndarray) -> np.ndarray:
        """Side radius at normalised height zeta (clipped to the body), floored so the
        apex of a full cone stays invertible."""
        z = np.clip(zeta, 0.0, 1.0)
        r = self.bottom_radius + (self.top_radius - self.bottom_radius) * z
        return np.maximum(r, 1e-6 * max(self.bottom_radius, self.top_radius))

    def _to_unit_geo(self, p: np.ndarray) -> np.ndarray:
        zeta = p[:, 2] / self.height
        r = self._radius_at(zeta)
        return np.column_stack([p[:, 0] / r, p[:, 1] / r, zeta])

    def _from_unit_geo(self, q: np.ndarray) -> np.ndarray:
        r = self._radius_at(q[:, 2])
        return np.column_stack([q[:, 0] * r, q[:, 1] * r, q[:, 2] * self.height])

    def _samples_geo(self, step: float) -> SurfaceSamples:
        r0, r1, h = self.bottom_radius, self.top_radius, self.height
        slant = math.hypot(h, r1 - r0)
        nr, nz = h / slant, (r0 - r1) / slant

        def profile(s):
            f = s / slant
            one = np.ones_like(s)
            return r0 + (r1 - r0) * f, h * f, nr * one, nz * one

        parts = [revolution_part(profile, slant, step)]
        if r0 > 0.0:
            parts.append(disk_part(np.zeros(3), _Y, _X, r0, step))
        if r1 > 0.0:
            parts.append(disk_part(np.array([0.0, 0.0, h]), _X, _Y, r1, step))
        return assemble(parts)

    def _aabb_geo(self) -> np.ndarray:
        r = max(self.bottom_radius, self.top_radius)
        return np.array([[-r, -r, 0.0], [r, r, self.height]])

    def _mesh_geo(self, sections: int):
        import trimesh  # only meshes need it: keeps it out of plain imports

        r0, r1, h = self.bottom_radius, self.top_radius, self.height
        prof = [(0.0, 0.0)] if r0 > 0 else []
        prof += [(r0, 0.0), (r1, h)]
        prof += [(0.0, h)] if r1 > 0 else []
        mesh = trimesh.creation.revolve(np.array(prof), sections=sections)
        if mesh.volume < 0:
            mesh.invert()
        return mesh
