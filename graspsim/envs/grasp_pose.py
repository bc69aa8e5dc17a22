"""``graspsim/GraspPose-v0``: propose a grasp pose for an object seen as a point cloud.

The continuous sibling of ``GraspSelect-v0`` (same objects, table, sensor, trial and
rewards; see :mod:`graspsim.envs.table_task`), for policies that propose grasps instead of
picking planned ones. No planner runs: an episode costs its cloud and its trial.

Observation (``Dict``): ``cloud`` (N, 3) float32, world frame [m]; ``bounds`` (2, 3)
float32, the lower and upper corners of the region the grasp point may be put in (the
cloud's bounding box grown by ``REGION_MARGIN``, not below the table).

Action: ``Box(-1, 1, (10,))``:

* ``[0:3]`` the grasp point (TCP, mid-pad between the fingers), mapped linearly onto
  ``bounds``;
* ``[3:6]`` the approach direction (wrist z) and ``[6:9]`` a hint of the closing axis
  (wrist x; made orthogonal to the approach), both world frame, any length -- the
  6D rotation representation of Zhou et al. (2019), continuous for learning;
* ``[9]`` the jaw opening at the pose, mapped onto the gripper's range.

An approach or closing hint too short or too parallel to define a frame ends the
episode with reward 0 (``info["outcome"] == "invalid_action"``). Poses that start
inside the table or the object are ``start_collision`` trials (reward 0), as are
those the execution error pushes there. :meth:`GraspPoseEnv.action_from_pose` is the
inverse map (e.g. to propose a planned grasp).
"""

from __future__ import annotations

import time

import numpy as np
from gymnasium import spaces

from graspsim.envs.env_config import EnvConfig
from graspsim.envs.table_task import WORLD_BOUND, TableTask
from graspsim.errors import GraspsimError
from graspsim.transforms import make_transform

__all__ = ["GraspPoseEnv", "REGION_MARGIN"]

REGION_MARGIN = 0.01  # [m]
_DEGENERATE = 1e-3


class GraspPoseEnv(TableTask):
    """Propose one grasp (wrist pose and opening) per episode (see the module
    docstring). Keyword arguments are :class:`EnvConfig` fields (``n_candidates`` is
    not used)."""

    def __init__(self, render_mode: str | None = None, *, config: EnvConfig | None = None, **kwargs):
        super().__init__(render_mode, config=config, **kwargs)
        N = self.config.cloud_size
        self.observation_space = spaces.Dict({
            "cloud": spaces.Box(-WORLD_BOUND, WORLD_BOUND, (N, 3), np.float32),
            "bounds": spaces.Box(-WORLD_BOUND, WORLD_BOUND, (2, 3), np.float32),
        })
        self.action_space = spaces.Box(-1.0, 1.0, (10,), np.float32)
        g = self.gripper
        self._tcp = float(g.nominal_tcp[2])
        self._bounds: np.ndarray | None = None
        self._noise_T: np.ndarray | None = None
        self._done = True

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        shape = self._object_option(options)
        t0 = time.perf_counter()
        rng = np.random.default_rng(int(self.np_random.integers(0, 2**63)))
        ep_rng, noise_rng = rng.spawn(2)
        self.episode = self._draw_episode(ep_rng, shape)
        pts = self.episode.points if len(self.episode.points) else self.episode.T_world_obj[None, :3, 3]
        lo, hi = pts.min(axis=0) - REGION_MARGIN, pts.max(axis=0) + REGION_MARGIN
        lo[2] = max(lo[2], 0.0)
        self._bounds = np.clip(np.stack([lo, hi]), -WORLD_BOUND, WORLD_BOUND).astype(np.float32)
        self._noise_T = self._noise(1, noise_rng)[0]
        self._executed = None
        self._done = False
        self.timing = {"reset": time.perf_counter() - t0}
        info = {"object": self.episode.drawn.to_dict(), "n_points": len(self.episode.points)}
        return self._observation(), info

    def _observation(self) -> dict:
        return {"cloud": self.episode.cloud.copy(), "bounds": self._bounds.copy()}

    # ------------------------------------------------------------------ action <-> pose
    def pose_from_action(self, action) -> tuple[np.ndarray, float] | None:
        """(T_world_wrist (4, 4), contact width [m]) of an action, or None when its
        rotation is degenerate."""
        a = np.clip(np.asarray(action, float).reshape(10), -1.0, 1.0)
        lo, hi = self._bounds.astype(float)
        tcp = lo + 0.5 * (a[0:3] + 1.0) * (hi - lo)
        z, xh = a[3:6], a[6:9]
        nz = np.linalg.norm(z)
        if nz < _DEGENERATE:
            return None
        z = z / nz
        x = xh - (xh @ z) * z
        nx = np.linalg.norm(x)
        if nx < _DEGENERATE:
            return None
        x = x / nx
        R = np.column_stack([x, np.cross(z, x), z])
        g = self.gripper
        opening = g.min_opening + 0.5 * (a[9] + 1.0) * (g.max_opening - g.min_opening)
        return make_transform(R, tcp - self._tcp * z), float(opening - 2.0 * g.approach_clearance)

    def action_from_pose(self, T_world_wrist: np.ndarray, width: float) -> np.ndarray:
        """The action (10,) float32 that proposes wrist pose ``T_world_wrist`` (4, 4)
        with contact width ``width`` [m] (the jaws open to width + 2 x clearance);
        positions outside ``bounds`` are clipped."""
        if self._bounds is None:
            raise GraspsimError("no episode yet: call reset() first")
        T = np.asarray(T_world_wrist, float)
        lo, hi = self._bounds.astype(float)
        tcp = T[:3, 3] + self._tcp * T[:3, 2]
        g = self.gripper
        opening = np.clip(width + 2.0 * g.approach_clearance, g.min_opening, g.max_opening)
        a = np.concatenate([2.0 * (tcp - lo) / np.maximum(hi - lo, 1e-9) - 1.0, T[:3, 2], T[:3, 0],
                            [2.0 * (opening - g.min_opening) / (g.max_opening - g.min_opening) - 1.0]])
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    # ------------------------------------------------------------------ step
    def step(self, action):
        if self._done or self.episode is None:
            raise GraspsimError("the episode has ended (one grasp per episode): call reset() first")
        t0 = time.perf_counter()
        pose = self.pose_from_action(action)
        if pose is None:
            reward, info = 0.0, self._invalid_info()
        else:
            T, width = pose
            T = T @ self._noise_T
            results = self._trials(T[None], [width])
            reward, info = self._outcome_info(results)
            self._executed = (T, width)
            info["T_world_wrist"] = T.copy()
        self._done = True
        self.timing = {**self.timing, "step": time.perf_counter() - t0}
        return self._observation(), float(reward), True, False, info
