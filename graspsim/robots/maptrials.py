"""A map's grasps executed by an arm, written back into the map file.

The counterpart of :func:`graspsim.sim.mapsim.simulate_map` (the same selection, object,
placement, settings and storage; ``graspsim trial MAP --robot panda`` calls it): the
floating gripper's scene becomes the arm's (:func:`~graspsim.robots.execute.build_arm_scene`)
and each grasp is planned and executed by the arm
(:func:`~graspsim.robots.execute.run_arm_trials`), its IK seeded by the arm's cached
capability map. Results go to ``grasps/qualities/mujoco_arm_lift_place``, their record
naming the robot and its base; grasps the reachability check refused count as
failures (UNREACHABLE, APPROACH_COLLISION). A map whose ``reachable`` column
(:func:`~graspsim.robots.mapreach.mark_reach_file`) was judged for another arm, base or
object pose than this run's is still ranked by it, with a warning saying so.
"""

from __future__ import annotations

import logging
import os

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.robots.arm import DEFAULT_BASE, base_transform, build_robot_model, get_arm
from graspsim.robots.capability import CapabilityConfig, capability_map
from graspsim.robots.execute import ArmLiftPlace, build_arm_scene, run_arm_trials
from graspsim.sim.mapsim import MapTrials, map_trials
from graspsim.sim.noise import ExecutionNoise

__all__ = ["simulate_map_arm", "reach_mismatch"]

log = logging.getLogger(__name__)


def reach_mismatch(record: dict | None, robot: str, T_world_base: np.ndarray,
                   T_world_obj: np.ndarray | None = None, tol: float = 1e-6) -> str | None:
    """What differs between a map's reach record (``meta.extra["reach"]``) and a run of
    ``robot`` at ``T_world_base`` with the object at ``T_world_obj`` (None: not
    compared), in words; None when nothing does (or there is no record)."""
    if not record:
        return None
    if record.get("robot") != robot:
        return f"the arm {record.get('robot')!r}, not {robot!r}"
    if not np.allclose(np.asarray(record.get("T_world_base"), float), T_world_base, atol=tol):
        return "another base"
    if T_world_obj is not None and not np.allclose(np.asarray(record.get("T_world_obj"), float), T_world_obj,
                                                   atol=tol):
        return "the object standing elsewhere"
    return None


def simulate_map_arm(path: str | os.PathLike, *, robot: str = "panda", base=DEFAULT_BASE,
                     protocol: ArmLiftPlace = ArmLiftPlace(), threads: int | None = None, seed: int = 0,
                     noise: ExecutionNoise | None = None, capability: CapabilityConfig | None = None,
                     capability_cache=None, on_progress=None, on_selected=None, **selection) -> MapTrials:
    """Execute grasps of the map file ``path`` with the arm ``robot`` standing at ``base``
    (x [m], y [m], yaw [rad] on the table top, or a (4, 4) pose) and (``write``) store the
    results in it. ``capability`` / ``capability_cache``: the capability map's settings and
    cache folder (``False``: no cache). Every other argument as in
    :func:`~graspsim.sim.mapsim.simulate_map`: ``selection`` holds the ones that choose the
    grasps, the object and the settings and store the results (``top``, ``sample``,
    ``min_grade``, ``rank``, ``separation``, ``mesh``, ``mesh_scale``, ``mass``,
    ``settings``, ``write``, ``replace_stored``, ``cache_dir``, ``dataset``), passed to
    :func:`~graspsim.sim.mapsim.map_trials` as they are."""
    arm = get_arm(robot)
    T_base = base_transform(base)
    if not isinstance(protocol, ArmLiftPlace):
        raise InvalidParameterError("an arm executes the lift_place protocol (ArmLiftPlace) only")
    record = {}

    def selected(gmap, index):
        record.update((gmap.meta.extra.get("reach") or {}) if gmap.has_reach else {})
        if on_selected is not None:
            on_selected(gmap, index)

    def scene_of(obj, gripper, settings, T_world_obj):
        scene = build_arm_scene(obj, gripper, settings, arm=arm, base=T_base, T_world_obj=T_world_obj)
        why = reach_mismatch(record, arm.name, T_base, scene.T_world_obj)
        if why is not None:
            log.warning("the map's reachable column was judged for %s: it still orders the grasps "
                        "(graspsim reach to judge them again for this run)", why)
        return scene

    def execute(scene, T_obj_wrist, width):
        cmap = capability_map(build_robot_model(arm, scene.gripper, T_base), arm, T_base,
                              capability or CapabilityConfig(), cache_dir=capability_cache)
        return run_arm_trials(scene, T_obj_wrist, width, protocol, threads=threads, seed=seed, noise=noise,
                              capability=cmap, on_progress=on_progress)

    return map_trials(path, scene_of, execute, protocol=protocol, seed=seed, noise=noise, on_selected=selected,
                      **selection)
