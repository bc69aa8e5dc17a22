"""The experiment harness's scene helpers: what a run plans and simulates against.

* :func:`map_config`: the scripts' ``MapConfig`` (the default, or quick runs' coarse maps);
* :func:`standing_cloud`: an object standing on the table at a random yaw, seen as a
  (single-view) cloud; :func:`camera_position` (distance, elevation, azimuth);
* :func:`noise_sigmas`: a ``--noise`` label (default, none, MM:DEG) as sigmas;
* :func:`experiment_database`: the FS map database a run plans against (a private
  ``<out>/fsdb`` built fresh unless ``--db``), :func:`database_record`,
  :func:`database_note`; :func:`build_grid` stores a size grid of maps in it before a
  run, and :class:`RunDatabase` reads it during the run without ever storing (so every
  scene, and every condition compared, plans against the same stored maps).

Scripts import these through ``_common``.
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import math
import os
import shutil
from pathlib import Path

import numpy as np

from graspsim.errors import MapDatabaseError, NoFeasibleGraspError
from graspsim.maps.database import MapDatabase
from graspsim.maps.generate import generate_fs_map

__all__ = ["map_config", "camera_position", "standing_cloud", "noise_sigmas", "experiment_database", "database_record",
           "database_note", "RunDatabase", "GRID", "grid_shapes", "build_grid"]


def map_config(quick: bool = False, **kw):
    """The scripts' ``MapConfig(**kw)``: at the library's default resolution, or for
    quick runs coarse (1 cm surface step, 22 deg rotation step)."""
    from graspsim.maps.map_config import MapConfig

    if quick:
        kw = {"surface_step": 0.01, "rotation_step": math.radians(22.0), **kw}
    return MapConfig(**kw)


def camera_position(distance: float, elevation_deg: float, azimuth: float) -> np.ndarray:
    """(3,) a camera ``distance`` [m] from the origin at ``elevation_deg`` above the
    horizontal and ``azimuth`` [rad] about the vertical."""
    el = math.radians(elevation_deg)
    return distance * np.array([math.cos(el) * math.cos(azimuth), math.cos(el) * math.sin(azimuth), math.sin(el)])


def standing_cloud(truth, rng: np.random.Generator, *, resolution: float, noise: float, outliers: float,
                   at=(0.55, -0.05), camera: tuple[float, float] | None = None):
    """A cloud of ``truth`` (a Primitive or Compound) standing on the table (z = 0) at
    ``at`` (x, y) [m] and a yaw drawn from ``rng``; seen from all around, or with
    ``camera`` = (distance [m], elevation [deg]) from one camera at an azimuth drawn
    next. Returns (points (N, 3) [m] in the cloud's (world) frame, T_cloud_true)."""
    from graspsim.primitives import synthetic_cloud
    from graspsim.transforms import make_transform

    a = rng.uniform(0, 2 * math.pi)
    R = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    T = make_transform(R, [at[0], at[1], -truth.aabb[0, 2]])
    cam = None if camera is None else camera_position(camera[0], camera[1], rng.uniform(0, 2 * math.pi))
    c = synthetic_cloud(truth, rng, resolution=resolution, noise=noise, outliers=outliers, camera=cam,
                        T_world_obj=T)
    return c.points, T



def noise_sigmas(label: str) -> tuple[float, float]:
    """(position [m], rotation [deg]) of a ``--noise`` label: default (``ExecutionNoise``'s
    defaults, the execution error of the environments and E04), none or MM:DEG."""
    if label == "default":
        from graspsim.sim.noise import ExecutionNoise

        d = ExecutionNoise()
        return d.position_sigma, round(math.degrees(d.rotation_sigma), 12)
    if label == "none":
        return 0.0, 0.0
    try:
        mm, deg = (float(x) for x in label.split(":"))
    except ValueError:
        raise ValueError(f"a noise condition is default, none or MM:DEG (e.g. 3:2), got {label!r}") from None
    if not (mm >= 0 and deg >= 0 and math.isfinite(mm + deg)):
        raise ValueError(f"--noise sigmas must be finite and >= 0, got {label!r}")
    return mm / 1000.0, deg


def experiment_database(db: str | os.PathLike | None, out: str | os.PathLike, config, *, threads: int | None = None,
                        gripper=None):
    """The ``MapDatabase`` a run plans against, with the paper's five shapes
    (``PAPER_SHAPES``) built in it at ``config`` (a ``MapConfig``) for ``gripper`` (a
    ``GripperSpec``; None: the default): ``db`` (a folder given with ``--db``) used as it
    is, or by default a private ``<out>/fsdb`` emptied and built fresh (seconds), so the
    run does not depend on what ran before it. Maps the planner builds for parts during
    the run are added to it."""
    from graspsim.maps.database import PAPER_SHAPES, MapDatabase

    root = Path(db) if db else Path(out) / "fsdb"
    if not db:
        shutil.rmtree(root, ignore_errors=True)
    database = MapDatabase(root, config=config, **({} if gripper is None else {"gripper": gripper}))
    database.build(PAPER_SHAPES.values(), threads=threads)
    return database


def database_record(db) -> dict:
    """The FS maps a ``MapDatabase`` holds (keys), with its folder: maps the planner
    builds for parts out of every stored map's range are added during a run, and a
    rerun on a database that has grown can plan some objects differently."""
    return {"root": str(db.root), "maps": sorted(e["key"] for e in db.entries())}


def database_note(summary: dict) -> str:
    """A README sentence on the database a run planned against ("" if not recorded)."""
    d = summary.get("database")
    if not d:
        return ""
    a, b = len(d["start"]["maps"]), len(d["end"]["maps"])
    grew = f", {b} at the end: parts out of every stored map's range are built and stored during the run" \
        if b != a else ", none added during the run"
    return f" The FS map database held {a} maps at the start{grew}."


#: The most FS maps a :class:`RunDatabase` keeps built in memory (the first built out
#: first): one is 14-18 s of building for a household part, a few MB to hold, and a user's
#: writable database stores it for good, so a run should not rebuild what it built before.
MEMORY_MAPS = 32


class RunDatabase(MapDatabase):
    """The run's database, read only: a part no stored map serves within the scaling
    range gets its FS map built in memory (kept in this process, never stored), so
    every scene plans against the same stored maps whatever ran before it. ``built``:
    the keys of the maps served so (since it was last emptied).

    Its copies in a scene's worker processes plan as it does (``copies_plan_alike``):
    only a part that no stored map serves reaches the maps built in memory, and a
    segment with such a part is planned in this process
    (:func:`~graspsim.planning.scene_segments.plan_batches`), where ``built`` records it."""

    copies_plan_alike = True

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.built: set[str] = set()
        self._memory: dict = {}

    def __getstate__(self) -> dict:
        """Pickled (sent to a scene worker with every segment) without the maps built in
        memory, as the loaded maps are left out: a copy never builds one (see above),
        and up to :data:`MEMORY_MAPS` maps of a few MB each, sent with every segment,
        made a long run's planning slower with every map built."""
        return {**super().__getstate__(), "built": set(), "_memory": {}}

    def get(self, shape, *, build: bool = True, threads: int | None = None):
        if self.contains(shape) or not build:
            return super().get(shape, build=build, threads=threads)
        key = self.key(shape)
        self.built.add(key)
        if key not in self._memory:
            gmap = generate_fs_map(shape, self.gripper, self.quality, self.config, threads=threads)
            self._memory[key] = gmap.select(np.argsort(-gmap.grade, kind="stable"))  # as stored: best first
            while len(self._memory) > MEMORY_MAPS:
                self._memory.pop(next(iter(self._memory)))
        return self._memory[key]


#: the size grid of the run's database (the paper's five shapes besides): every
#: dimension in steps of x4, so a part from 0.5 mm to 29 cm is within a ratio of 2 of a
#: stored map on every dimension (the planner scales maps by up to 3)
GRID = (0.0015, 0.006, 0.024, 0.096)


_RESIDENT: dict = {}


def resident_run_database(root, quick_maps: bool = False) -> RunDatabase:
    """This process's one :class:`RunDatabase` on ``root`` at the (quick or default) map
    config: a worker process's loaded maps and maps built in memory serve every task it
    runs."""
    key = (str(root), bool(quick_maps))
    if key not in _RESIDENT:
        _RESIDENT[key] = RunDatabase(root, config=map_config(quick_maps))
    return _RESIDENT[key]


def grid_shapes(config) -> list:
    """The primitives of the run's database besides the paper's shapes: boxes with
    sorted sides (identification orders them), cylinders, spheres, cones (tops down to
    0.4 mm: identified cones are often pointed) and half-toroids of :data:`GRID` sizes,
    those larger than the surface step of the map config ``config``."""
    from itertools import combinations_with_replacement as cwr

    from graspsim.primitives import make_primitive

    g = GRID
    out = [make_primitive("box", x=x, y=y, z=z) for x, y, z in cwr(g, 3)]
    out += [make_primitive("cylinder", radius=r, height=h) for r in g for h in g]
    out += [make_primitive("sphere", radius=r) for r in g[1:]]
    out += [make_primitive("cone", bottom_radius=b, top_radius=t, height=h) for b in g[1:]
            for t in (0.0004, *g) if t <= b for h in g[1:]]
    out += [make_primitive("half_toroid", major_radius=a, minor_radius=b) for a in g for b in g if b < a]
    return [s for s in out if s.size_scale > config.surface_step]


def build_grid(db) -> list[str]:
    """Store the maps of :func:`grid_shapes` in ``db`` (those stored already are kept);
    returns the shapes that have no grasp at all (e.g. a 1.5 mm disc 19 cm wide, a
    sphere wider than the gripper opens), which are not stored."""
    empty = []
    for shape in grid_shapes(db.config):
        if db.contains(shape):
            continue
        try:
            db.add(shape, threads=2)
        except NoFeasibleGraspError:
            empty.append(str(shape))
        except MapDatabaseError as err:
            if "no grasps" not in str(err):
                raise
            empty.append(str(shape))
    return empty
