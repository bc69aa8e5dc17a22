"""Meshes as scene objects: the shipped sets, a user's folder of meshes with an optional
manifest, the default mass of a mesh, and the content hash a saved scene keeps.

**Sets.** ``household``: the real everyday objects shipped in ``assets/objects``
(robosuite's bottle, bread, can, cereal box, lemon and milk carton; pybullet's domino,
duck, jenga block, Lego brick, mug and teddy); ``random``: pybullet's 30 procedurally
generated "random objects" (irregular, non-primitive). Every one fits the Festo's
opening across its narrowest width. Each set is split by one fixed rule, written before
any tuning on it: its meshes sorted by the SHA-256 of their file content, every third
(positions 2, 5, 8, ...) is *held out* (``household-heldout``, ``random-heldout``), the rest
is the *tuning* part (``household-tuning``, ``random-tuning``); nothing is tuned on a
held-out mesh, which E10 reports apart.

**A folder.** Any folder of mesh files (``.stl .obj .ply .off .glb .gltf``, as trimesh
reads them; not recursive) is a set. An optional manifest ``objects.json`` or
``objects.toml`` in it gives per-file settings and defaults for all::

    {"defaults": {"scale": 0.001},
     "objects": {"mug.stl": {"mass": 0.31, "friction": 0.6}, "box.obj": {"density": 250}}}

    [defaults]
    scale = 0.001
    [objects."mug.stl"]
    mass = 0.31

keys: ``scale`` (multiplies the file's coordinates: 0.001 for millimetres), ``mass`` [kg],
``density`` [kg/m^3 of the enclosed volume], ``friction`` (sliding coefficient; the
object's contacts use it), ``exclude`` (true: not drawn). Unknown keys or files are refused.

**Default mass** (no mass or density given): household objects are neither solid water
nor one fixed density. A closed mesh that fills at least half of its convex hull is taken
as a filled object at :data:`FILL_DENSITY` (400 kg/m^3: YCB's packaged food and fruit
span 200 (cracker box) to 950 (soup can) kg/m^3; 400 gives a 0.45 l cereal box 180 g and a
lemon 14 g); any other mesh -- open, or a closed shell that encloses little of its hull,
e.g. a cup modelled with its walls -- is a shell of :data:`SHELL_DENSITY` (2 kg/m^2: 1.7
mm of plastic or 0.8 mm of ceramic; YCB's mug, 0.06 m^2 of surface, weighs 118 g, this
gives 116 g), counting a closed shell's two faces once. The rule is
:func:`default_mass`; a manifest's mass or density overrides it.

**Frame.** A mesh's file origin can lie anywhere (pybullet's teddy: 10 cm from the
bear); the simulated object's frame is the file's frame moved to the mesh's centre of
mass (of the enclosed volume, else of its convex parts: the prepared model's,
:func:`graspsim.sim.meshes.prepare_mesh`), and ``T_obj_file`` records the file's
frame in it, so poses can be given in the file's frame.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

from graspsim._resources import package_path
from graspsim.errors import InvalidParameterError, MeshError

__all__ = ["ASSETS", "MeshEntry", "MeshSet", "SHIPPED", "FILL_DENSITY", "SHELL_DENSITY", "SOLID_SHARE",
           "MANIFESTS", "file_sha256", "default_mass", "read_folder", "shipped_set",
           "mesh_set", "is_mesh_set", "heldout_split", "BENCHMARK_SET"]

#: Where the shipped meshes live: ``assets/objects``, installed with the package.
ASSETS = package_path("assets", "objects")
#: Density [kg/m^3] of a filled household object (default_mass).
FILL_DENSITY = 400.0
#: Mass per area [kg/m^2] of a hollow or open household object (default_mass).
SHELL_DENSITY = 2.0
#: A closed mesh filling at least this share of its convex hull is a filled object.
SOLID_SHARE = 0.5
#: The manifest files a folder may hold (one at most).
MANIFESTS = ("objects.json", "objects.toml")
_KEYS = {"scale", "mass", "density", "friction", "exclude"}
_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")  # graspsim.sim.meshes.MESH_SUFFIXES

#: The object set of the clutter benchmark where none is named: ``graspsim scene``,
#: :func:`~graspsim.tabletop.clutter.run_benchmark`, :func:`~graspsim.tabletop.clutter.benchmark_episode`,
#: the ``ClutterClear-v0`` environment (``ClutterEnvConfig.object_set``, which repeats the name so that
#: the environment's settings load without the simulator) and E15: the shipped real meshes.
BENCHMARK_SET = "household"
#: The shipped sets: name -> files under ASSETS.
SHIPPED = {
    "household": ("robosuite/bottle.stl", "robosuite/bread.stl", "robosuite/can.stl", "robosuite/cereal.stl",
                  "robosuite/lemon.stl", "robosuite/milk.stl", "pybullet/domino.stl", "pybullet/duck.stl",
                  "pybullet/jenga.stl", "pybullet/lego.stl", "pybullet/mug.stl", "pybullet/teddy.stl"),
    "random": tuple(f"pybullet/random_{i:03d}.stl" for i in range(30)),
}
_PARTS = ("tuning", "heldout")


def file_sha256(path: str | os.PathLike) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError as err:
        raise MeshError(f"cannot read mesh file {path}: {err.strerror or err}") from err
    return h.hexdigest()


@dataclass(frozen=True)
class MeshEntry:
    """One mesh of a set: name (the file's stem), file (relative to :data:`ASSETS` for the
    shipped meshes, else absolute), sha256 of its bytes, scale, and the manifest's mass
    [kg], density [kg/m^3] and friction (None: the defaults)."""

    name: str
    file: str
    sha256: str
    scale: float = 1.0
    mass: float | None = None
    density: float | None = None
    friction: float | None = None

    @property
    def path(self) -> Path:
        p = Path(self.file)
        return p if p.is_absolute() else ASSETS / p


@dataclass(frozen=True)
class MeshSet:
    """A set of meshes scenes draw from: its label (a set name or a folder) and entries."""

    label: str
    entries: tuple[MeshEntry, ...]


def heldout_split(entries) -> tuple[list, list]:
    """(tuning, held out) of ``entries`` (objects with a ``sha256``): sorted by their
    content hash, every third (positions 2, 5, 8, ...) is held out. A rule of the files'
    content alone, fixed before any tuning."""
    order = sorted(entries, key=lambda e: e.sha256)
    return [e for i, e in enumerate(order) if i % 3 != 2], [e for i, e in enumerate(order) if i % 3 == 2]


def shipped_set(name: str) -> MeshSet:
    """A shipped set by name: ``household``, ``random``, or either with ``-tuning`` /
    ``-heldout`` (see the module docstring)."""
    base, _, part = name.partition("-")
    if base not in SHIPPED or part not in ("", *_PARTS):
        raise InvalidParameterError(f"unknown mesh set {name!r}; valid: {sorted(shipped_names())}")
    entries = [MeshEntry(Path(f).stem, f, file_sha256(ASSETS / f)) for f in SHIPPED[base]]
    if part:
        entries = heldout_split(entries)[_PARTS.index(part)]
    return MeshSet(name, tuple(sorted(entries, key=lambda e: e.file)))


def shipped_names() -> tuple[str, ...]:
    return tuple(f"{b}{p}" for b in SHIPPED for p in ("", *(f"-{q}" for q in _PARTS)))


def is_mesh_set(name: str) -> bool:
    """Whether ``name`` names a shipped mesh set or a folder (not a built-in set)."""
    return name in shipped_names() or Path(name).is_dir()


def mesh_set(name: str) -> MeshSet:
    """A shipped set by name, else the folder ``name`` (:func:`read_folder`)."""
    if name in shipped_names():
        return shipped_set(name)
    return read_folder(name)


def _manifest(folder: Path) -> tuple[dict, Path | None]:
    """The folder's manifest (empty without one) and its path."""
    found = [folder / m for m in MANIFESTS if (folder / m).is_file()]
    if len(found) > 1:
        raise InvalidParameterError(f"{folder} holds both {MANIFESTS[0]} and {MANIFESTS[1]}; keep one")
    if not found:
        return {}, None
    path = found[0]
    try:
        if path.suffix == ".json":
            d = json.loads(path.read_text())
        else:
            import tomllib

            d = tomllib.loads(path.read_text())
    except (OSError, ValueError) as err:  # tomllib.TOMLDecodeError is a ValueError
        raise InvalidParameterError(f"cannot read the manifest {path}: {err}") from err
    if not isinstance(d, dict) or set(d) - {"defaults", "objects"}:
        raise InvalidParameterError(f"manifest {path}: expected the tables 'defaults' and 'objects', got "
                                    f"{sorted(d) if isinstance(d, dict) else type(d).__name__}")
    for k in ("defaults", "objects"):
        if not isinstance(d.get(k, {}), dict):
            raise InvalidParameterError(f"manifest {path}: '{k}' must be a table of settings")
    return d, path


def _positive(path, key: str, v) -> float | None:
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
        raise InvalidParameterError(f"manifest {path}: {key} must be a number > 0, got {v!r}")
    return float(v)


def read_folder(folder: str | os.PathLike) -> MeshSet:
    """The mesh files directly in ``folder`` (sorted by name) with its manifest's settings
    (see the module docstring). Refuses a folder without meshes, a manifest naming a file
    that is not there, unknown keys and values out of range."""
    root = Path(folder)
    if not root.is_dir():
        raise InvalidParameterError(f"objects folder {folder} is not a folder")
    root = root.resolve()
    files = sorted(p for p in root.iterdir() if p.is_file() and p.suffix.lower() in _SUFFIXES)
    if not files:
        raise InvalidParameterError(f"objects folder {folder} holds no mesh file ({' '.join(_SUFFIXES)})")
    man, where = _manifest(root)
    defaults, per = man.get("defaults", {}), man.get("objects", {})
    names = {p.name for p in files}
    if set(per) - names:
        raise InvalidParameterError(f"manifest of {folder} names files not in the folder: {sorted(set(per) - names)}; "
                                    f"its meshes: {sorted(names)}")
    out = []
    for p in files:
        own = per.get(p.name, {})
        if not isinstance(own, dict):
            raise InvalidParameterError(f"manifest of {folder}, {p.name}: expected a table of settings")
        weight = {"mass", "density"} & set(own)  # a file's own mass or density replaces the defaults' both
        s = {**{k: v for k, v in defaults.items() if not (weight and k in ("mass", "density"))}, **own}
        if set(s) - _KEYS:
            raise InvalidParameterError(f"manifest of {folder}, {p.name}: unknown settings "
                                        f"{sorted(set(s) - _KEYS)}; valid: {sorted(_KEYS)}")
        if s.get("exclude", False) is True:
            continue
        if s.get("mass") is not None and s.get("density") is not None:
            raise InvalidParameterError(f"manifest of {folder}, {p.name}: give mass or density, not both")
        at = f"{where}, {p.name}"
        out.append(MeshEntry(p.stem, str(p), file_sha256(p), _positive(at, "scale", s.get("scale")) or 1.0,
                             _positive(at, "mass", s.get("mass")), _positive(at, "density", s.get("density")),
                             _positive(at, "friction", s.get("friction"))))
    if not out:
        raise InvalidParameterError(f"every mesh of {folder} is excluded by its manifest")
    return MeshSet(str(root), tuple(out))


def default_mass(mesh) -> tuple[float, str]:
    """(mass [kg], model) of a household object with ``mesh``'s shape [m] (see the
    module docstring): ``"filled"`` (closed, filling >= :data:`SOLID_SHARE` of its hull:
    :data:`FILL_DENSITY` x volume) or ``"shell"`` (:data:`SHELL_DENSITY` x area; a closed
    shell's area halved: its inner and outer faces are one wall)."""
    closed = bool(mesh.is_watertight) and mesh.volume > 0
    try:
        hull = float(mesh.convex_hull.volume)
    except Exception:
        hull = 0.0
    if closed and hull > 0 and mesh.volume >= SOLID_SHARE * hull:
        return float(FILL_DENSITY * mesh.volume), "filled"
    area = float(mesh.area) * (0.5 if closed else 1.0)
    if not area > 0:
        raise MeshError("the mesh has no surface area")
    return float(SHELL_DENSITY * area), "shell"
