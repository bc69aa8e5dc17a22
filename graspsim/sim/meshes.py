"""Arbitrary meshes for simulation: reading OBJ/STL/PLY and CoACD convex decomposition,
cached on disk.

MuJoCo collides meshes as their convex hulls, so a non-convex object must be split into
convex parts first (CoACD, Wei et al. 2022). Decomposition takes seconds to minutes, so
the parts are cached under ``cache_dir`` (default ``$GRASPSIM_CACHE_DIR/coacd`` or
``~/.cache/graspsim/coacd``), keyed by a hash of the mesh's vertices and faces and of the
CoACD parameters: the same mesh and parameters always give the same parts.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim.errors import DependencyNotInstalled, InvalidParameterError, MeshError

__all__ = ["CoacdParams", "check_mesh_path", "load_mesh", "convex_parts", "default_cache_dir"]

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")


@dataclass(frozen=True)
class CoacdParams:
    """CoACD settings. threshold: concavity tolerance (smaller = more parts);
    max_parts: cap on the number of convex hulls (-1 = none); seed: CoACD's seed, so the
    decomposition is reproducible."""

    threshold: float = 0.05
    max_parts: int = 16
    preprocess_resolution: int = 50
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0.01 <= self.threshold <= 1.0:
            raise InvalidParameterError(f"CoACD threshold must be in [0.01, 1], got {self.threshold!r}")
        if self.max_parts == 0 or self.max_parts < -1:
            raise InvalidParameterError(f"max_parts must be -1 or >= 1, got {self.max_parts!r}")


def default_cache_dir() -> Path:
    root = os.environ.get("GRASPSIM_CACHE_DIR")
    base = Path(root) if root else Path.home() / ".cache" / "graspsim"
    return base / "coacd"


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


def load_mesh(path: str | os.PathLike, *, scale: float = 1.0):
    """Read a triangle mesh (OBJ, STL, PLY, ...) as one ``trimesh.Trimesh`` [m].

    Raises :class:`MeshError` if the file is missing, unreadable or has no triangles.
    """
    import trimesh

    path = check_mesh_path(path)
    if not (np.isfinite(scale) and scale > 0):
        raise MeshError(f"mesh scale must be > 0, got {scale!r}")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as err:  # trimesh raises many kinds of errors on bad files
        raise MeshError(f"cannot read mesh {path}: {err}") from err
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"mesh file {path} holds no triangles")
    if not np.all(np.isfinite(mesh.vertices)):
        raise MeshError(f"mesh file {path} has non-finite vertices")
    if scale != 1.0:
        mesh.apply_scale(scale)
    return mesh


def _key(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    h.update(json.dumps(asdict(params), sort_keys=True).encode())
    return h.hexdigest()[:32]


def convex_parts(mesh, params: CoacdParams = CoacdParams(), *,
                 cache_dir: str | os.PathLike | None = None) -> list[np.ndarray]:
    """Convex parts of ``mesh`` as a list of vertex arrays (V_i, 3) in the mesh's frame.

    A convex mesh is returned as its own hull without running CoACD. Results are cached
    in ``cache_dir`` (see the module docstring); pass the same folder to reuse them.
    """
    if mesh.is_convex:
        return [np.asarray(mesh.convex_hull.vertices, dtype=float)]
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = _key(mesh.vertices, mesh.faces, params)
    file = cache / f"{key}.npz"
    if file.is_file():
        try:
            with np.load(file) as z:
                parts = [z[f"part{i}"] for i in range(int(z["count"]))]
            log.debug("CoACD cache hit %s (%d parts)", file, len(parts))
            return parts
        except (OSError, KeyError, ValueError) as err:
            log.warning("ignoring unreadable CoACD cache file %s: %s", file, err)
    try:
        import coacd
    except ImportError as err:
        raise DependencyNotInstalled(
            "convex decomposition of meshes needs CoACD: pip install coacd") from err
    coacd.set_log_level("error")
    try:
        result = coacd.run_coacd(
            coacd.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32)),
            threshold=params.threshold, max_convex_hull=params.max_parts,
            preprocess_resolution=params.preprocess_resolution, seed=params.seed,
        )
    except Exception as err:
        raise MeshError(f"CoACD failed to decompose the mesh: {err}") from err
    parts = [np.asarray(v, dtype=float) for v, _ in result if len(v) >= 4]
    if not parts:
        raise MeshError("CoACD returned no convex part with a volume")
    log.info("CoACD split a %d-face mesh into %d convex parts", len(mesh.faces), len(parts))
    try:
        cache.mkdir(parents=True, exist_ok=True)
        with atomic_path(file, error=MeshError) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, count=len(parts), **{f"part{i}": p for i, p in enumerate(parts)})
    except (OSError, MeshError) as err:
        log.warning("cannot cache CoACD parts in %s: %s", cache, err)
    return parts
