"""Gymnasium environments for learning and benchmarking grasp policies.

* ``graspsim/GraspSelect-v0`` (:class:`~graspsim.envs.grasp_select.GraspSelectEnv`):
  choose one of K grasps the planner offers for an object seen as a point cloud --
  a one-step contextual bandit with an action mask.
* ``graspsim/GraspPose-v0`` (:class:`~graspsim.envs.grasp_pose.GraspPoseEnv`): propose a
  wrist pose (continuous action) for the same task.
* ``graspsim/ClutterClear-v0`` (:class:`~graspsim.envs.clutter_clear.ClutterClearEnv`):
  clear a table-top scene of several objects seen by a depth camera, one chosen grasp
  per step (the clutter-removal protocol of :mod:`graspsim.tabletop.clutter`).

All are registered by ``import graspsim`` (Gymnasium 1.x loads no plugin entry points),
by entry-point strings, so importing graspsim does not import mujoco. Nor does it import
gymnasium (with numpy, ~0.1 s): when gymnasium is not loaded yet, a one-shot import hook
registers the environments right after gymnasium's own import, so
``import graspsim; import gymnasium; gymnasium.make("graspsim/GraspSelect-v0")`` works in
either import order. ``gymnasium.make("graspsim:graspsim/GraspSelect-v0")`` imports
graspsim first.
Keyword arguments of ``gymnasium.make`` are :class:`~graspsim.envs.env_config.EnvConfig`
fields. For ``make_vec`` use ``autoreset_mode=SAME_STEP`` (one-step episodes; see
:mod:`graspsim.envs.grasp_select`).

May use: the base modules, geometry, primitives, grippers, grades, maps, plots, perception,
planning, sim and tabletop (never calibration, the viewer, the apps or the CLI).
"""

from __future__ import annotations

import sys

__all__ = ["GRASP_SELECT_ID", "GRASP_POSE_ID", "CLUTTER_CLEAR_ID", "register_envs", "register_when_imported",
           "GraspSelectEnv", "GraspPoseEnv", "ClutterClearEnv", "EnvConfig"]

GRASP_SELECT_ID = "graspsim/GraspSelect-v0"
GRASP_POSE_ID = "graspsim/GraspPose-v0"
CLUTTER_CLEAR_ID = "graspsim/ClutterClear-v0"
_ENTRY_POINTS = {GRASP_SELECT_ID: "graspsim.envs.grasp_select:GraspSelectEnv",
                 GRASP_POSE_ID: "graspsim.envs.grasp_pose:GraspPoseEnv",
                 CLUTTER_CLEAR_ID: "graspsim.envs.clutter_clear:ClutterClearEnv"}


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent)."""
    import gymnasium

    for env_id, entry in _ENTRY_POINTS.items():
        if env_id not in gymnasium.registry:
            # each env ends its episodes itself (ClutterClear truncates at its attempt limit): no TimeLimit
            gymnasium.register(id=env_id, entry_point=entry, disable_env_checker=False)


def register_when_imported() -> None:
    """Register the environments now if gymnasium is loaded, else as soon as it is."""
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _RegisterOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterOnImport())


class _RegisterOnImport:
    """One-shot import hook (a ``sys.meta_path`` finder): finds ``gymnasium`` with the
    other finders and wraps its loader so that :func:`register_envs` runs right after
    gymnasium's module body."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "gymnasium":
            return None
        import importlib.util

        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        loader = getattr(spec, "loader", None)
        if loader is not None and hasattr(loader, "exec_module"):
            run = loader.exec_module

            def exec_module(module):
                run(module)
                register_envs()

            loader.exec_module = exec_module
        return spec


def __getattr__(name: str):
    if name == "GraspSelectEnv":
        from graspsim.envs.grasp_select import GraspSelectEnv

        return GraspSelectEnv
    if name == "GraspPoseEnv":
        from graspsim.envs.grasp_pose import GraspPoseEnv

        return GraspPoseEnv
    if name == "ClutterClearEnv":
        from graspsim.envs.clutter_clear import ClutterClearEnv

        return ClutterClearEnv
    if name == "EnvConfig":
        from graspsim.envs.env_config import EnvConfig

        return EnvConfig
    raise AttributeError(f"module 'graspsim.envs' has no attribute {name!r}")
