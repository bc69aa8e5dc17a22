"""The objects table-top scenes draw from: primitives sized for the gripper, the
case-study analogs and the mesh objects shipped in ``assets/objects``.

An :class:`ObjectSpec` says what an object is (a shape description or a mesh file) and
how heavy it is; :meth:`ObjectSpec.sim_object` builds its simulation body (cached per
process: CoACD runs once per mesh). Every drawn object fits the gripper's opening across
at least one direction: its narrowest extent is at most ``gripper.max_opening`` less
twice the approach clearance (checked, not assumed).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass

import numpy as np

from graspsim._resources import package_path
from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.primitives import Box, Cylinder, Sphere, shape_from_dict
from graspsim.primitives.case_study import ANALOGS
from graspsim.sim.meshes import CoacdParams
from graspsim.sim.objects import SimObject, object_from_mesh, object_from_shape

__all__ = ["ObjectSpec", "OBJECT_SETS", "draw_object", "narrowest_extent", "MESHES", "ASSETS"]

#: Where the shipped meshes live: ``assets/objects``, installed with the package.
ASSETS = package_path("assets", "objects")
#: Mesh objects by name: (file under ASSETS, scale).
MESHES = {"bread": ("robosuite/bread.stl", 1.0)}
#: How the shipped meshes are prepared: CoACD without a time limit (the same parts on
#: every machine, however loaded; they are small and cached after the first use).
SHIPPED = CoacdParams(time_limit=math.inf)
#: The object sets a scene draws from.
OBJECT_SETS = ("primitives", "analogs", "meshes", "mixed")
DENSITY = 500.0  # kg/m^3: household objects are hollow or light (water would be 1000)


@dataclass(frozen=True)
class ObjectSpec:
    """What an object is. source: "primitive" | "analog" | "mesh"; name: its name (the
    primitive kind, the analog's or the mesh's name); shape: the shape's ``to_dict()``
    (primitives and analogs); density [kg/m^3]."""

    source: str
    name: str
    shape: dict | None = None
    density: float = DENSITY

    def __post_init__(self) -> None:
        if self.source not in ("primitive", "analog", "mesh"):
            raise InvalidParameterError(f"object source must be primitive, analog or mesh, got {self.source!r}")
        if self.source == "mesh" and self.name not in MESHES:
            raise InvalidParameterError(f"unknown mesh object {self.name!r}; valid: {sorted(MESHES)}")
        if self.source != "mesh" and not isinstance(self.shape, dict):
            raise InvalidParameterError(f"a {self.source} object needs its shape description")
        if not (math.isfinite(self.density) and self.density > 0):
            raise InvalidParameterError(f"density must be > 0 kg/m^3, got {self.density!r}")

    def to_dict(self) -> dict:
        return {"source": self.source, "name": self.name, "shape": self.shape, "density": self.density}

    @classmethod
    def from_dict(cls, d: dict) -> ObjectSpec:
        try:
            return cls(d["source"], d["name"], d.get("shape"), float(d.get("density", DENSITY)))
        except (KeyError, TypeError, ValueError) as err:
            raise InvalidParameterError(f"not an object description: {d!r}") from err

    def sim_object(self) -> SimObject:
        """The simulation body (object frame of docs/design.md §3, centre of mass at the origin for
        shapes; the file's frame for meshes)."""
        return _sim_object(json.dumps(self.to_dict(), sort_keys=True))

    def shape_object(self):
        """The Primitive / Compound (None for a mesh)."""
        return None if self.shape is None else shape_from_dict(self.shape)


@functools.lru_cache(maxsize=64)
def _sim_object(key: str) -> SimObject:
    spec = ObjectSpec.from_dict(json.loads(key))
    if spec.source == "mesh":
        file, scale = MESHES[spec.name]
        # no time limit: a scene's objects must not depend on the machine's load
        return object_from_mesh(ASSETS / file, scale=scale, density=spec.density, coacd=SHIPPED)
    return object_from_shape(shape_from_dict(spec.shape), density=spec.density)


def _primitive(rng: np.random.Generator) -> ObjectSpec:
    """A box, cylinder or sphere of household size that the gripper can span."""
    kind = ("box", "cylinder", "sphere")[int(rng.integers(3))]
    if kind == "box":
        a, b = rng.uniform(0.03, 0.08, 2)
        shape = Box(float(a), float(b), float(rng.uniform(0.03, 0.12)))
    elif kind == "cylinder":
        shape = Cylinder(float(rng.uniform(0.015, 0.04)), float(rng.uniform(0.04, 0.14)))
    else:
        shape = Sphere(float(rng.uniform(0.025, 0.04)))
    return ObjectSpec("primitive", kind, shape.to_dict())


def _analog(rng: np.random.Generator) -> ObjectSpec:
    name = sorted(ANALOGS)[int(rng.integers(len(ANALOGS)))]
    return ObjectSpec("analog", name, ANALOGS[name]().to_dict())


def _mesh(rng: np.random.Generator) -> ObjectSpec:
    return ObjectSpec("mesh", sorted(MESHES)[int(rng.integers(len(MESHES)))])


def narrowest_extent(obj: SimObject) -> float:
    """The object's smallest width [m] over 90 directions (its hull's minimum chord bound)."""
    v = np.asarray(obj.surface.vertices, float)
    k = np.arange(90)
    golden = math.pi * (3 - math.sqrt(5))
    z = 1 - (k + 0.5) / 90  # half sphere of directions (a width is symmetric)
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(golden * k), r * np.sin(golden * k), z], 1)
    proj = v @ d.T
    return float((proj.max(0) - proj.min(0)).min())


def draw_object(rng: np.random.Generator, object_set: str = "mixed",
                gripper: GripperSpec = HGPL_25_60_A) -> ObjectSpec:
    """One object from ``object_set`` ("primitives", "analogs", "meshes" or "mixed": half
    primitives, 3/8 analogs, 1/8 meshes) that ``gripper`` can span."""
    if object_set not in OBJECT_SETS:
        raise InvalidParameterError(f"unknown object set {object_set!r}; valid: {list(OBJECT_SETS)}")
    if object_set == "mixed":
        u = rng.random()
        object_set = "primitives" if u < 0.5 else "analogs" if u < 0.875 else "meshes"
    draw = {"primitives": _primitive, "analogs": _analog, "meshes": _mesh}[object_set]
    limit = gripper.max_opening - 2 * gripper.approach_clearance
    for _ in range(100):
        spec = draw(rng)
        if narrowest_extent(spec.sim_object()) <= limit:
            return spec
    raise InvalidParameterError(f"no object of set {object_set!r} fits a {gripper.max_opening * 1000:.0f} mm opening")
