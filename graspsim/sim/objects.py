"""Objects to simulate: collision geometry and mass properties in the object frame.

* Box, cylinder and sphere become native MuJoCo geoms.
* A cone frustum is convex: one mesh geom (its hull).
* A half-toroid is cut into ``pieces`` tube segments, each the convex hull of its two
  end circles (12 pieces of 15 deg leave the surface within 0.9 % of the ring radius).
* A compound is the union of its parts' geoms, each placed by the part's pose.
* Arbitrary meshes are prepared by :func:`graspsim.sim.meshes.prepare_mesh` (convex parts).

The body frame of the simulated object is the object frame of the map. Mass comes from
a density or is given; inertia is analytic for primitives, summed over parts (overlaps
counted twice, a small error) for compounds, and from the mesh (or its convex parts when
it is not watertight) for meshes.
"""

from __future__ import annotations

import functools
import logging
import math
import os
from dataclasses import dataclass, field

import numpy as np

from graspsim.errors import SimulationError
from graspsim.primitives import Box, Compound, Cone, Cylinder, HalfToroid, Primitive, Sphere
from graspsim.sim.meshes import CoacdParams, PreparedMesh, prepare_mesh
from graspsim.transforms import matrix_to_quat, quat_to_matrix, transform_points

__all__ = ["GeomPart", "SimObject", "object_from_shape", "object_from_mesh", "LIGHT_MASS"]

log = logging.getLogger(__name__)

#: [kg] Below this an object's simulated grasps measure the contact model as well as the grasp:
#: MuJoCo's contacts are accelerations, so the pads sink deeper into a lighter object at the
#: same grip force (with the default ``stiff`` contacts 1.5 mm into a 3.3 g domino at 250 N,
#: 0.2 mm at 98 g, and a grid of level grasps holds at every mass; with the ``soft`` ones of
#: the results published before, 4.6 and 1 mm, and the grid holds half the time at 3.3 g:
#: ``experiments/study_light_objects.py``).
LIGHT_MASS = 0.01


@dataclass(frozen=True)
class GeomPart:
    """One collision geom in the object frame. kind: "box" | "cylinder" | "sphere" |
    "mesh"; size: MuJoCo size (half extents / radius, half height) [m]; pos (3,) [m];
    quat (4,) w, x, y, z; vertices (V, 3) [m] for meshes (their hull is used)."""

    kind: str
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    vertices: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class SimObject:
    """An object ready for a scene.

    geoms: collision parts, object frame. mass [kg]; com (3,) [m] and inertia (3, 3)
    [kg m^2] about the COM, object frame. surface: a trimesh of the object for the
    resting pose and the start-collision check. description: what it is (for results).
    friction: the sliding friction of its contacts (None: the scene's; given, its geoms
    take precedence in every contact, MuJoCo's geom priority).
    """

    geoms: tuple[GeomPart, ...]
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    surface: object = field(repr=False)
    description: dict = field(default_factory=dict)
    friction: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass) and self.mass > 0):
            raise SimulationError(f"object mass must be a finite value > 0 kg, got {self.mass!r}")
        if not self.geoms:
            raise SimulationError("object has no collision geometry")
        if self.friction is not None and not (math.isfinite(self.friction) and self.friction > 0):
            raise SimulationError(f"object friction must be a finite value > 0, got {self.friction!r}")


@functools.lru_cache(maxsize=256)
def _say_light(what: str, grams: float) -> None:
    log.warning("%s weighs %.1f g: under %g g the simulated pads sink deeper into an object at the "
                "gripper's full force than into a heavier one, so its outcomes measure the contact model as "
                "well as the grasp (docs/design.md, Simulation; experiments/study_light_objects.py)",
                what, grams, 1000 * LIGHT_MASS)


def _light(obj: SimObject, what: str) -> SimObject:
    """``obj``; once per process and object, a warning when it weighs under :data:`LIGHT_MASS`."""
    if obj.mass < LIGHT_MASS:
        _say_light(what, round(1000.0 * obj.mass, 1))
    return obj


def _mass(volume: float, mass: float | None, density: float) -> float:
    if mass is not None:
        if not (math.isfinite(float(mass)) and mass > 0):
            raise SimulationError(f"object mass must be a finite value > 0 kg, got {mass!r}")
        return float(mass)
    if not (math.isfinite(density) and density > 0):
        raise SimulationError(f"object density must be > 0 kg/m^3, got {density!r}")
    return float(density * volume)


def _primitive_geoms(shape: Primitive, pieces: int) -> list[GeomPart]:
    if isinstance(shape, Box):
        return [GeomPart("box", tuple(shape.half))]
    if isinstance(shape, Sphere):
        return [GeomPart("sphere", (shape.radius, 0.0, 0.0))]
    if isinstance(shape, Cylinder):
        return [GeomPart("cylinder", (shape.radius, 0.5 * shape.height, 0.0))]
    if isinstance(shape, Cone):
        return [GeomPart("mesh", vertices=np.asarray(shape.mesh(sections=32).vertices))]
    if isinstance(shape, HalfToroid):
        R, r = shape.major_radius, shape.minor_radius
        psi = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
        th = np.linspace(0.0, math.pi, pieces + 1)
        out = []
        for a, b in zip(th[:-1], th[1:]):
            ends = []
            for t in (a, b):
                rho = R + r * np.cos(psi)
                ends.append(np.stack([rho * np.cos(t), rho * np.sin(t), r * np.sin(psi)], -1))
            out.append(GeomPart("mesh", vertices=np.concatenate(ends) - shape.com_geo))
        return out
    raise SimulationError(f"no simulation geometry for primitive {shape.kind!r}")


def _place(g: GeomPart, T: np.ndarray) -> GeomPart:
    """The geom moved by the 4x4 transform T (part frame -> object frame)."""
    R, t = T[:3, :3], T[:3, 3]
    if g.kind == "mesh":
        return GeomPart("mesh", vertices=transform_points(T, g.vertices))
    Rg = R @ quat_to_matrix(np.asarray(g.quat))
    return GeomPart(g.kind, g.size, tuple(R @ np.asarray(g.pos) + t), tuple(matrix_to_quat(Rg)))


def object_from_shape(shape: Primitive | Compound, *, mass: float | None = None,
                      density: float = 1000.0, pieces: int = 12) -> SimObject:
    """A primitive or compound as a simulation object (mass given, or density x volume)."""
    if isinstance(shape, Compound):
        m = _mass(shape.volume, mass, density)
        vols = np.array([p.volume for p in shape.parts])
        geoms, inertia = [], np.zeros((3, 3))
        for part, T, v in zip(shape.parts, shape.poses, vols):
            geoms += [_place(g, T) for g in _primitive_geoms(part, pieces)]
            mp = m * v / vols.sum()
            R, c = T[:3, :3], T[:3, 3]
            inertia += R @ part.inertia(mp) @ R.T + mp * (c @ c * np.eye(3) - np.outer(c, c))
        return _light(SimObject(tuple(geoms), m, np.zeros(3), inertia, shape.mesh(32), shape.to_dict()),
                      "the compound object")
    if not isinstance(shape, Primitive):
        raise SimulationError(f"cannot simulate a {type(shape).__name__}; give a primitive, "
                              "a compound or a mesh file")
    m = _mass(shape.volume, mass, density)
    return _light(SimObject(tuple(_primitive_geoms(shape, pieces)), m, np.zeros(3), shape.inertia(m),
                            shape.mesh(32), shape.to_dict()), f"the {shape.kind}")


def object_from_mesh(path, *, T_obj_mesh: np.ndarray | None = None,
                     scale: float = 1.0, mass: float | None = None, density: float = 1000.0,
                     coacd: CoacdParams = CoacdParams(),
                     cache_dir: str | os.PathLike | None = None, progress=None,
                     friction: float | None = None) -> SimObject:
    """A mesh file as a simulation object: its collision model from
    :func:`~graspsim.sim.meshes.prepare_mesh` (convex parts, bounded and cached; mass
    properties of the closed mesh, else of its parts), placed in the object frame.

    path: a mesh file, or a :class:`~graspsim.sim.meshes.PreparedMesh` already prepared
    (then ``scale``, ``coacd``, ``cache_dir`` and ``progress`` are not used).
    T_obj_mesh: 4x4 pose of the mesh's frame in the object frame (default identity);
    for a map adapted from a point cloud, ``inv(T_cloud_obj)`` when mesh and cloud
    share a frame. The model is prepared in the mesh's own frame, so one cache entry
    serves every placement. scale: multiplies the file's coordinates (e.g. 0.001 for mm files).
    friction: the object's own sliding friction (None: the scene's).
    """
    prepared = path if isinstance(path, PreparedMesh) else prepare_mesh(
        path, scale=scale, params=coacd, cache_dir=cache_dir, progress=progress)
    T = np.eye(4)
    if T_obj_mesh is not None:
        T = np.asarray(T_obj_mesh, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise SimulationError(f"T_obj_mesh must be a finite 4x4 transform, got shape {T.shape}")
    R = T[:3, :3]
    surface = prepared.surface.copy()
    if T_obj_mesh is not None:
        surface.apply_transform(T)
    m = _mass(prepared.volume, mass, density)
    desc = {"primitive": "mesh", "file": prepared.source, "scale": prepared.scale, "parts": len(prepared.parts),
            "model": prepared.describe()}
    return _light(SimObject(tuple(GeomPart("mesh", vertices=transform_points(T, p)) for p in prepared.parts), m,
                            R @ prepared.com + T[:3, 3], m * (R @ prepared.unit_inertia @ R.T), surface, desc,
                            friction), f"mesh {os.path.basename(str(prepared.source))}")
