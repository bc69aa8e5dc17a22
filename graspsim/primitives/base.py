"""The shape-primitive interface and what all primitives share.

Every primitive is described in two frames:

* its *geometric* frame, where the formulas are simplest (a cone's base at z = 0, a
  half-toroid's ring centred on the origin), and
* the *object* frame of docs/design.md §3: origin at the centre of mass, z along the main
  axis. Object = geometric - ``com_geo``; no rotation between them.

Every public method takes and returns object-frame quantities in metres.
Subclasses implement the ``_geo`` methods; the base class does the frame shift.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields, replace
from typing import ClassVar

import numpy as np

from graspsim.errors import PrimitiveError
from graspsim.primitives.samples import SurfaceSamples

__all__ = ["Primitive", "orient_outward", "MIN_DIM", "MAX_DIM"]

#: Smallest dimension of a primitive [m]. Anything thinner is degenerate: a plane or a
#: line seen as a solid (identification of a flat or collinear cluster), far below
#: what a sensor resolves or the gripper can hold.
MIN_DIM = 1e-3

#: Largest dimension of a primitive [m]: nothing a two-jaw gripper handles is a kilometre
#: long, and beyond it areas and volumes head towards float overflow.
MAX_DIM = 1e3


@dataclass(frozen=True)
class Primitive(ABC):
    """A solid shape primitive with named dimensions in metres."""

    kind: ClassVar[str]
    dim_names: ClassVar[tuple[str, ...]]

    # ----------------------------------------------------------------- construction
    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                fvalue = float(value)
            except (TypeError, ValueError, OverflowError):
                raise PrimitiveError(
                    f"{self.kind} {f.name} must be a number in metres, got {value!r}"
                ) from None
            if not math.isfinite(fvalue):
                raise PrimitiveError(f"{self.kind} {f.name} must be finite, got {value!r}")
            if abs(fvalue) > MAX_DIM:
                raise PrimitiveError(f"{self.kind} {f.name} must be at most {MAX_DIM:g} m (no object that "
                                     f"large is grasped; were the dimensions meant in metres?), got {value!r}")
            object.__setattr__(self, f.name, fvalue)
        self._validate()

    def _validate(self) -> None:
        for name in self.dim_names:
            self._check_floor(name)

    def _check_floor(self, name: str) -> None:
        value = getattr(self, name)
        if not value > 0.0:
            raise PrimitiveError(f"{self.kind} {name} must be > 0 m, got {value!r}")
        if value < MIN_DIM:
            raise PrimitiveError(
                f"{self.kind} {name} must be >= {MIN_DIM:g} m (thinner is degenerate: a "
                f"plane or a line, not a solid), got {value!r}")

    @property
    def dims(self) -> dict[str, float]:
        """Named dimensions [m], in the order of ``dim_names``."""
        return {name: float(getattr(self, name)) for name in self.dim_names}

    def dims_vector(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in self.dim_names])

    def with_dims(self, **dims: float) -> Primitive:
        """A copy with some dimensions replaced (validated)."""
        unknown = set(dims) - set(self.dim_names)
        if unknown:
            raise PrimitiveError(
                f"{self.kind} has no dimension(s) {sorted(unknown)}; valid: {list(self.dim_names)}"
            )
        return replace(self, **dims)

    def to_dict(self) -> dict:
        return {"primitive": self.kind, "dims": self.dims}

    def __str__(self) -> str:
        inner = ", ".join(f"{k}={v * 100:.3g} cm" for k, v in self.dims.items())
        return f"{self.kind}({inner})"

    # --------------------------------------------------------------- mass properties
    @property
    @abstractmethod
    def volume(self) -> float:
        """Solid volume [m^3]."""

    @property
    def com_geo(self) -> np.ndarray:
        """Centre of mass in the geometric frame [m]; zero for centred shapes."""
        return np.zeros(3)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in the object frame: the origin, by definition."""
        return np.zeros(3)

    @abstractmethod
    def _inertia_geo_unit(self) -> np.ndarray:
        """Inertia tensor (3, 3) about the geometric origin for unit mass."""

    def inertia(self, mass: float = 1.0) -> np.ndarray:
        """Inertia tensor (3, 3) about the centre of mass, object axes [kg m^2]."""
        if not mass > 0.0:
            raise PrimitiveError(f"mass must be > 0 kg, got {mass!r}")
        c = self.com_geo
        shift = np.dot(c, c) * np.eye(3) - np.outer(c, c)
        return mass * (self._inertia_geo_unit() - shift)

    def mass(self, density: float) -> float:
        if not density > 0.0:
            raise PrimitiveError(f"density must be > 0 kg/m^3, got {density!r}")
        return density * self.volume

    # ------------------------------------------------------------------- geometry
    @abstractmethod
    def _sdf_geo(self, p: np.ndarray) -> np.ndarray: ...

    @abstractmethod
    def _samples_geo(self, step: float) -> SurfaceSamples: ...

    @abstractmethod
    def _aabb_geo(self) -> np.ndarray: ...

    @abstractmethod
    def _mesh_geo(self, sections: int): ...

    def _ray_exit_geo(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        return _march_exit(self._sdf_geo, o, d, self.size_scale)

    def _unit_axes(self):
        """The lengths along x, y, z (one number: the same on all three) that the unit
        shape is scaled by to make this one: a box's half sides, a cylinder's radius and
        half height, a sphere's radius. A primitive whose unit map is no scaling (the
        cone, the half-toroid) overrides :meth:`_to_unit_geo` and :meth:`_from_unit_geo`."""
        raise NotImplementedError(f"{type(self).__name__} has no axis scaling to its unit shape")

    def _to_unit_geo(self, p: np.ndarray) -> np.ndarray:
        return p / self._unit_axes()

    def _from_unit_geo(self, q: np.ndarray) -> np.ndarray:
        return q * self._unit_axes()

    def to_unit(self, points: np.ndarray) -> np.ndarray:
        """Shape-normalised coordinates (N, 3) of object-frame points: the same for
        corresponding points of every size variant of this primitive (surface to
        surface, axis to axis). See :meth:`from_unit`."""
        return self._to_unit_geo(np.asarray(points, float).reshape(-1, 3) + self.com_geo)

    def from_unit(self, q: np.ndarray) -> np.ndarray:
        """Object-frame points (N, 3) of shape-normalised coordinates (inverse of
        :meth:`to_unit`). ``b.from_unit(a.to_unit(p))`` maps a point of ``a`` to the
        corresponding point of the size variant ``b`` (the paper's scaling, eqs. 3-4)."""
        return self._from_unit_geo(np.asarray(q, float).reshape(-1, 3)) - self.com_geo

    def sdf(self, points: np.ndarray) -> np.ndarray:
        """Exact signed distance (N,) [m] of object-frame points (N, 3); < 0 inside."""
        p = np.asarray(points, dtype=float)
        return self._sdf_geo(p + self.com_geo)

    def contains(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        return self.sdf(points) < -tol

    def normals(self, points: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        """Outward unit normals (N, 3) at (or near) surface points: the SDF gradient."""
        p = np.asarray(points, dtype=float).reshape(-1, 3) + self.com_geo
        # the six shifted copies in one SDF call (row by row the same arithmetic as six calls)
        shifted = np.empty((3, 2, len(p), 3))
        for k in range(3):
            e = np.zeros(3)
            e[k] = eps
            np.add(p, e, out=shifted[k, 0])
            np.subtract(p, e, out=shifted[k, 1])
        d = self._sdf_geo(shifted.reshape(-1, 3)).reshape(3, 2, len(p))
        g = np.empty_like(p)
        for k in range(3):
            g[:, k] = d[k, 0] - d[k, 1]
        n = np.linalg.norm(g, axis=1, keepdims=True)
        return g / np.maximum(n, 1e-300)

    def surface_samples(self, step: float) -> SurfaceSamples:
        """Deterministic samples of the whole surface at spacing <= ``step`` [m]."""
        if not (step > 0.0 and math.isfinite(step)):
            raise PrimitiveError(f"surface step must be a positive length in metres, got {step!r}")
        if step > self.size_scale:
            raise PrimitiveError(
                f"surface step {step} m is larger than the {self} itself "
                f"(size scale {self.size_scale:.4g} m); use a step below that"
            )
        return self._samples_geo(step).shifted(-self.com_geo)

    def ray_exit(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Distance (N,) along unit ``directions`` from ``origins`` on or inside the
        surface to where the ray first leaves the solid [m]; inf if it never does."""
        o = np.asarray(origins, dtype=float).reshape(-1, 3) + self.com_geo
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        return self._ray_exit_geo(o, d)

    @property
    def aabb(self) -> np.ndarray:
        """Axis-aligned bounds (2, 3) in the object frame [m]."""
        return self._aabb_geo() - self.com_geo

    @property
    def size_scale(self) -> float:
        """Largest extent of the bounding box [m]."""
        b = self._aabb_geo()
        return float(np.max(b[1] - b[0]))

    @property
    @abstractmethod
    def min_cross_section(self) -> float:
        """Thinnest local width of the solid [m]: no pair of parallel jaws closer than
        this can hold any part of it (a sphere's diameter, a box's shortest edge)."""

    @property
    def circumradius(self) -> float:
        """Largest distance from the centre of mass to the surface [m] (analytic in
        every primitive; this mesh-based fallback is for subclasses that lack it)."""
        return _circumradius(self)

    def mesh(self, sections: int = 64):
        """A watertight ``trimesh.Trimesh`` in the object frame."""
        m = self._mesh_geo(sections)
        m.apply_translation(-self.com_geo)
        return m


def orient_outward(mesh, sdf):
    """Flip faces of ``mesh`` whose normal disagrees with the SDF gradient (outward)."""
    c = mesh.triangles_center
    eps = 1e-6
    g = np.stack([sdf(c + eps * e) - sdf(c - eps * e) for e in np.eye(3)], axis=1)
    flip = np.sum(g * mesh.face_normals, axis=1) < 0.0
    if np.any(flip):
        faces = mesh.faces.copy()
        faces[flip] = faces[flip][:, ::-1]
        mesh = type(mesh)(mesh.vertices, faces, process=False)
    return mesh


def _circumradius(shape: Primitive) -> float:
    # Vertices of a fine mesh bound the distance from below; the bounding-box corners
    # from above. Meshes here sample the true surface (vertices lie on it), and the
    # furthest point of every primitive is a rim or an extreme point that the mesh
    # contains, so the mesh value is exact up to the faceting of circles.
    v = shape.mesh(sections=256).vertices
    return float(np.max(np.linalg.norm(v, axis=1)))


def _march_exit(sdf, o: np.ndarray, d: np.ndarray, scale: float) -> np.ndarray:
    """First exit of rays started on/inside a solid, by sphere tracing on an exact SDF
    followed by bisection. Works for non-convex solids; accurate to ~1e-9 m."""
    n = len(o)
    t = np.full(n, 1e-7)
    out = np.full(n, np.inf)
    min_step = 2e-5 * max(scale, 1e-3)
    active = np.arange(n)
    t_in = t.copy()
    for _ in range(4000):
        if active.size == 0:
            break
        p = o[active] + t[active, None] * d[active]
        s = sdf(p)
        crossed = s >= 0.0
        if np.any(crossed):
            idx = active[crossed]
            lo, hi = t_in[idx], t[idx]
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                inside = sdf(o[idx] + mid[:, None] * d[idx]) < 0.0
                lo = np.where(inside, mid, lo)
                hi = np.where(inside, hi, mid)
            out[idx] = 0.5 * (lo + hi)
        keep = ~crossed
        active = active[keep]
        t_in[active] = t[active]
        t[active] = t[active] + np.maximum(-s[keep], min_step)
        far = t[active] > 4.0 * scale
        active = active[~far]
    return out
