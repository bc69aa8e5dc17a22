"""Which of a map's grasps an arm at a base reaches, recorded in the map.

:func:`reach_column` judges every row of a map for ``robot`` standing at ``base``, the
object where a trial puts it (:func:`graspsim.sim.mapsim.observed_placement`, else
resting on the table; the same scene as ``graspsim trial --robot``):

* the first cut, every row: the arm's capability map
  (:func:`~graspsim.robots.capability.capability_map`, cached by content) looked up at
  the grasp's wrist pose; rows it refuses are unreachable (:data:`~graspsim.maps.graspmap.REACH_NONE`),
  the rest first-cut reachable (:data:`~graspsim.maps.graspmap.REACH_FIRST_CUT`);
* the exact check, the ``exact`` best rows the first cut passed (by the map's own
  ranking, reachability aside): the plan an arm trial makes
  (:func:`~graspsim.robots.execute.plan_grasps`: the floating harness's start check, IK
  of the grasp, its pre-grasp and the approach line, the lift, the lowering, the
  retreat and the move from home, collision-checked at the jaws' executed opening);
  planned rows are :data:`~graspsim.maps.graspmap.REACH_EXACT`, the others unreachable.

The column is plain data of the map (``maps`` knows nothing of arms): its ranking puts
reachable rows first (:func:`graspsim.maps.robust.ranking`), so ``graspsim trial --top N``
runs the best ones the arm reaches. :func:`mark_reach_file` stores it in a map file
atomically (``graspsim reach``), with the arm, its base, the object's pose and the counts
in ``meta.extra["reach"]``.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.maps import GraspabilityMap, load_map, write_reach
from graspsim.maps.graspmap import REACH_EXACT, REACH_FIRST_CUT, REACH_NONE
from graspsim.maps.robust import executed_width, ranking
from graspsim.robots.arm import DEFAULT_BASE, base_transform, build_robot_model, get_arm
from graspsim.robots.capability import CapabilityConfig, capability_map
from graspsim.robots.execute import ArmLiftPlace, build_arm_scene, plan_counts, plan_grasps
from graspsim.sim.mapsim import map_gripper, map_object, observed_placement
from graspsim.sim.trial_scene import SimSettings

__all__ = ["reach_column", "mark_reach", "mark_reach_file", "DEFAULT_EXACT"]

log = logging.getLogger(__name__)

#: The rows the exact check judges by default (the issue's goal: a map's 100 best).
DEFAULT_EXACT = 100
_CHUNK = 1 << 16  # rows per first-cut block: (4, 4) float64 poses of 65 536 rows, 8 MB


def reach_column(gmap: GraspabilityMap, *, robot: str = "panda", base=DEFAULT_BASE, exact: int = DEFAULT_EXACT,
                 rank: str = "robust", protocol: ArmLiftPlace = ArmLiftPlace(), map_dir=None,
                 capability: CapabilityConfig | None = None, capability_cache=None, cache_dir=None,
                 on_progress=None) -> tuple[np.ndarray, dict]:
    """(the ``reachable`` column (N,) float32, its record) of ``gmap`` for the arm
    ``robot`` at ``base`` (x [m], y [m], yaw [rad] on the table top, or a (4, 4) pose):
    module doc. ``exact``: how many of the best first-cut rows get the exact check;
    ``rank``: the order choosing them; ``protocol``: the arm trial's approach and lift
    the exact check plans; ``map_dir``: where a mesh object's relative file lies;
    ``capability`` / ``capability_cache``: the capability map's settings and cache folder
    (``False``: no cache); ``cache_dir``: prepared meshes'; ``on_progress(k)``: exact
    checks done."""
    if not (isinstance(exact, (int, np.integer)) and not isinstance(exact, bool) and exact >= 0):
        raise InvalidParameterError(f"exact must be an integer >= 0, got {exact!r}")
    arm = get_arm(robot)
    T_base = base_transform(base)
    gripper = map_gripper(gmap)
    mu = gmap.meta.quality.get("friction")
    settings = SimSettings(friction=float(mu)) if mu else SimSettings()
    obj = map_object(gmap, map_dir=map_dir, density=settings.density, cache_dir=cache_dir)
    scene = build_arm_scene(obj, gripper, settings, arm=arm, base=T_base,
                            T_world_obj=observed_placement(gmap, obj, False))
    cfg = capability or CapabilityConfig()
    cmap = capability_map(build_robot_model(arm, gripper, T_base), arm, T_base, cfg, cache_dir=capability_cache)
    n = len(gmap)
    col = np.full(n, REACH_NONE, np.float32)
    for a in range(0, n, _CHUNK):  # the first cut, in blocks (bounded memory for a million rows)
        T = scene.T_world_obj @ gmap.select(np.arange(a, min(a + _CHUNK, n))).T_obj_wrist
        col[a:a + len(T)] = np.where(cmap.lookup(T)[0], REACH_FIRST_CUT, REACH_NONE)
    passed = int((col == REACH_FIRST_CUT).sum())
    order = ranking(gmap, rank, reach=False)
    rows = order[col[order] == REACH_FIRST_CUT][:exact]
    plans = []
    if len(rows):
        chosen = gmap.select(rows)
        openings = gripper.pregrasp_opening(executed_width(chosen))
        plans, _, _ = plan_grasps(scene, scene.T_world_obj @ chosen.T_obj_wrist, openings, protocol,
                                  capability=cmap, on_planned=on_progress)
        col[rows] = np.where([p.outcome is None for p in plans], REACH_EXACT, REACH_NONE)
    record = {
        "robot": arm.name, "T_world_base": T_base.tolist(), "T_world_obj": scene.T_world_obj.tolist(),
        "base": _base_args(base), "rank": rank, "approach": protocol.approach,
        "first_cut": {"capability_key": cmap.key, "voxel": cfg.voxel, "directions": cfg.directions,
                      "rows": n, "passed": passed},
        "exact": {"rows": len(rows), "planned": int(sum(p.outcome is None for p in plans)),
                  **plan_counts(plans)},
        "counts": {"exact": int((col == REACH_EXACT).sum()), "first_cut": int((col == REACH_FIRST_CUT).sum()),
                   "unreachable": int((col == REACH_NONE).sum())},
        "module": "graspsim.robots.mapreach",
    }
    return col, record


def _base_args(base) -> list | None:
    """x [m], y [m], yaw [deg] of a base given as three numbers (None for a (4, 4) pose)."""
    b = np.asarray(base, float)
    return None if b.shape != (3,) else [float(b[0]), float(b[1]), math.degrees(float(b[2]))]


def mark_reach(gmap: GraspabilityMap, **kwargs) -> GraspabilityMap:
    """``gmap`` with its ``reachable`` column filled and ``meta.extra["reach"]`` recorded
    (arguments as :func:`reach_column`)."""
    from dataclasses import replace

    col, record = reach_column(gmap, **kwargs)
    out = replace(gmap, reachable=col)
    return out.with_meta(extra={**gmap.meta.extra, "reach": record})


def mark_reach_file(path: str | os.PathLike, **kwargs) -> dict:
    """Judge every grasp of the map file ``path`` (:func:`reach_column`; ``map_dir`` is
    its folder) and store the column and its record in it atomically
    (:func:`graspsim.maps.write_reach`: nothing written on failure, trial results kept).
    Returns the record."""
    path = Path(path)
    gmap = load_map(path)
    kwargs.setdefault("map_dir", path.parent)
    col, record = reach_column(gmap, **kwargs)
    write_reach(path, col, record)
    return record
