"""Simulating the grasps of a map file and writing the results back into it.

The map's object (a primitive, a compound, or a mesh reference) becomes the simulated
object; with ``mesh=`` a given mesh -- the real object -- replaces it, placed by the
map's recorded cloud->object transform ``meta.extra["T_cloud_obj"]`` (mesh and cloud
share a frame), as the paper tested maps planned from primitives on real objects.

Results go to ``grasps/qualities/mujoco`` (``lift_place``) or
``grasps/qualities/mujoco_tug`` (``tug``), one row per grasp of the map: rows not
simulated hold outcome -1, object_in_gripper -1 and NaN metrics, and ``simulated`` says
which rows were. Simulating more rows later with the same protocol, scene and noise
merges; anything else replaces the group.

A third-party grasp file (ACRONYM, GraspGen, GraspNet: :mod:`graspsim.maps.formats`) is
never written: it is read once into a graspsim map beside it (``<stem>.graspsim.h5``,
its own labels under ``grasps/qualities/source``), and the results go there
(``MapTrials.file``).
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from graspsim.errors import GraspsimError, InvalidParameterError, MapFileError, SimulationError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps import GraspabilityMap, load_map, read_sim_results, write_sim_results
from graspsim.maps.robust import executed_width
from graspsim.sim.batch import run_trials
from graspsim.sim.meshes import PreparedMesh
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.objects import SimObject, object_from_mesh, object_from_shape
from graspsim.sim.protocols import LiftPlace, Protocol
from graspsim.sim.results import RESULT_GROUPS, TrialResults
from graspsim.sim.trial_scene import Scene, SimSettings, build_scene
from graspsim.transforms import invert_transform

__all__ = ["MapTrials", "select_grasps", "map_object", "map_gripper", "observed_placement", "simulate_map",
           "map_trials", "write_results"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class MapTrials:
    """Results of simulating some rows of a map: ``index`` (n,) the map rows, in the
    order of ``results``; ``scene`` the compiled scene; ``group`` where they were
    written (None if not written); ``width`` (n,) the widths the jaws opened to [m],
    :func:`~graspsim.maps.robust.executed_width` (the map need not be read again to draw them);
    ``viewpoint`` the map's recorded viewpoint (a single view's camera; None: seen all round)."""

    index: np.ndarray
    results: TrialResults
    scene: Scene
    group: str | None
    width: np.ndarray | None = None
    #: results of earlier runs the map file held in ``group`` and kept beside these (rows)
    kept: int = 0
    #: results of earlier runs this run replaced (``replace=True``; rows)
    replaced: int = 0
    file: Path | None = None
    viewpoint: list | None = None


def select_grasps(gmap: GraspabilityMap, *, top: int | None = None, sample: int | None = None,
                  min_grade: float | None = None, rng: np.random.Generator | None = None,
                  rank: str = "robust", separation: tuple[float, float] | None = None) -> np.ndarray:
    """Map row indices to simulate: the ``top`` best by ``rank`` (``"robust"``: the
    map's robust scores where it has them, else the grade; ``"paper"``: the grade; see
    :func:`graspsim.maps.robust.ranking`) -- with ``separation`` = (distance [m], angle
    [rad]) the ``top`` best at least that far apart (:func:`~graspsim.maps.separation.separated_rows`)
    --, or ``sample`` grasps spread uniformly over the surface among those with grade >
    ``min_grade``, or all."""
    if top is not None and sample is not None:
        raise InvalidParameterError("give top or sample, not both")
    rows = np.arange(len(gmap))
    if min_grade is not None:
        rows = rows[gmap.above(min_grade)]
    if top is not None:
        if top < 0:
            raise InvalidParameterError(f"top must be >= 0, got {top}")
        from graspsim.maps.robust import ranking

        order = ranking(gmap.select(rows), rank)
        if separation is None:
            return rows[order[:top]]
        from graspsim.maps.separation import separated_rows

        sub = gmap.select(rows)
        return rows[separated_rows(sub.grasp_point, sub.wrist_quat, order, top, distance=float(separation[0]),
                                   angle=float(separation[1]))]
    if sample is not None:
        if sample < 0:
            raise InvalidParameterError(f"sample must be >= 0, got {sample}")
        return rows[gmap.select(rows).uniform_surface_rows(sample, rng or np.random.default_rng(0))]
    return rows


def map_gripper(gmap: GraspabilityMap) -> GripperSpec:
    if not gmap.meta.gripper:
        raise SimulationError("the map records no gripper (meta.gripper is empty)")
    return gmap.meta.gripper_spec


def _given_mass(obj: dict) -> float | None:
    m = obj.get("mass")
    if m is None or (isinstance(m, float) and math.isnan(m)):
        return None
    m = float(m)
    if not (math.isfinite(m) and m > 0):
        raise SimulationError(f"the map's object mass must be > 0 kg, got {m!r}")
    return m


def map_object(gmap: GraspabilityMap, *, mesh: str | os.PathLike | PreparedMesh | None = None,
               mesh_scale: float = 1.0, mass: float | None = None, density: float = 1000.0,
               map_dir: str | os.PathLike | None = None, cache_dir=None) -> SimObject:
    """The object to simulate for a map (see the module docstring). ``mesh``: a mesh file
    (prepared by :func:`~graspsim.sim.meshes.prepare_mesh` at ``mesh_scale``) or a
    :class:`~graspsim.sim.meshes.PreparedMesh`. ``mass`` overrides the map's; otherwise
    the map's mass, or ``density`` x volume if it has none. Against a mesh, the mesh is the
    object: ``density`` x its volume unless ``mass`` is given (an adapted map's mass is that
    of the fitted parts, which fill a mug's cavity: 0.50 kg where the mesh gives 0.25 kg)."""
    obj = gmap.meta.object or {}
    if mesh is not None:
        placement = gmap.meta.placement
        if placement is None:
            log.warning("map has no T_cloud_obj: assuming the mesh is in the object frame")
            T_obj_mesh = None
        else:
            T_obj_mesh = invert_transform(placement.T_cloud_obj)
        return object_from_mesh(mesh, T_obj_mesh=T_obj_mesh, scale=mesh_scale, mass=mass,
                                density=density, cache_dir=cache_dir)
    mass = mass if mass is not None else _given_mass(obj)
    if obj.get("file"):
        path = Path(obj["file"])
        if not path.is_absolute() and map_dir is not None:
            path = Path(map_dir) / path
        return object_from_mesh(path, scale=float(obj.get("scale", 1.0)), mass=mass,
                                density=density, cache_dir=cache_dir)
    if "primitive" not in obj:
        raise SimulationError("the map's object has neither a primitive nor a mesh file; "
                              "pass mesh= to simulate against a mesh")
    try:
        shape = gmap.meta.shape
    except GraspsimError as err:
        raise SimulationError(f"cannot rebuild the map's object {obj!r}: {err}") from err
    return object_from_shape(shape, mass=mass, density=density)


def _group(results: TrialResults) -> str:
    return RESULT_GROUPS.get(results.protocol["name"], "grasps/qualities/mujoco_" + results.protocol["name"])


def stored_results(path: str | os.PathLike, protocol: Protocol, scene: Scene, noise: ExecutionNoise | None,
                   index: np.ndarray) -> tuple[str, int, str | None]:
    """What storing trials of map rows ``index`` (with this protocol, scene and noise)
    would do to the results the file already holds: (group, rows held, None when the new
    rows can be stored beside them, else why they would be replaced)."""
    group = RESULT_GROUPS.get(protocol.name, "grasps/qualities/mujoco_" + protocol.name)
    try:
        old = read_sim_results(path, group)
    except MapFileError:  # unreadable: write_sim_results saves the new results aside
        return group, 0, None
    held = np.asarray(old.get("simulated", ()), bool)
    if not held.any():
        return group, 0, None
    info = old.get("info", {})
    new = {"protocol": protocol.to_dict(), "scene": scene.info(),
           "noise": None if noise is None else noise.to_dict()}
    other = [k for k in ("protocol", "scene", "noise") if info.get(k) != _jsonish(new[k])]
    if other:
        return group, int(held.sum()), f"made with another {' and '.join(other)}"
    again = int(held[np.asarray(index)[np.asarray(index) < len(held)]].sum())
    if again:
        return group, int(held.sum()), f"{again} of the grasps selected now among them"
    return group, int(held.sum()), None


def _jsonish(value):
    """``value`` as it reads back from the file's JSON record (tuples as lists ...)."""
    import json

    from graspsim._jsonable import to_jsonable

    return json.loads(json.dumps(to_jsonable(value)))


def write_results(path: str | os.PathLike, n_rows: int, index: np.ndarray,
                  results: TrialResults) -> str:
    """Store results for map rows ``index`` in the map file (merging earlier rows of the
    same protocol and scene; results of other settings are replaced: see
    :func:`stored_results`); returns the group written."""
    group = _group(results)
    info = results.info()
    arrays = {"simulated": np.zeros(n_rows, bool)}
    for k, v in results.arrays().items():
        fill = np.nan if np.issubdtype(v.dtype, np.floating) else -1
        arrays[k] = np.full(n_rows, fill, dtype=v.dtype)
    try:
        old = read_sim_results(path, group)
    except MapFileError as err:  # the file went bad during the run: write_sim_results saves aside
        log.warning("cannot read earlier results of %s: %s", path, err)
        old = {}
    same = all(old.get("info", {}).get(k) == _jsonish(info[k]) for k in ("protocol", "scene", "noise"))
    if old and same and "simulated" in old:
        keep = np.asarray(old["simulated"], bool)
        for k in arrays:
            if k in old and len(old[k]) == n_rows:
                arrays[k][keep] = np.asarray(old[k])[keep]
    for k, v in results.arrays().items():
        arrays[k][index] = v
    arrays["simulated"][index] = True
    write_sim_results(path, arrays, group=group, attrs_json=info)
    return group


def observed_placement(gmap: GraspabilityMap, obj: SimObject, has_mesh: bool) -> np.ndarray | None:
    """T_world_obj (4, 4) for a map planned from a cloud: the object stands on the table
    as the cloud saw it (:func:`~graspsim.sim.trial_scene.observed_pose`), up along the normal
    of the table the planner was told about (its map then holds only poses above that
    table), or for a mesh (the real object, in the cloud's frame) without one, along the
    cloud's +z. None: the object's own stable resting pose (a map not planned from a
    cloud, or primitives planned without a table)."""
    from graspsim.sim.trial_scene import observed_pose

    placement = gmap.meta.placement
    if placement is None:
        return None
    if placement.table is not None:
        return observed_pose(obj, placement.T_cloud_obj, placement.table["normal"])
    if has_mesh:
        return observed_pose(obj, placement.T_cloud_obj)
    return None


def simulate_map(path: str | os.PathLike, *, protocol: Protocol = LiftPlace(),
                 top: int | None = None, sample: int | None = None, min_grade: float | None = None,
                 threads: int | None = None, seed: int = 0, noise: ExecutionNoise | None = None,
                 mesh: str | os.PathLike | PreparedMesh | None = None, mesh_scale: float = 1.0,
                 mass: float | None = None, settings: SimSettings | None = None,
                 write: bool = True, replace_stored: bool = False, cache_dir=None, on_progress=None,
                 on_selected=None, on_record=None, rank: str = "robust",
                 separation: tuple[float, float] | None = None,
                 dataset: dict | None = None) -> MapTrials:
    """Simulate grasps of the map file ``path`` and (``write``) store the results in it.

    settings: defaults to :class:`SimSettings` with the pad friction of the map's quality
    model (the planner's mu). Selection: see :func:`select_grasps` (``seed`` also draws
    the uniform sample; ``rank`` orders ``top``, ``separation`` spreads it).
    ``on_selected(gmap, index)`` is called once the rows are chosen
    and before anything is simulated (it may raise to stop, e.g. on an empty or huge
    selection). ``on_record``: see :func:`~graspsim.sim.batch.run_trials` (trial numbers
    are positions in ``MapTrials.index``). A third-party grasp file is imported
    beside itself first (see the module doc; ``mesh`` / ``mesh_scale`` then name its
    object's mesh, ``dataset`` holds the other arguments of
    :func:`~graspsim.maps.formats.read_grasp_file`) and the results go to that map.

    Results the file already holds are kept: the new rows are stored beside them when
    they were made with the same protocol, scene and noise and simulate other grasps;
    otherwise storing would replace them, which needs ``replace_stored=True`` (else an
    :class:`~graspsim.errors.InvalidParameterError` before anything is simulated;
    ``write=False`` stores nothing). ``MapTrials.kept`` / ``.replaced`` say which.
    """
    def scene_of(obj, gripper, settings, T_world_obj):
        return build_scene(obj, gripper, settings, table=protocol.table, gravity=protocol.gravity,
                           T_world_obj=T_world_obj)

    def execute(scene, T_obj_wrist, width):
        return run_trials(scene, T_obj_wrist, width, protocol, threads=threads, seed=seed, noise=noise,
                          on_progress=on_progress, on_record=on_record)

    return map_trials(path, scene_of, execute, protocol=protocol, top=top, sample=sample, min_grade=min_grade,
                      seed=seed, noise=noise, mesh=mesh, mesh_scale=mesh_scale, mass=mass, settings=settings,
                      write=write, replace_stored=replace_stored, cache_dir=cache_dir, on_selected=on_selected,
                      rank=rank, separation=separation, dataset=dataset)


def map_trials(path, scene_of, execute, *, protocol: Protocol, top: int | None = None, sample: int | None = None,
               min_grade: float | None = None, seed: int = 0, noise: ExecutionNoise | None = None,
               mesh=None, mesh_scale: float = 1.0, mass: float | None = None, settings: SimSettings | None = None,
               write: bool = True, replace_stored: bool = False, cache_dir=None, on_selected=None,
               rank: str = "robust", separation: tuple[float, float] | None = None,
               dataset: dict | None = None) -> MapTrials:
    """The one path from a map file to its stored trial results, whatever executes the grasps:
    :func:`simulate_map` (the floating gripper) and the arm's
    :func:`graspsim.robots.simulate_map_arm` differ only in ``scene_of(obj, gripper, settings,
    T_world_obj) -> scene`` and ``execute(scene, T_obj_wrist, width) -> TrialResults``.
    Selection, the object and where it stands, the settings, the stored-results check and the storing are
    :func:`simulate_map`'s (arguments as there)."""
    path, mesh = _simulated_file(Path(path), mesh, mesh_scale, dataset)
    gmap = load_map(path)
    gripper = map_gripper(gmap)
    if settings is None:
        mu = gmap.meta.quality.get("friction")
        settings = SimSettings(friction=float(mu)) if mu else SimSettings()
    rng = np.random.default_rng(seed)
    index = select_grasps(gmap, top=top, sample=sample, min_grade=min_grade, rng=rng, rank=rank,
                          separation=separation)
    if on_selected is not None:
        on_selected(gmap, index)
    obj = map_object(gmap, mesh=mesh, mesh_scale=mesh_scale, mass=mass, density=settings.density,
                     map_dir=path.parent, cache_dir=cache_dir)
    scene = scene_of(obj, gripper, settings, observed_placement(gmap, obj, mesh is not None))
    held, why = 0, None
    if write and len(index):
        group, held, why = stored_results(path, protocol, scene, noise, index)
        if why is not None and not replace_stored:
            raise InvalidParameterError(
                f"{path.name} already holds the results of {held} trials in {group} ({why}): storing "
                "these would replace them; pass --replace (replace_stored=True) to replace them, or "
                "--no-write (write=False) to keep them and store nothing")
    chosen = gmap.select(index)  # transforms of the chosen rows only (all of a 10 M-grasp map: 1.2 GB)
    width = executed_width(chosen)
    results = execute(scene, chosen.T_obj_wrist, width)
    results = replace(results, extra={**results.extra, "map_file": str(path),
                                      "mesh": None if mesh is None else str(getattr(mesh, "source", mesh))})
    group = write_results(path, len(gmap), index, results) if write and len(index) else None
    return MapTrials(index=index, results=results, scene=scene, group=group, width=width, file=path,
                     viewpoint=gmap.meta.extra.get("viewpoint"),
                     kept=held if group and why is None else 0, replaced=held if group and why else 0)


def _simulated_file(path: Path, mesh, mesh_scale: float, dataset: dict | None):
    """(the map file to simulate and write, the mesh override left for map_object): a
    third-party file's imported map beside it, its mesh given to the import."""
    from graspsim.maps.formats import is_foreign
    from graspsim.maps.imported import import_beside

    if not is_foreign(path):
        if dataset:
            raise InvalidParameterError(f"{path} is a graspsim map: {sorted(dataset)} apply to "
                                        "third-party grasp files only")
        return path, mesh
    kw = dict(dataset or {})
    if mesh is not None:
        kw.update(mesh=mesh, mesh_scale=mesh_scale)
    return import_beside(path, **kw), None
