"""The full-scale (FS) map database: a folder of map files plus an index.

Maps are keyed by primitive, dimensions, gripper and generation settings; missing
entries are built on demand. :meth:`MapDatabase.match` answers the paper's
known / familiar question (section 2.4) with the one rule of :mod:`graspsim.maps.match`
and the database's one tolerance ``tol`` (relative: 3 %, ``match.KNOWN_TOL``).

Layout::

    ROOT/index.json                     one record per stored map (written atomically)
    ROOT/<primitive>/<key>.h5           the maps (written atomically)

The default root is ``$GRASPSIM_DB`` or ``~/.cache/graspsim/db``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_write_text
from graspsim.errors import GraspsimError, MapDatabaseError, MapFileError
from graspsim.grades.paper import QualityModel
from graspsim.grippers import gripper_key
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.io import load_map, save_map
from graspsim.maps.map_config import MapConfig
from graspsim.maps.match import KNOWN_TOL, MatchDecision, match_entries
from graspsim.maps.validate import validate_map
from graspsim.primitives import Box, Cone, Cylinder, HalfToroid, Primitive, Sphere, make_primitive, primitive_from_dict

__all__ = ["MapDatabase", "PAPER_SHAPES", "default_root", "size_grid", "index_record", "BUILD_PROGRESS"]

log = logging.getLogger(__name__)

#: How a map the database builds without being given a ``progress`` callback (a
#: primitive the planner found no stored map for; ``build`` in this process) reports
#: progress: a callable ``(shape) -> context manager`` yielding a fraction callback
#: ``(float in [0, 1]) -> None``; None: silently. The command line sets one that draws a
#: progress bar on a terminal (quiet with --json); the library itself draws nothing.
BUILD_PROGRESS: ContextVar[Callable | None] = ContextVar("graspsim_build_progress", default=None)

# The five primitives of the paper's database (section 3.1). The paper gives only the
# cylinder's size (r = 2 cm, h = 20 cm); the others are chosen to be graspable by the
# HGPL-25-60 (chords up to 11 cm) and of similar scale: a 6 cm cube, a 3.5 cm ball, a
# cup-like frustum and a handle-sized half-toroid.
PAPER_SHAPES: dict[str, Primitive] = {
    "box": Box(0.06, 0.06, 0.06),
    "cylinder": Cylinder(0.02, 0.20),
    "sphere": Sphere(0.035),
    "cone": Cone(0.04, 0.02, 0.10),
    "half_toroid": HalfToroid(0.04, 0.01),
}


def default_root() -> Path:
    return Path(os.environ.get("GRASPSIM_DB", Path.home() / ".cache" / "graspsim" / "db"))


def size_grid(shape: Primitive, scales: Iterable[float]) -> list[Primitive]:
    """Copies of ``shape`` with every dimension multiplied by each scale factor."""
    out = []
    for s in scales:
        if not s > 0:
            raise MapDatabaseError(f"size scale factors must be > 0, got {s!r}")
        out.append(shape.with_dims(**{k: v * s for k, v in shape.dims.items()}))
    return out


@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive advisory lock on ``path`` (POSIX flock; a no-op where unavailable)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _valid_record(entry) -> bool:
    """An index record a lookup may use: a dict naming a possible shape, its file and
    a grasp count (anything else is skipped with a warning, and ``db check`` reports it)."""
    try:
        if not isinstance(entry, dict):
            raise TypeError(f"not a record: {entry!r}")
        for k in ("key", "file"):
            if not isinstance(entry.get(k), str):
                raise TypeError(f"{k} {entry.get(k)!r} is not a string")
        n = entry.get("accepted", 0)
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            raise TypeError(f"accepted {n!r} is not a count")
        primitive_from_dict(entry)
    except (GraspsimError, KeyError, TypeError, ValueError) as err:
        log.warning("database record %s skipped (%s); `graspsim db check --repair` removes it",
                    entry.get("key") if isinstance(entry, dict) else "?", err)
        return False
    return True


def _digest(obj) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:10]


#: Maps the run-time cache of a database holds at most (:meth:`MapDatabase.load_entry`).
CACHE_MAPS = 64
#: Bytes of map columns the run-time cache holds at most: a scene's parts draw on a few
#: dozen stored maps (E10's household-tuning frames on 20, about 160 MB), which a cache of
#: 8 maps loaded again and again (a read and a new scaling set-up each time).
CACHE_BYTES = 512 * 2**20


def map_bytes(gmap: GraspabilityMap) -> int:
    """Bytes of a map's columns (what it holds in memory, its metadata aside)."""
    return int(sum(v.nbytes for v in gmap.columns().values()))


class MapDatabase:
    """FS maps on disk for one gripper, quality model and generation config. The folder
    is made if missing; with ``create=False`` (reading or checking a database) a missing
    folder is a :class:`~graspsim.errors.MapDatabaseError` instead. The maps planning
    reads (:meth:`load_entry`) stay in memory, the least recently used leaving first
    once more than ``cache_size`` maps or ``cache_bytes`` bytes are held (0: none kept)."""

    def __init__(self, root: str | os.PathLike | None = None, *,
                 gripper: GripperSpec = HGPL_25_60_A, quality: QualityModel | None = None,
                 config: MapConfig | None = None, tol: float = KNOWN_TOL, cache_size: int = CACHE_MAPS,
                 cache_bytes: int = CACHE_BYTES, create: bool = True):
        self.root = Path(root) if root is not None else default_root()
        self.gripper = gripper
        self.quality = quality or QualityModel()
        self.config = config or MapConfig()
        self.tol = float(tol)
        self.cache_size = int(cache_size)
        self.cache_bytes = int(cache_bytes)
        self._cache: OrderedDict = OrderedDict()  # key -> (map, its bytes)
        self._cached_bytes = 0
        self._valid_of: tuple[bytes, list[int]] | None = None  # the index's bytes, its usable records
        if not create:  # read or check a database: one that is not there is an error, not made
            try:
                there = self.root.is_dir()
            except (OSError, ValueError) as err:  # ValueError: a NUL byte in the path
                raise MapDatabaseError(f"cannot read map database folder {self.root}: {err}") from err
            if not there:
                raise MapDatabaseError(
                    f"no map database at {self.root}: " + ("it is not a folder" if self.root.exists() else
                                                            "the folder does not exist")
                    + " (valid: a folder made by 'graspsim db build'; default $GRASPSIM_DB or ~/.cache/graspsim/db)")
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except (OSError, ValueError) as err:  # ValueError: a NUL byte in the path
            raise MapDatabaseError(f"cannot create map database folder {self.root}: {err}") from err
        # a model file's gripper by its content, not its path: a copy elsewhere finds the same maps
        self._settings = _digest({"gripper": gripper_key(gripper), "quality": self.quality.to_dict(),
                                  "config": self.config.to_dict()})

    def __getstate__(self) -> dict:
        """Pickled (sent to a worker process) without the maps it has loaded: a database
        is its folder and settings; the receiver loads what it needs."""
        return {**self.__dict__, "_cache": OrderedDict(), "_cached_bytes": 0, "_valid_of": None}

    # ------------------------------------------------------------------ index
    @property
    def index_path(self) -> Path:
        return self.root / "index.json"

    def _read_index(self) -> list[dict]:
        return self._read_index_text()[1]

    def _read_index_text(self) -> tuple[bytes, list[dict]]:
        """The index file's bytes and its records (parsed afresh: callers may edit them)."""
        if not self.index_path.exists():
            return b"", []
        try:
            raw = self.index_path.read_bytes()
            data = json.loads(raw)
            if not isinstance(data["maps"], list):
                raise TypeError(f"its maps are a {type(data['maps']).__name__}, not a list")
            return raw, list(data["maps"])
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise MapDatabaseError(
                f"database index {self.index_path} is damaged ({err}); delete it and run "
                "`graspsim db build` again to rebuild it from the map files") from err

    def _write_index(self, records: list[dict]) -> None:
        atomic_write_text(self.index_path, json.dumps({"format": "graspsim-db-1", "maps": records},
                                                      indent=1, sort_keys=True),
                          error=MapDatabaseError)

    def entries(self, *, all_settings: bool = False) -> list[dict]:
        """Index records of the maps built with this database's settings (``all_settings``:
        of every map in the folder; their ``"settings"`` digest tells them apart). Records of
        impossible shapes (e.g. a zero radius) are skipped: never a lookup source."""
        raw, records = self._read_index_text()
        if self._valid_of is None or self._valid_of[0] != raw:  # checked once per index content
            self._valid_of = (raw, [i for i, e in enumerate(records) if _valid_record(e)])
        return [e for e in (records[i] for i in self._valid_of[1])
                if all_settings or e.get("settings") == self._settings]

    @property
    def settings_digest(self) -> str:
        """The digest of gripper, quality model and map settings that keys this database's maps."""
        return self._settings

    def key(self, shape: Primitive) -> str:
        dims = "_".join(f"{k}{v * 1000:.1f}" for k, v in shape.dims.items())
        return f"{shape.kind}_{dims}_{self.gripper.name}_{self._settings}"

    def path(self, shape: Primitive) -> Path:
        return self.root / shape.kind / f"{self.key(shape)}.h5"

    # ------------------------------------------------------------------ queries
    def match(self, shape: Primitive, *, max_ratio: float = float("inf")) -> MatchDecision:
        """Which stored map serves ``shape``: KNOWN (a map within the relative tolerance
        ``self.tol``, :data:`~graspsim.maps.match.KNOWN_TOL`, on every dimension),
        FAMILIAR (the nearest map, at most ``max_ratio`` times larger or
        smaller on every dimension: the scaling range, that can be grasped from every
        direction the shape can) or BUILD (see :mod:`graspsim.maps.match`); ``entry`` is
        the serving index record."""
        g = self.gripper
        return match_entries(shape.kind, shape.dims, self.entries(), tol=self.tol, max_ratio=max_ratio,
                             max_width=g.max_opening - 2.0 * g.approach_clearance)

    def lookup(self, kind: str, dims: dict[str, float]) -> MatchDecision:
        """:meth:`match` for a primitive given by name and dims [m] (validated)."""
        return self.match(make_primitive(kind, **dims))

    def contains(self, shape: Primitive) -> bool:
        return any(e["key"] == self.key(shape) for e in self.entries()) and self.path(shape).exists()

    def get(self, shape: Primitive, *, build: bool = True, threads: int | None = None) -> GraspabilityMap:
        """The FS map of ``shape``: loaded if stored (and readable), otherwise built,
        stored and returned as built (sorted best first, as stored)."""
        p = self.path(shape)
        if self.contains(shape):
            try:
                return self._ours(load_map(p, verify_transforms=False))
            except MapFileError as err:
                log.warning("rebuilding damaged database map %s: %s", p, err)
        if not build:
            raise MapDatabaseError(f"no map of {shape} in {self.root}")
        return self.add(shape, threads=threads)

    def load_entry(self, entry: dict, *, accepted_only: bool = False) -> GraspabilityMap:
        """A stored map; with ``accepted_only`` just its grasps above the threshold --
        stored maps are sorted best first, so that is a prefix of the file (a partial
        read) -- kept in the in-memory cache (see the class) for repeated run-time use. A stored
        map that cannot be read raises :class:`MapDatabaseError` saying how to repair."""
        path = self.root / entry["file"]
        try:
            if not accepted_only:
                return self._ours(load_map(path, verify_transforms=False))
            key = (str(path), path.stat().st_mtime_ns)
            hit = self._cache.get(key)
            if hit is not None:
                self._cache.move_to_end(key)
                return hit[0]
            gmap = self._ours(load_map(path, rows=slice(0, int(entry["accepted"])), verify_transforms=False))
        except (OSError, KeyError, TypeError, ValueError) as err:  # MapFileError is an OSError
            raise MapDatabaseError(f"stored map {path} is unusable ({err}); `graspsim db check --repair "
                                   f"--root {self.root}` removes it (the next use rebuilds it)") from err
        if len(gmap) and not gmap.accepted.all():
            raise MapDatabaseError(f"{path} is not sorted best first; rebuild the database")
        self._keep(key, gmap)
        return gmap

    def _keep(self, key, gmap: GraspabilityMap) -> None:
        """Cache ``gmap``, then drop the least recently used maps while more than
        ``cache_size`` maps or ``cache_bytes`` bytes are held (a map larger than the
        byte budget is not kept)."""
        size = map_bytes(gmap)
        if self.cache_size <= 0 or size > self.cache_bytes:
            return
        self._cache[key] = (gmap, size)
        self._cached_bytes += size
        while len(self._cache) > self.cache_size or self._cached_bytes > self.cache_bytes:
            self._cached_bytes -= self._cache.popitem(last=False)[1][1]

    def _ours(self, gmap: GraspabilityMap) -> GraspabilityMap:
        """A stored map as this database's gripper's: a map keyed by this gripper's digest
        but made with a copy of its model file elsewhere (the key holds the file's content,
        not its path) records this gripper's path, so its trials simulate this file."""
        model = gmap.meta.gripper.get("model")
        if model != self.gripper.model and isinstance(model, str) and isinstance(self.gripper.model, str) \
                and {k: v for k, v in gmap.meta.gripper.items() if k != "model"} == \
                {k: v for k, v in self.gripper.to_dict().items() if k != "model"}:
            return gmap.with_meta(gripper=self.gripper.to_dict())
        return gmap

    # ------------------------------------------------------------------ building
    def add(self, shape: Primitive, *, threads: int | None = None, progress=None) -> GraspabilityMap:
        """Generate and store the FS map of ``shape`` (replacing any stored one)."""
        gmap, record = _build_one(self, shape, threads=threads, progress=progress)
        self._merge([record])
        return gmap

    def linked_copy(self, folder: str | os.PathLike) -> MapDatabase:
        """A database with the same settings in the new ``folder`` over this one's map
        files (symbolic links and a copy of the index): maps it builds are stored in
        ``folder`` only, and this database is left as it was."""
        folder = Path(folder)
        folder.mkdir(parents=True)
        shutil.copy2(self.index_path, folder / "index.json")
        for e in self.entries():
            dst = folder / e["file"]
            dst.parent.mkdir(parents=True, exist_ok=True)
            dst.symlink_to((self.root / e["file"]).resolve())
        return MapDatabase(folder, gripper=self.gripper, quality=self.quality, config=self.config)

    def _merge(self, new: list[dict]) -> None:
        """Add records to the index (replacing those with the same keys)."""
        keys = {r["key"] for r in new}
        self.edit_index(lambda records: [e for e in records if not (isinstance(e, dict) and e.get("key") in keys)]
                        + new)

    def records(self) -> list[dict]:
        """Every index record, whatever its settings (raises if the index is damaged)."""
        return self._read_index()

    def edit_index(self, edit, *, damaged_ok: bool = False) -> None:
        """Replace the index records by ``edit(records)``. The read-modify-write holds
        an exclusive lock, so processes writing one database at the same time lose no
        record; ``damaged_ok``: a damaged index reads as empty (to rebuild it)."""
        with _locked(self.root / ".index.lock"):
            try:
                records = self._read_index()
            except MapDatabaseError:
                if not damaged_ok:
                    raise
                records = []
            self._write_index(edit(records))

    def build(self, shapes: Iterable[Primitive], *, threads: int | None = None, progress=None,
              executor=None) -> list[dict]:
        """Build every missing map (resumable: stored maps are skipped). ``progress`` is
        called with (done, total, shape) after each shape. With an ``executor``
        (``graspsim.executors``: local processes or Ray) maps are built in parallel
        workers (one thread each) and give exactly the maps a serial build gives."""
        shapes = list(shapes)
        missing = [s for s in shapes if not self.contains(s)]
        done = len(shapes) - len(missing)
        if progress:
            for s in shapes:
                if s not in missing:
                    progress(done, len(shapes), s)
        if executor is None or len(missing) <= 1:
            for s in missing:
                self.add(s, threads=threads)
                done += 1
                if progress:
                    progress(done, len(shapes), s)
        else:
            from graspsim.maps.kernels import ensure_compiled

            ensure_compiled()  # here, once: the workers then load the kernels from the cache
            jobs = [_BuildJob(str(self.root), s.to_dict(), self.gripper.to_dict(), self.quality.to_dict(),
                              self.config.to_dict(), self.tol) for s in missing]
            for i, record in executor.imap(_build_job, jobs):
                self._merge([record])  # one writer of the index: this process
                done += 1
                if progress:
                    progress(done, len(shapes), missing[i])
        keys = {self.key(s) for s in shapes}
        return [e for e in self.entries() if e["key"] in keys]


@dataclass(frozen=True)
class _BuildJob:
    root: str
    shape: dict
    gripper: dict
    quality: dict
    config: dict
    tol: float


def _build_job(job: _BuildJob) -> dict:
    """Worker side of a parallel build: generate and store one map, return its record."""
    db = MapDatabase(job.root, gripper=GripperSpec.from_dict(job.gripper),
                     quality=QualityModel.from_dict(job.quality), config=MapConfig(**job.config),
                     tol=job.tol)
    return _build_one(db, primitive_from_dict(job.shape), threads=1)[1]


def index_record(root: Path, path: Path, gmap: GraspabilityMap, seconds: float | None,
                 created: float | None = None) -> dict:
    """The index record of the map ``gmap`` stored at ``path`` (ROOT/<primitive>/<key>.h5,
    the key ending in the settings digest); ``created``: a timestamp (default now)."""
    key = path.stem
    return {"key": key, "primitive": gmap.meta.object["primitive"], "dims": dict(gmap.meta.object["dims"]),
            "gripper": gmap.meta.gripper.get("name"), "settings": key.rsplit("_", 1)[-1],
            "file": str(path.relative_to(root)), "grasps": len(gmap), "accepted": int(gmap.accepted.sum()),
            "seconds": seconds, "created": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(created))}


def _build_one(db: MapDatabase, shape: Primitive, *, threads=None, progress=None):
    """Generate, sort best first and store one FS map; returns it and its index record."""
    t0 = time.perf_counter()
    show = BUILD_PROGRESS.get() if progress is None else None
    with (show(shape) if show is not None else contextlib.nullcontext(progress)) as report:
        gmap = generate_fs_map(shape, db.gripper, db.quality, db.config, threads=threads,
                               progress=report)
    gmap = gmap.select(np.argsort(-gmap.grade, kind="stable"))  # accepted grasps first
    validate_map(gmap, error=MapDatabaseError, what=f"the FS map of {shape} (not stored)")
    p = db.path(shape)
    p.parent.mkdir(exist_ok=True)
    save_map(gmap, p)
    record = index_record(db.root, p, gmap, time.perf_counter() - t0)
    log.info("database: stored %s (%d grasps)", shape, len(gmap))
    return gmap, record
