"""Arbitrary meshes for simulation: reading OBJ/STL/PLY, checking them, and preparing
their collision model (convex parts and mass properties), bounded in time and cached.

MuJoCo collides meshes as their convex hulls, so a non-convex object must be split into
convex parts first. :func:`prepare_mesh` is the one entry point (``graspsim trial
--mesh``, mesh objects of scenes, the experiments); it

1. reads the file's raw arrays and refuses what cannot be simulated, one line each
   (:func:`check_mesh_arrays`): no triangles, NaN/inf or out-of-range vertices (trimesh
   would silently drop them), no extent, and sizes implausible in metres: wider than
   :data:`MAX_MESH_EXTENT` (millimetres or centimetres read as metres; ``--mesh-scale``)
   or smaller than :data:`MIN_MESH_EXTENT`;
2. splits the mesh into connected components: a convex, closed component is its own
   hull (the multi-body meshes of primitives need nothing more);
3. decomposes the rest with CoACD (Wei et al. 2022) after decimating it to at most
   ``max_faces`` faces (fast-simplification), in a separate process killed once it has
   used ``time_limit`` seconds of CPU (CoACD has no limit of its own: an open mesh or one
   of a few thousand faces can take many minutes). Closed components (watertight and
   consistently wound, as the file has them before zero-area slivers are dropped) go
   first and skip CoACD's manifold remeshing, which they do not need and which costs most
   of its time and thickens the shape (the duck: 46 s of CPU and 5.8 % of volume added
   with it, 7.6 s and 0.9 % without); open components follow, remeshed, with what is left
   of the limit; a component spanning no volume (a stray triangle) is dropped. CPU time,
   not wall time, so that the same mesh gets the same model on an idle and on a loaded
   machine; a wall-clock backstop (:data:`WALL_FACTOR` x the limit + :data:`WALL_SLACK`)
   ends a worker that a loaded machine starves, and that result is not cached;
4. if a group's process fails or runs out of time, falls back to the convex hull of each
   of its components, with a one-line warning (:attr:`PreparedMesh.warning`);
5. caches the result under :func:`default_cache_dir`, keyed by a hash of the file's
   vertex and face arrays, the scale and the settings, written atomically: a second
   run of the same mesh loads it (no decomposition, no decimation). A complete model
   serves every time limit at least the CPU time CoACD took for it (recorded with it):
   a model made without a limit is not handed to a call whose limit would have fallen
   back, so the model a call gets does not depend on what the cache holds; a fallback
   is kept apart, for the time limit that gave it.

Mass properties: a closed mesh's own volume, centre of mass and inertia; an open or
non-manifold mesh has no meaningful volume, so those of the union of its convex parts
(overlaps counted twice) stand in; :attr:`PreparedMesh.mass_from` says which.

The decomposition is deterministic (CoACD's seed, and a limit on CPU time, which load
does not change) for a given mesh, scale and settings; only a mesh whose decomposition
needs within a few per cent of ``time_limit`` CPU seconds could fall either way, and
only a machine so loaded that the wall-clock backstop ends the worker gives another
model (with a warning saying so, and not cached). :attr:`PreparedMesh.method` records
which model was made. On systems without ``/proc`` the worker's CPU time cannot be read
and the limit is wall-clock time.

Every caller in graspsim uses the default :class:`CoacdParams` -- ``trial --mesh``, a
user's folder of scene meshes and the meshes shipped for scenes alike: since the limit is
CPU time, the default gives the same model on an idle and a loaded machine, and on a faster or
a slower CPU so long as no mesh needs nearly the limit (a CPU is not a clock: one a third
slower spends a third more CPU seconds; the slowest shipped mesh that finishes took 8.7 s of
the 15 on the slower of two hosts measured, the three that fall back need minutes), and it
keeps a first use to seconds per mesh (without a limit CoACD took 10-50 minutes for the shipped Lego
brick, can and mug on a loaded machine). The price, measured on the shipped household set:
9 of its 12 meshes get CoACD's parts or are convex (the duck among them, since closed meshes
skip the remeshing), and the open parts of the Lego brick, the mug (its handle; its closed
body keeps its cavity) and the can exceed the 15 CPU seconds and are simulated as one hull
per connected component, with the warning; the random set's meshes are unions of convex
components and need no CoACD. ``time_limit=math.inf`` stays available to a caller
who wants CoACD's parts whatever they cost.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim._cache import user_cache
from graspsim.checks import Rule, check_fields
from graspsim.errors import DependencyNotInstalled, InvalidParameterError, MeshError

__all__ = ["CoacdParams", "PreparedMesh", "prepare_mesh", "surface_model", "check_mesh_path", "check_mesh_arrays",
           "load_mesh", "convex_parts", "default_cache_dir", "MAX_MESH_EXTENT", "MIN_MESH_EXTENT"]

#: CoACD's counts (faces, vertices, resolutions, search sizes): >= 1 as whole numbers.
_COUNT = Rule(lambda v: int(v) >= 1, ">= 1")

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")
#: The widest mesh accepted in metres (the clouds' limit, ``perception.prepare.MAX_EXTENT``).
MAX_MESH_EXTENT = 2.0
#: The smallest graspable object [m]: a mesh smaller than this is probably not in metres.
MIN_MESH_EXTENT = 0.005
#: Bumped when the preparation changes, so older cache entries are not reused.
PREP_VERSION = 3
_WORKER = Path(__file__).with_name("_coacd_worker.py")


#: the wall-clock backstop of the decomposition worker: WALL_FACTOR x its CPU limit +
#: WALL_SLACK seconds (a starved worker on a loaded machine; the result is not cached)
WALL_FACTOR = 4.0
WALL_SLACK = 10.0
_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _cpu_seconds(pid: int) -> float | None:
    """User + system CPU time [s] of process ``pid`` (all its threads), from /proc; None
    where /proc is not there (the caller then counts wall time)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / _TICK  # utime, stime (fields 14, 15)


@dataclass(frozen=True)
class CoacdParams:
    """Mesh preparation settings. threshold: CoACD's concavity tolerance (smaller = more
    parts); max_parts: cap on CoACD's convex hulls (-1 = none); preprocess_resolution,
    resolution, mcts_*: CoACD's manifold remeshing, sampling and tree search (60
    iterations, not CoACD's 150: the duck turned onto its resting face took 15.3-17.1 s of
    CPU with 150 and 9.8 s with 60, the parts' volume outside the mesh 1.3 % and 1.2 %); seed:
    CoACD's seed (reproducible parts); time_limit [s]: CPU seconds the decimation and
    decomposition worker may use before the hull fallback is taken (inf: none; see the
    module docstring for the wall-clock backstop); max_faces: meshes
    with more faces are decimated to this many before CoACD; max_hull_vertices: a convex
    part with more vertices is thinned on a grid (MuJoCo hulls of 100k vertices are slow)."""

    threshold: float = 0.05
    max_parts: int = 16
    preprocess_resolution: int = 50  # grid resolution of the manifold remeshing (CoACD: 20-100)
    seed: int = 0
    resolution: int = 2000  # surface samples per Hausdorff-distance (concavity) estimate (CoACD: 1e3-1e4)
    mcts_iterations: int = 60  # tree-search iterations per cut (CoACD: 60-2000)
    mcts_nodes: int = 20  # candidate cutting planes tried at each node of the search tree (CoACD: 10-40)
    mcts_max_depth: int = 3  # how many cuts ahead the search looks (CoACD: 2-7)
    time_limit: float = 15.0
    max_faces: int = 20_000
    max_hull_vertices: int = 1024

    def __post_init__(self) -> None:
        if not 0.01 <= self.threshold <= 1.0:
            raise InvalidParameterError(f"CoACD threshold must be in [0.01, 1], got {self.threshold!r}")
        if self.max_parts == 0 or self.max_parts < -1:
            raise InvalidParameterError(f"max_parts must be -1 or >= 1, got {self.max_parts!r}")
        if not self.time_limit >= 0:  # inf: no limit (a caller's explicit choice)
            raise InvalidParameterError(f"time_limit must be >= 0 s (inf: none), got {self.time_limit!r}")
        check_fields(self, _COUNT, "max_faces", "max_hull_vertices", "resolution", "preprocess_resolution",
                     "mcts_iterations", "mcts_nodes", "mcts_max_depth")


@dataclass(frozen=True, eq=False)
class PreparedMesh:
    """A mesh ready for simulation, in the mesh file's frame (scaled to metres).

    parts: convex vertex arrays (V_i, 3) [m]; method: "convex" (one hull), "components"
    (each component convex: its hulls), "coacd" (CoACD's parts for the non-convex
    components), "hull" (the fallback: one hull per component) or "surface"
    (:func:`surface_model`: a thin prism per face); volume [m^3], com (3,)
    [m], unit_inertia (3, 3) [m^2] (inertia about the COM per kg); mass_from: "mesh"
    (closed mesh) or "parts" (the union of the parts stands in); surface: the mesh
    (trimesh); faces: the file's face count; watertight; warning: the fallback's reason,
    or None; key: the cache key; from_cache; seconds: the time preparation took; source:
    the file (or "<trimesh>"); scale: the scale applied to the file's coordinates;
    decompose_cpu: the CPU seconds CoACD took for this model (0: none ran, or unknown)."""

    parts: tuple[np.ndarray, ...]
    method: str
    volume: float
    com: np.ndarray
    unit_inertia: np.ndarray
    mass_from: str
    surface: object = field(repr=False)
    faces: int = 0
    watertight: bool = False
    warning: str | None = None
    key: str = ""
    from_cache: bool = False
    seconds: float = 0.0
    source: str = ""
    scale: float = 1.0
    decompose_cpu: float = 0.0

    def describe(self) -> dict:
        """What was simulated, for results and ``--json``."""
        return {"file": self.source, "scale": self.scale, "faces": self.faces, "watertight": self.watertight,
                "method": self.method, "parts": len(self.parts), "mass_from": self.mass_from,
                "volume_cm3": round(self.volume * 1e6, 4), "from_cache": self.from_cache,
                "seconds": round(self.seconds, 3), "warning": self.warning}


def default_cache_dir() -> Path:
    """``$GRASPSIM_CACHE_DIR/coacd``, else ``$XDG_CACHE_HOME/graspsim/coacd``, else
    ``~/.cache/graspsim/coacd`` (:func:`graspsim._cache.user_cache`)."""
    return user_cache("coacd")


def check_mesh_path(path: str | os.PathLike) -> Path:
    """``path`` as a Path if it names a mesh file of a supported type, else :class:`MeshError`
    (commands call it before their work; :func:`load_mesh` before reading)."""
    path = Path(path)
    try:
        is_file = path.is_file()
    except (OSError, ValueError) as err:  # a name too long, a NUL byte
        raise MeshError(f"cannot read mesh file {path}: {getattr(err, 'strerror', None) or err}") from err
    if not is_file:
        raise MeshError(f"mesh file {path} does not exist")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"mesh file {path} has an unsupported type; use one of {MESH_SUFFIXES}")
    return path


def _check_scale(scale: float) -> float:
    try:
        s = float(scale)
    except (TypeError, ValueError):
        s = float("nan")
    if not (np.isfinite(s) and s > 0):
        raise MeshError(f"mesh scale must be a finite number > 0 (e.g. --mesh-scale 0.001 for millimetres), "
                        f"got {scale!r}")
    return s


def check_mesh_arrays(vertices, faces, *, scale: float = 1.0, name: str = "the mesh",
                      scale_option: str = "--mesh-scale") -> None:
    """Raise :class:`MeshError` (one line: what is wrong, what is valid) unless the raw
    arrays (V, 3) and (F, 3), times ``scale``, are a mesh that can be simulated: at least
    one triangle, finite vertices, face indices in range, some extent in every
    direction, and between :data:`MIN_MESH_EXTENT` and :data:`MAX_MESH_EXTENT` across.
    ``scale_option``: how the caller's user sets the scale, named in the hints
    (``graspsim trial``'s ``--mesh-scale``; a folder manifest's ``scale``)."""
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise MeshError(f"{name} holds no triangles")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise MeshError(f"{name} has {int(bad.sum())} vertices with NaN/inf coordinates (the first is vertex "
                        f"{int(np.flatnonzero(bad)[0])}); every coordinate must be a finite number")
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"{name} has faces that name vertices outside 0..{len(v) - 1}")
    mask = np.zeros(len(v), bool)
    mask[f.ravel()] = True  # the vertices faces use (np.unique of 1 M indices takes seconds)
    used = v[mask].astype(np.float64) * scale
    width = np.ptp(used, axis=0)
    big = float(width.max())
    if big > MAX_MESH_EXTENT:
        hints = [f"{u} ({big / k:.4g} m with {scale_option} {scale / k:g})"
                 for u, k in (("millimetres", 1000.0), ("centimetres", 100.0)) if big / k <= MAX_MESH_EXTENT]
        hint = ("is it in " + " or ".join(hints) + "?") if hints else f"convert it to metres with {scale_option} S"
        raise MeshError(f"{name} is {big:.4g} m across, implausible for a graspable object (at most "
                        f"{MAX_MESH_EXTENT:g} m); {hint}")
    if big < MIN_MESH_EXTENT:
        raise MeshError(f"{name} is only {big * 1000:.3g} mm across, smaller than any graspable object (at least "
                        f"{MIN_MESH_EXTENT * 1000:g} mm); is it in another unit? scale it with {scale_option} S "
                        "(S multiplies the file's coordinates to give metres)")
    if float(width.min()) < 1e-6 * big or not _some_area(v, f, 1e-12 * big * big / scale**2):
        raise MeshError(f"{name} is flat or degenerate (its extents are {np.round(width * 1000, 3).tolist()} mm); "
                        "a solid needs some thickness in every direction")


def _some_area(v: np.ndarray, f: np.ndarray, floor: float) -> bool:
    """Whether some triangle has an area above ``floor`` (looked for a block at a time:
    a usable mesh answers in its first block)."""
    for i in range(0, len(f), 4096):
        c = v[f[i:i + 4096]].astype(np.float64)
        if (np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1) > 2 * floor).any():
            return True
    return False


def _read_arrays(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The file's vertices and faces as stored (``process=False``: trimesh would drop
    NaN vertices and merge duplicates)."""
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as err:  # trimesh raises many kinds of errors on bad files
        raise MeshError(f"cannot read mesh {path}: {err}") from err
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"mesh file {path} holds no triangles")
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


def _clean(vertices: np.ndarray, faces: np.ndarray, scale: float, name: str):
    """The checked raw arrays as a processed trimesh [m] (vertices merged, degenerate
    and duplicate faces dropped)."""
    import trimesh

    mesh = trimesh.Trimesh(vertices * scale if scale != 1.0 else vertices, faces, process=True)
    # closed before its slivers go: dropping a zero-area face opens the surface in topology only
    closed = _closed(mesh)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise MeshError(f"{name} holds only degenerate triangles (no triangle has an area)")
    mesh.metadata["closed"] = closed
    return mesh


def load_mesh(path: str | os.PathLike, *, scale: float = 1.0, scale_option: str = "--mesh-scale"):
    """Read a triangle mesh (OBJ, STL, PLY, ...) as one ``trimesh.Trimesh`` [m].

    Raises :class:`MeshError` if the file is missing or unreadable, or fails
    :func:`check_mesh_arrays` (no triangles, NaN vertices, implausible size in metres;
    its hints name ``scale_option``).
    """
    path = check_mesh_path(path)
    scale = _check_scale(scale)
    vertices, faces = _read_arrays(path)
    check_mesh_arrays(vertices, faces, scale=scale, name=f"mesh {path.name}", scale_option=scale_option)
    return _clean(vertices, faces, scale, f"mesh {path.name}")


def _key(vertices: np.ndarray, faces: np.ndarray, scale: float, params: CoacdParams) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    settings = {k: v for k, v in asdict(params).items() if k != "time_limit"}
    h.update(json.dumps({"v": PREP_VERSION, "scale": scale, "params": settings}, sort_keys=True).encode())
    return h.hexdigest()[:32]


def _grid_first(points: np.ndarray, cells: int) -> np.ndarray:
    """One point per cell of a grid of ``cells`` across the widest extent (the first in order)."""
    pitch = float(np.ptp(points, axis=0).max()) / cells
    keys = np.floor((points - points.min(axis=0)) / pitch).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return points[np.sort(first)]


def _thin(points: np.ndarray, max_vertices: int) -> np.ndarray:
    """The hull vertices of ``points``, thinned on a grid (one per cell, the first in
    order; 256 cells across, then halved) until at most ``max_vertices`` remain;
    deterministic. The grid goes first: Qhull is slow on 100k co-circular points."""
    from scipy.spatial import ConvexHull

    cells = 256
    if len(points) > max_vertices:
        points = _grid_first(points, cells)
    hull = points[ConvexHull(points).vertices]
    while len(hull) > max_vertices and cells >= 8:
        cells //= 2
        kept = _grid_first(hull, cells)
        hull = kept[ConvexHull(kept).vertices]
    return np.ascontiguousarray(hull, dtype=np.float64)


def _hull_part(points: np.ndarray, max_vertices: int) -> np.ndarray | None:
    """One convex part: the thinned hull vertices of ``points``, None when they span no volume."""
    from scipy.spatial import QhullError

    v = np.asarray(points, np.float64)
    if len(v) < 4:
        return None
    try:
        return _thin(v, max_vertices)
    except (QhullError, ValueError):  # flat or collinear: no volume
        return None


def _components(mesh):
    """The mesh's connected components, each a trimesh (only one: the mesh itself)."""
    comps = mesh.split(only_watertight=False)
    return list(comps) if len(comps) > 1 else [mesh]


def _decompose(mesh, params: CoacdParams, progress, *, closed: bool,
               limit: float) -> tuple[list[np.ndarray] | None, str | None, bool, float]:
    """(CoACD's parts of ``mesh`` from the bounded worker, or None; why it gave none;
    whether the outcome depended on the machine's load: the wall-clock backstop ended it;
    the worker's CPU seconds, last read while it ran). closed: the mesh is closed and
    consistently wound (CoACD's manifold remeshing skipped); limit: the CPU seconds this
    call may use (what is left of ``params.time_limit``)."""
    try:
        import coacd  # noqa: F401
    except ImportError as err:
        raise DependencyNotInstalled("convex decomposition of meshes needs CoACD: pip install coacd") from err
    worker = {k: getattr(params, k) for k in ("threshold", "max_parts", "preprocess_resolution", "resolution",
                                              "mcts_iterations", "mcts_nodes", "mcts_max_depth", "seed",
                                              "max_faces")}
    worker["closed"] = bool(closed)
    with tempfile.TemporaryDirectory(prefix="graspsim-coacd-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, vertices=np.asarray(mesh.vertices, np.float64), faces=np.asarray(mesh.faces, np.int64),
                 params=json.dumps(worker))
        with open(Path(tmp) / "err.txt", "w+b") as err_file:
            proc = subprocess.Popen([sys.executable, str(_WORKER), str(src), str(dst)], stdout=subprocess.PIPE,
                                    stderr=err_file, env={**os.environ, "PYTHONWARNINGS": "ignore"})
            os.set_blocking(proc.stdout.fileno(), False)
            stage, said, used = "decomposing", b"", 0.0
            started = time.monotonic()
            backstop = started + WALL_FACTOR * limit + WALL_SLACK
            try:
                while proc.poll() is None:
                    cpu = _cpu_seconds(proc.pid)
                    spent = time.monotonic() - started if cpu is None else cpu
                    used = max(used, spent)
                    if spent > limit:
                        return None, (f"decomposition did not finish within its limit of {params.time_limit:g} s"
                                      f" of {'wall' if cpu is None else 'CPU'} time"), False, used
                    if time.monotonic() > backstop:
                        return None, (f"decomposition was starved of CPU (machine load) past "
                                      f"{backstop - started:g} s of wall time; not cached: run it again"), True, used
                    try:
                        said += os.read(proc.stdout.fileno(), 65536)
                    except BlockingIOError:
                        pass
                    stages = [ln[6:] for ln in said.decode(errors="replace").splitlines() if ln.startswith("stage ")]
                    stage = stages[-1] if stages else stage
                    if progress is not None:
                        fraction = spent / limit if np.isfinite(limit) else 0.0
                        progress(stage, min(1.0, max(0.0, fraction)))
                    time.sleep(0.05)
            finally:
                if proc.poll() is None:
                    proc.kill()
                proc.wait()
                proc.stdout.close()
            err_file.seek(0)
            err = err_file.read().decode(errors="replace")
        if proc.returncode != 0 or not dst.is_file():
            last = (err.strip().splitlines() or [f"exit status {proc.returncode}"])[-1]
            return None, f"CoACD failed ({last[:200]})", False, used
        with np.load(dst) as z:
            parts = [z[f"part{i}"] for i in range(int(z["count"]))]
    parts = [p for p in (_hull_part(p, params.max_hull_vertices) for p in parts) if p is not None]
    return (parts, None, False, used) if parts else (None, "CoACD returned no convex part with a volume", False, used)


def _mass_properties(mesh, parts: list[np.ndarray]) -> tuple[float, np.ndarray, np.ndarray, str]:
    """(volume, com, inertia per unit mass, "mesh" | "parts") of the prepared model."""
    import trimesh

    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0:
        return float(mesh.volume), np.asarray(mesh.center_mass, float), mesh.moment_inertia / mesh.volume, "mesh"
    hulls = [trimesh.convex.convex_hull(p) for p in parts]
    vols = np.array([h.volume for h in hulls])
    if not vols.sum() > 0:
        raise MeshError("the mesh encloses no volume")
    volume = float(vols.sum())
    com = sum(v * h.center_mass for v, h in zip(vols, hulls)) / volume
    unit = np.zeros((3, 3))
    for v, h in zip(vols, hulls):
        d = h.center_mass - com
        unit += h.moment_inertia + v * (d @ d * np.eye(3) - np.outer(d, d))
    return volume, np.asarray(com, float), unit / volume, "parts"


def _closed(component) -> bool:
    """Whether a component is a closed, consistently wound surface enclosing a volume (what
    CoACD can decompose without remeshing it first)."""
    return bool(component.is_watertight and component.is_winding_consistent and component.volume > 0)


def _build(mesh, params: CoacdParams, name: str, progress) -> tuple[list[np.ndarray], str, str | None, bool, float]:
    """(parts, method, warning, cacheable, CoACD's CPU seconds) for the cleaned mesh (steps
    2-4 of the module docstring); not cacheable: the machine's load decided the model."""
    if mesh.is_convex:
        return [_thin(np.asarray(mesh.vertices, float), params.max_hull_vertices)], "convex", None, True, 0.0
    comps = _components(mesh)
    convex = [c for c in comps if c.is_watertight and c.is_convex]
    rest = [c for c in comps if not (c.is_watertight and c.is_convex)]
    parts = [p for p in (_hull_part(c.vertices, params.max_hull_vertices) for c in convex) if p is not None]
    if not rest:
        return parts, "components", None, True, 0.0
    import trimesh

    # closed components first (fast: no remeshing), then open ones with what is left of the limit;
    # an open component spanning no volume (a stray triangle) adds nothing to either
    is_closed = [bool(mesh.metadata.get("closed")) or _closed(c) for c in rest]
    closed = [c for c, k in zip(rest, is_closed) if k]
    opened = [c for c, k in zip(rest, is_closed) if not k and _hull_part(c.vertices, 8) is not None]
    groups = [(g, flag) for g, flag in ((closed, True), (opened, False)) if g]
    used, filled, whys, by_load = 0.0, [], [], False
    for group, closed in groups:
        remainder = group[0] if len(group) == 1 else trimesh.util.concatenate(group)
        decomposed, why, starved, spent = _decompose(remainder, params, progress, closed=closed,
                                                     limit=max(0.0, params.time_limit - used))
        used, by_load = used + spent, by_load or starved
        if decomposed is not None:
            parts += decomposed
            continue
        filled += group
        whys.append(why)
        parts += [p for p in (_hull_part(c.vertices, params.max_hull_vertices) for c in group) if p is not None]
    if not filled:
        return parts, "coacd", None, True, used
    if not parts:
        raise MeshError(f"{name} has no part with a volume (flat or degenerate)")
    what = ("its convex hull" if len(comps) == 1 else
            f"the convex hulls of {'its' if len(filled) == len(comps) else f'{len(filled)} of its'} "
            f"{len(comps)} components")
    warning = (f"{name}: {whys[0]}; simulating {what} instead (concave regions are filled: for the mesh's own "
               "surface use `graspsim trial --mesh-model surface`, or raise CoacdParams.time_limit)")
    return parts, "hull", warning, not by_load, used


def _cache_read(file: Path) -> dict | None:
    import trimesh

    if not file.is_file():
        return None
    try:
        with np.load(file) as z:
            info = json.loads(str(z["info"]))
            parts = tuple(z[f"part{i}"] for i in range(int(z["count"])))
            surface = trimesh.Trimesh(z["surface_vertices"], z["surface_faces"], process=False)
            return {"parts": parts, "com": z["com"], "unit_inertia": z["unit_inertia"], "surface": surface, **info}
    except (OSError, KeyError, ValueError) as err:
        log.warning("ignoring unreadable mesh cache file %s: %s", file, err)
        return None


def _cache_write(file: Path, prepared: PreparedMesh) -> None:
    info = {"method": prepared.method, "volume": prepared.volume, "mass_from": prepared.mass_from,
            "warning": prepared.warning, "watertight": prepared.watertight,
            "decompose_cpu": prepared.decompose_cpu}
    try:
        file.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(file, error=MeshError) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, count=len(prepared.parts), com=prepared.com, unit_inertia=prepared.unit_inertia,
                         surface_vertices=np.asarray(prepared.surface.vertices, np.float64),
                         surface_faces=np.asarray(prepared.surface.faces, np.int64),
                         info=json.dumps(info), **{f"part{i}": p for i, p in enumerate(prepared.parts)})
    except (OSError, MeshError) as err:
        log.warning("cannot cache the prepared mesh in %s: %s", file.parent, err)


def _source_arrays(source, scale: float) -> tuple[str, str, np.ndarray, np.ndarray]:
    """(name for messages, label, vertices, faces) of a mesh file or a ``trimesh.Trimesh``
    (its arrays as they are), checked by :func:`check_mesh_arrays` at ``scale``."""
    import trimesh

    if isinstance(source, trimesh.Trimesh):
        name, label = "the mesh", "<trimesh>"
        vertices, faces = np.asarray(source.vertices, np.float64), np.asarray(source.faces, np.int64)
    else:
        path = check_mesh_path(source)
        name, label = f"mesh {path.name}", str(path)
        vertices, faces = _read_arrays(path)
    check_mesh_arrays(vertices, faces, scale=scale, name=name)
    return name, label, vertices, faces


def prepare_mesh(source, *, scale: float = 1.0, params: CoacdParams = CoacdParams(),
                 cache_dir: str | os.PathLike | None = None,
                 progress: Callable[[str, float], None] | None = None) -> PreparedMesh:
    """The collision model of a mesh: convex parts and mass properties (module docstring).

    source: a mesh file (OBJ, STL, PLY, OFF, GLB) or a ``trimesh.Trimesh`` (its arrays as
    they are); scale: multiplies the coordinates (0.001 for a file in millimetres);
    cache_dir: where prepared models are kept (default :func:`default_cache_dir`);
    progress(stage, fraction): called while decimation/decomposition runs (fraction of
    the time limit spent). Raises :class:`MeshError` on a mesh that cannot be simulated.
    The fallback's warning is logged once per call and kept in ``warning``.
    """

    t0 = time.perf_counter()
    scale = _check_scale(scale)
    name, label, vertices, faces = _source_arrays(source, scale)
    key = _key(vertices, faces, scale, params)
    # a complete model serves any time limit at least the CPU time it took (recorded since; older
    # entries serve every limit); a fallback only the (CPU-time) limit that gave it.
    # "cpu" in its name: fallbacks cached while the limit was wall-clock time (a loaded machine's:
    # the shipped bread fell back there, CoACD parts it in 3 s of CPU) are not reused
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    file, fallback = folder / f"{key}.npz", folder / f"{key}.hull-cpu{params.time_limit:g}s.npz"
    complete = _cache_read(file)
    if complete is not None and float(complete.get("decompose_cpu", 0.0)) > params.time_limit:
        complete = None  # made with more CPU time than this limit allows: this limit gets the fallback
    cached = complete or _cache_read(fallback)
    if cached is not None:
        out = PreparedMesh(cached["parts"], cached["method"], float(cached["volume"]), np.asarray(cached["com"]),
                           np.asarray(cached["unit_inertia"]), cached["mass_from"], cached["surface"], len(faces),
                           bool(cached["watertight"]), cached["warning"], key, True, time.perf_counter() - t0, label,
                           scale, float(cached.get("decompose_cpu", 0.0)))
    else:
        mesh = _clean(vertices, faces, scale, name)
        parts, method, warning, cacheable, used = _build(mesh, params, name, progress)
        volume, com, unit, mass_from = _mass_properties(mesh, parts)
        out = PreparedMesh(tuple(parts), method, volume, com, unit, mass_from, mesh, len(faces),
                           bool(mesh.is_watertight), warning, key, False, time.perf_counter() - t0, label, scale,
                           used if method == "coacd" else 0.0)
        if cacheable:  # a fallback the machine's load made is not pinned
            _cache_write(fallback if method == "hull" else file, out)
        log.info("prepared %s: %d convex parts (%s) in %.1f s", name, len(parts), method, out.seconds)
    if out.warning:
        log.warning("%s%s", out.warning, " (cached)" if out.from_cache else "")
    return out


#: the most faces :func:`surface_model` takes (one MuJoCo geom each: trials slow down with them)
MAX_SURFACE_FACES = 10_000


def surface_model(source, *, scale: float = 1.0, thickness: float = 0.0015,
                  max_faces: int = MAX_SURFACE_FACES) -> PreparedMesh:
    """The mesh's own surface as its collision model: each triangle extruded ``thickness``
    [m] inwards along its normal into a thin convex prism (a closed mesh; an open one
    is extruded half each way), so concavities, cavities and thin walls stay as the mesh
    has them -- where CoACD's few parts (``prepare_mesh``) thicken a wall by millimetres
    or its fallback fills a mug's cavity. The price is one geom per face: trials run
    slower than with a dozen parts (about 8x for a 2334-face mug in E14), so this model
    is for checking outcomes against the exact geometry, not for every run. Mass
    properties: those of the closed mesh (else of the prisms). Not cached (it takes
    milliseconds). Raises :class:`MeshError` on a mesh that cannot be simulated or has
    more than ``max_faces`` faces (decimate it first)."""

    t0 = time.perf_counter()
    scale = _check_scale(scale)
    if not (math.isfinite(thickness) and 0 < thickness <= 0.01):
        raise InvalidParameterError(f"surface thickness must be in (0, 0.01] m, got {thickness!r}")
    name, label, vertices, faces = _source_arrays(source, scale)
    mesh = _clean(vertices, faces, scale, name)
    if len(mesh.faces) > max_faces:
        raise MeshError(f"{name} has {len(mesh.faces)} faces; a surface model takes at most {max_faces} "
                        "(one geom each): decimate the mesh first")
    closed = bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)
    tri = np.asarray(mesh.triangles, float)
    normal = np.asarray(mesh.face_normals, float)[:, None, :]
    inner, outer = (tri - thickness * normal, tri) if closed else (tri - thickness / 2 * normal,
                                                                    tri + thickness / 2 * normal)
    parts = [np.concatenate([a, b]) for a, b in zip(outer, inner)]
    volume, com, unit, mass_from = _mass_properties(mesh, parts)
    out = PreparedMesh(tuple(parts), "surface", volume, com, unit, mass_from, mesh, len(faces), closed, None,
                       "", False, time.perf_counter() - t0, label, scale)
    log.info("prepared %s: its surface as %d prisms of %.1f mm", name, len(parts), 1000 * thickness)
    return out


def convex_parts(mesh, params: CoacdParams = CoacdParams(), *,
                 cache_dir: str | os.PathLike | None = None) -> list[np.ndarray]:
    """Convex parts of the trimesh ``mesh`` as a list of vertex arrays (V_i, 3) in the
    mesh's frame: ``prepare_mesh(mesh, ...).parts``."""
    return list(prepare_mesh(mesh, params=params, cache_dir=cache_dir).parts)
