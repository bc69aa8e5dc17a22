"""The objects table-top scenes draw from: primitives sized for the gripper, the
case-study analogs, and meshes: the sets shipped in ``assets/objects``
(``household``, ``random`` and their tuning / held-out parts) or any folder of a user's
mesh files (:mod:`graspsim.tabletop.mesh_objects`: manifests, default mass, content hashes).

An :class:`ObjectSpec` says what an object is (a shape description or a mesh file with
its content hash, scale, mass and friction); :meth:`ObjectSpec.sim_object` builds its
simulation body (cached per process: CoACD runs once per mesh, and its parts are cached
on disk). A mesh whose file changed since its spec was written is refused. Every drawn
object fits the gripper's opening across at least one direction: its narrowest extent is
at most ``gripper.max_opening`` less twice the approach clearance (checked, not assumed;
a folder's meshes that do not fit are left out, said so, and a folder none of whose
meshes fits is refused).
"""

from __future__ import annotations

import functools
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim.errors import InvalidParameterError, MeshError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.primitives import Box, Cylinder, Sphere, shape_from_dict
from graspsim.primitives.case_study import ANALOGS
from graspsim.sim.meshes import prepare_mesh
from graspsim.sim.objects import SimObject, object_from_mesh, object_from_shape
from graspsim.tabletop.mesh_objects import (
    ASSETS,
    MeshEntry,
    MeshSet,
    default_mass,
    file_sha256,
    is_mesh_set,
    mesh_set,
    shipped_names,
)
from graspsim.transforms import make_transform

__all__ = ["ObjectSpec", "OBJECT_SETS", "draw_object", "narrowest_extent", "MESHES", "ASSETS", "check_object_set",
           "object_set_names", "prepare_objects", "mesh_spec"]

log = logging.getLogger(__name__)
#: How a folder's user scales a mesh, named in the hints of a mesh refused for its size.
_SCALE_OPTION = "the manifest's scale"

#: The mesh of the "meshes" set (of "mixed"): name -> (file under ASSETS, scale).
MESHES = {"bread": ("robosuite/bread.stl", 1.0)}
#: The built-in object sets a scene draws from (besides the shipped mesh sets of
#: :func:`object_set_names` and any folder of meshes).
OBJECT_SETS = ("primitives", "analogs", "meshes", "mixed")
DENSITY = 500.0  # kg/m^3: the primitives' and analogs' (household objects are hollow or light)


@dataclass(frozen=True)
class ObjectSpec:
    """What an object is. source: "primitive" | "analog" | "mesh"; name: its name (the
    primitive kind, the analog's or the mesh's name); shape: the shape's ``to_dict()``
    (primitives and analogs); density [kg/m^3] (meshes: None = the household default,
    :func:`~graspsim.tabletop.mesh_objects.default_mass`). Meshes: file (under ASSETS when
    relative), sha256 of its content (checked when the body is built), scale, mass [kg]
    (None: from density) and friction (None: the scene's)."""

    source: str
    name: str
    shape: dict | None = None
    density: float | None = DENSITY
    file: str | None = None
    sha256: str | None = None
    scale: float = 1.0
    mass: float | None = None
    friction: float | None = None

    def __post_init__(self) -> None:
        if self.source not in ("primitive", "analog", "mesh"):
            raise InvalidParameterError(f"object source must be primitive, analog or mesh, got {self.source!r}")
        if self.source == "mesh" and self.file is None:
            if self.name not in MESHES:
                raise InvalidParameterError(f"unknown mesh object {self.name!r}; valid: {sorted(MESHES)}")
            object.__setattr__(self, "file", MESHES[self.name][0])  # a scene written before files were named
        if self.source != "mesh" and not isinstance(self.shape, dict):
            raise InvalidParameterError(f"a {self.source} object needs its shape description")
        if self.density is None and self.source != "mesh":
            raise InvalidParameterError("a shape object needs a density")
        for k in ("density", "mass", "friction", "scale"):
            v = getattr(self, k)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise InvalidParameterError(f"object {k} must be > 0, got {v!r}")

    def to_dict(self) -> dict:
        d = {"source": self.source, "name": self.name, "shape": self.shape, "density": self.density}
        if self.source == "mesh":
            d.update(file=self.file, sha256=self.sha256, scale=self.scale, mass=self.mass, friction=self.friction)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ObjectSpec:
        try:
            f = {k: d.get(k) for k in ("file", "sha256", "mass", "friction")}
            dens = d.get("density", DENSITY)
            return cls(d["source"], d["name"], d.get("shape"), None if dens is None else float(dens),
                       scale=float(d.get("scale", 1.0)), **f)
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            raise InvalidParameterError(f"not an object description: {d!r}") from err

    def sim_object(self) -> SimObject:
        """The simulation body (object frame of docs/design.md §3, centre of mass at the origin for
        shapes; for meshes the file's frame moved to the centre of mass,
        ``description["T_obj_file"]`` the file's frame in it)."""
        return _sim_object(json.dumps(self.to_dict(), sort_keys=True))

    def shape_object(self):
        """The Primitive / Compound (None for a mesh)."""
        return None if self.shape is None else shape_from_dict(self.shape)

    @property
    def T_obj_file(self) -> np.ndarray:
        """(4, 4) the mesh file's frame in the object frame (identity for shapes)."""
        d = self.sim_object().description
        return np.asarray(d["T_obj_file"], float) if "T_obj_file" in d else np.eye(4)


def mesh_spec(entry: MeshEntry, density: float | None = None) -> ObjectSpec:
    """The spec of a set's mesh (``density``: when the entry gives neither mass nor density)."""
    return ObjectSpec("mesh", entry.name, None, entry.density if entry.density is not None else density,
                      entry.file, entry.sha256, entry.scale, entry.mass, entry.friction)


@functools.lru_cache(maxsize=128)
def _sim_object(key: str) -> SimObject:
    spec = ObjectSpec.from_dict(json.loads(key))
    if spec.source != "mesh":
        return object_from_shape(shape_from_dict(spec.shape), density=spec.density)
    path = MeshEntry(spec.name, spec.file, "").path
    if spec.sha256 is not None and file_sha256(path) != spec.sha256:
        raise InvalidParameterError(f"mesh {path} changed since the scene was written (its content hash is not the "
                                    f"recorded {spec.sha256[:12]}...); restore that file or draw the scene again")
    # the one mesh preparation (graspsim.sim.meshes.prepare_mesh) with its default settings, the
    # model `graspsim trial --mesh` gets: bounded by the worker's CPU time, so the same parts on
    # an idle or a loaded machine, ready in seconds on first use and cached by content after
    prepared = prepare_mesh(path, scale=spec.scale)
    mass, model = spec.mass, "given"
    if mass is None and spec.density is None:
        mass, model = default_mass(prepared.surface)
    elif mass is None:
        model = "density"
    # the object frame: the file's frame moved to the centre of mass of the prepared model
    T_obj_file = make_transform(np.eye(3), -np.asarray(prepared.com, float))
    obj = object_from_mesh(prepared, T_obj_mesh=T_obj_file, mass=mass, density=spec.density or 1000.0,
                           friction=spec.friction)
    obj.description.update(name=spec.name, sha256=spec.sha256, mass_model=model, T_obj_file=T_obj_file.tolist())
    return obj


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
    name = sorted(MESHES)[int(rng.integers(len(MESHES)))]
    file = MESHES[name][0]
    return ObjectSpec("mesh", name, None, DENSITY, file, file_sha256(ASSETS / file), MESHES[name][1])


def narrowest_extent(obj) -> float:
    """The smallest width [m] over 90 directions (a hull's minimum chord bound) of a
    SimObject's surface, or of vertices (V, 3)."""
    v = np.asarray(obj.surface.vertices if isinstance(obj, SimObject) else obj, float)
    k = np.arange(90)
    golden = math.pi * (3 - math.sqrt(5))
    z = 1 - (k + 0.5) / 90  # half sphere of directions (a width is symmetric)
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(golden * k), r * np.sin(golden * k), z], 1)
    proj = v @ d.T
    return float((proj.max(0) - proj.min(0)).min())


def object_set_names() -> tuple[str, ...]:
    """Every named object set: the built-in ones and the shipped mesh sets."""
    return (*OBJECT_SETS, *shipped_names())


def check_object_set(name) -> str:
    """``name`` if it is a named object set or a folder of meshes, else
    :class:`InvalidParameterError` naming the valid sets."""
    if not isinstance(name, str) or not (name in OBJECT_SETS or is_mesh_set(name)):
        raise InvalidParameterError(f"unknown object set {name!r}; valid: {list(object_set_names())} "
                                    "or a folder of mesh files")
    return name


def _fitting(name: str, limit: float) -> tuple[MeshSet, tuple[MeshEntry, ...]]:
    """(the set, its meshes whose narrowest extent is at most ``limit`` [m]); a set none
    of whose meshes fits is refused, those left out are logged. Read afresh each time
    (a folder's content may change), measured once per content."""
    ms = mesh_set(name)
    return ms, _fit_entries(ms, limit)


@functools.lru_cache(maxsize=16)
def _fit_entries(ms: MeshSet, limit: float) -> tuple[MeshEntry, ...]:
    from graspsim.sim.meshes import load_mesh

    name = ms.label
    fits, out = [], []  # out: (entry, narrowest width [m] or None, why it is not drawn)
    for e in ms.entries:
        try:
            w = narrowest_extent(load_mesh(e.path, scale=e.scale, scale_option=_SCALE_OPTION).vertices)
        except MeshError as err:  # unreadable, flat, or wider than 2 m / under 5 mm: its units are not metres
            out.append((e, None, str(err)))
        else:
            if w <= limit:
                fits.append(e)
                continue
            out.append((e, w, f"{Path(e.file).name} is {w * 1000:.0f} mm across at its narrowest, wider than the "
                              f"gripper spans ({limit * 1000:.0f} mm)"))
    if not fits:
        units = any(_SCALE_OPTION in why for _, _, why in out)  # a size refused as not in metres
        raise InvalidParameterError(
            f"no mesh of {name} can be drawn: " + "; ".join(why for _, _, why in out[:5])
            + (f"; and {len(out) - 5} more" if len(out) > 5 else "")
            + ("; scale a folder's meshes to metres in its manifest (objects.json: {\"defaults\": {\"scale\": "
               "0.001}} for mm)" if units else ""))
    for _, _, why in out:
        log.warning("%s: not drawn", why)
    return tuple(fits)


def prepare_objects(object_set: str, gripper: GripperSpec = HGPL_25_60_A, *, progress: bool = False,
                    delay: float = 0.0) -> list[str]:
    """Build the simulation body of every mesh ``object_set`` draws (a mesh set; nothing
    for the built-in sets), so a first scene does not wait on convex decompositions;
    ``progress``: a bar on stderr when it is a terminal, shown once the work has taken
    ``delay`` seconds (cached meshes take well under a second). Returns the names of the
    meshes drawn."""
    check_object_set(object_set)
    if object_set in OBJECT_SETS:
        return []
    _, entries = _fitting(object_set, gripper.max_opening - 2 * gripper.approach_clearance)
    from graspsim._progress import progress as stderr_bar

    with stderr_bar(len(entries), "preparing meshes", enabled=progress, unit="mesh", delay=delay, tick=1.0) as bar:
        for e in entries:
            bar.set_postfix_str(e.name, refresh=False)  # the mesh being decomposed (a first one can take minutes)
            mesh_spec(e).sim_object()
            bar.update()
    return [e.name for e in entries]


def draw_object(rng: np.random.Generator, object_set: str = "mixed",
                gripper: GripperSpec = HGPL_25_60_A) -> ObjectSpec:
    """One object from ``object_set`` ("primitives", "analogs", "meshes" or "mixed": half
    primitives, 3/8 analogs, 1/8 meshes; a shipped mesh set or a folder of meshes: one of
    its meshes, uniformly) that ``gripper`` can span."""
    check_object_set(object_set)
    limit = gripper.max_opening - 2 * gripper.approach_clearance
    if object_set not in OBJECT_SETS:
        _, entries = _fitting(object_set, limit)
        return mesh_spec(entries[int(rng.integers(len(entries)))])
    if object_set == "mixed":
        u = rng.random()
        object_set = "primitives" if u < 0.5 else "analogs" if u < 0.875 else "meshes"
    draw = {"primitives": _primitive, "analogs": _analog, "meshes": _mesh}[object_set]
    for _ in range(100):
        spec = draw(rng)
        if narrowest_extent(spec.sim_object()) <= limit:
            return spec
    raise InvalidParameterError(f"no object of set {object_set!r} fits a {gripper.max_opening * 1000:.0f} mm opening")
