"""Compound objects: the union of posed primitives (a bottle = two cylinders).

The compound's object frame has its origin at the compound's centre of mass (uniform
density, overlaps counted once); each part keeps its own object frame, placed by
``T_obj_part`` (4x4).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from graspsim.errors import PrimitiveError
from graspsim.primitives.base import Primitive, _march_exit
from graspsim.primitives.samples import SurfaceSamples
from graspsim.transforms import invert_transform, transform_points

__all__ = ["Compound", "object_frame"]


@dataclass(frozen=True)
class Compound:
    """Union of primitives. parts: tuple of Primitive; poses: (P, 4, 4) ``T_obj_part``."""

    parts: tuple[Primitive, ...]
    poses: np.ndarray

    kind = "compound"

    @classmethod
    def from_parts(cls, parts, poses) -> Compound:
        """Build from parts posed in any reference frame; re-centred on the joint COM."""
        parts = tuple(parts)
        poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
        if len(parts) == 0 or len(parts) != len(poses):
            raise PrimitiveError(
                f"a compound needs one pose per part and at least one part; got "
                f"{len(parts)} parts, {len(poses)} poses"
            )
        com, volume = _mass_properties(parts, poses)
        shifted = poses.copy()
        shifted[:, :3, 3] -= com
        out = cls(parts, shifted)
        out.__dict__["volume"] = volume  # a shift keeps the volume: no second integration
        return out

    def __str__(self) -> str:
        """The parts in words (a map's object row, logs): ``compound of 2 parts:
        cylinder(radius=3.49 cm, height=10.2 cm) + cylinder(...)``, with the overall size."""
        size = np.ptp(self.aabb, axis=0) * 100
        return (f"compound of {len(self.parts)} parts: " + " + ".join(str(p) for p in self.parts)
                + f"; {size[0]:.3g} x {size[1]:.3g} x {size[2]:.3g} cm overall")

    # ------------------------------------------------------------------ geometry
    def _part_points(self, i: int, p: np.ndarray) -> np.ndarray:
        return transform_points(invert_transform(self.poses[i]), p)

    def part_sdfs(self, points: np.ndarray) -> np.ndarray:
        """(P, N) signed distances of object-frame points to each part."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.stack([s.sdf(self._part_points(i, p)) for i, s in enumerate(self.parts)])

    def sdf(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of the union (exact outside, a bound inside) [m]."""
        return np.min(self.part_sdfs(points), axis=0)

    def normals(self, points: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        g = np.stack([self.sdf(p + eps * e) - self.sdf(p - eps * e) for e in np.eye(3)], axis=1)
        return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)

    def surface_samples(self, step: float) -> SurfaceSamples:
        """Samples of the union's surface: each part's samples not inside another part."""
        out = []
        for i, s in enumerate(self.parts):
            smp = s.surface_samples(step)
            R, t = self.poses[i][:3, :3], self.poses[i][:3, 3]
            pts, nrm = smp.points @ R.T + t, smp.normals @ R.T
            others = [j for j in range(len(self.parts)) if j != i]
            keep = np.ones(len(pts), bool)
            for j in others:
                keep &= self.parts[j].sdf(self._part_points(j, pts)) >= -1e-9
            out.append(SurfaceSamples(pts[keep], nrm[keep], smp.areas[keep], smp.cover_radius,
                                      smp.tangent_radius[keep], smp.normal_height[keep]))
        return SurfaceSamples.concat(out)

    def part_index(self, points: np.ndarray) -> np.ndarray:
        """(N,) index of the part whose surface is nearest to each point."""
        return np.argmin(np.abs(self.part_sdfs(points)), axis=0)

    def ray_exit(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        o = np.asarray(origins, float).reshape(-1, 3)
        d = np.asarray(directions, float).reshape(-1, 3)
        return _march_exit(self.sdf, o, d, self.size_scale)

    @property
    def aabb(self) -> np.ndarray:
        corners = []
        for i, s in enumerate(self.parts):
            b = s.aabb
            c = np.array(np.meshgrid(*b.T, indexing="ij")).reshape(3, -1).T
            corners.append(transform_points(self.poses[i], c))
        c = np.concatenate(corners)
        return np.stack([c.min(0), c.max(0)])

    @property
    def size_scale(self) -> float:
        b = self.aabb
        return float(np.max(b[1] - b[0]))

    @property
    def min_cross_section(self) -> float:
        """Thinnest local width of any part [m] (a lower bound for the union's)."""
        return min(p.min_cross_section for p in self.parts)

    @functools.cached_property
    def volume(self) -> float:
        """[m^3], integrated once per compound (overlaps on a grid: tens of ms)."""
        return _mass_properties(self.parts, self.poses)[1]

    @property
    def com(self) -> np.ndarray:
        return np.zeros(3)

    @property
    def circumradius(self) -> float:
        v = self.mesh().vertices
        return float(np.max(np.linalg.norm(v, axis=1)))

    def mesh(self, sections: int = 64):
        """Concatenated part meshes in the object frame (overlaps not removed)."""
        import trimesh

        meshes = []
        for i, s in enumerate(self.parts):
            m = s.mesh(sections)
            m.apply_transform(self.poses[i])
            meshes.append(m)
        return trimesh.util.concatenate(meshes)

    def to_dict(self) -> dict:
        return {
            "primitive": "compound",
            "parts": [p.to_dict() for p in self.parts],
            "poses": self.poses.tolist(),
        }


def _mass_properties(parts, poses, n_grid: int = 48) -> tuple[np.ndarray, float]:
    """Centre of mass and volume of a union of posed parts.

    Exact analytic sums when parts do not overlap; overlaps are removed with a grid
    integration over the overlap region only (their volume is usually small).
    """
    vols = np.array([p.volume for p in parts])
    coms = poses[:, :3, 3]
    V, M1 = vols.sum(), (vols[:, None] * coms).sum(0)
    if len(parts) > 1:
        boxes = []
        for i, s in enumerate(parts):
            b = s.aabb
            c = np.array(np.meshgrid(*b.T, indexing="ij")).reshape(3, -1).T
            w = transform_points(poses[i], c)
            boxes.append((w.min(0), w.max(0)))
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        axes = [np.linspace(lo[k], hi[k], n_grid + 1)[:-1] + (hi[k] - lo[k]) / (2 * n_grid) for k in range(3)]
        g = np.array(np.meshgrid(*axes, indexing="ij")).reshape(3, -1).T
        inside = np.stack(
            [s.sdf(transform_points(invert_transform(poses[i]), g)) < 0 for i, s in enumerate(parts)]
        )
        count = inside.sum(0)
        extra = count > 1
        if np.any(extra):
            dv = np.prod((hi - lo) / n_grid)
            k = (count[extra] - 1).astype(float)
            V -= dv * k.sum()
            M1 -= dv * (k[:, None] * g[extra]).sum(0)
    return M1 / V, float(V)


def object_frame(prims: list, T_cloud: list) -> tuple[np.ndarray, Compound | None]:
    """The object frame of identified parts, ``T_cloud`` their poses in the cloud frame:
    (T_cloud_obj, the compound or None): one part -> its frame; several -> the
    compound's centre of mass with the axes of its largest part."""
    if len(prims) == 1:
        return T_cloud[0], None
    vols = [p.volume for p in prims]
    big = int(np.argmax(vols))
    com = sum(v * T[:3, 3] for v, T in zip(vols, T_cloud)) / sum(vols)
    T_ref = T_cloud[big].copy()
    T_ref[:3, 3] = com
    inv = invert_transform(T_ref)
    compound = Compound.from_parts(prims, np.stack([inv @ T for T in T_cloud]))
    # from_parts re-centred the parts on the exact union COM (overlaps removed)
    shift = np.eye(4)
    shift[:3, 3] = (inv @ T_cloud[0])[:3, 3] - compound.poses[0][:3, 3]
    return T_ref @ shift, compound
