"""Gymnasium environments for learning and benchmarking grasp policies.

* ``graspsim/GraspSelect-v0`` (:class:`~graspsim.envs.grasp_select.GraspSelectEnv`):
  choose one of K grasps the planner offers for an object seen as a point cloud --
  a one-step contextual bandit with an action mask.
* ``graspsim/GraspPose-v0`` (:class:`~graspsim.envs.grasp_pose.GraspPoseEnv`): propose a
  wrist pose (continuous action) for the same task.

Both are registered when ``graspsim`` is imported (Gymnasium 1.x does not load entry
points by itself), by entry-point strings, so importing graspsim does not import
mujoco; ``gymnasium.make("graspsim:graspsim/GraspSelect-v0")`` imports graspsim first.
Keyword arguments of ``gymnasium.make`` are :class:`~graspsim.envs.config.EnvConfig`
fields. For ``make_vec`` use ``autoreset_mode=SAME_STEP`` (one-step episodes; see
:mod:`graspsim.envs.grasp_select`).
"""

from __future__ import annotations

__all__ = ["GRASP_SELECT_ID", "GRASP_POSE_ID", "register_envs", "GraspSelectEnv", "GraspPoseEnv",
           "EnvConfig"]

GRASP_SELECT_ID = "graspsim/GraspSelect-v0"
GRASP_POSE_ID = "graspsim/GraspPose-v0"
_ENTRY_POINTS = {GRASP_SELECT_ID: "graspsim.envs.grasp_select:GraspSelectEnv",
                 GRASP_POSE_ID: "graspsim.envs.grasp_pose:GraspPoseEnv"}


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent)."""
    import gymnasium

    for env_id, entry in _ENTRY_POINTS.items():
        if env_id not in gymnasium.registry:
            # one step per episode: the env ends it itself, no TimeLimit needed
            gymnasium.register(id=env_id, entry_point=entry, disable_env_checker=False)


def __getattr__(name: str):
    if name == "GraspSelectEnv":
        from graspsim.envs.grasp_select import GraspSelectEnv

        return GraspSelectEnv
    if name == "GraspPoseEnv":
        from graspsim.envs.grasp_pose import GraspPoseEnv

        return GraspPoseEnv
    if name == "EnvConfig":
        from graspsim.envs.config import EnvConfig

        return EnvConfig
    raise AttributeError(f"module 'graspsim.envs' has no attribute {name!r}")
