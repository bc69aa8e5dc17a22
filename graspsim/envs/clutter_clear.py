"""``graspsim/ClutterClear-v0``: clear a table of several objects, one chosen grasp a step.

The clutter-removal protocol of :mod:`graspsim.tabletop.clutter` with a policy choosing the
grasp. ``reset`` draws a settled table-top scene (:func:`graspsim.tabletop.table_scene.make_scene`:
``n_objects`` of ``object_set``, ``"pile"`` or ``"packed"``), renders it with one
D435-like depth camera and plans it (table, segments, every segment planned, grasps
checked against the whole scene: :func:`graspsim.planning.scene.plan_scene`); the
scene's K best grasps are the candidates (less the twins of grasps that failed earlier in
the episode, which the protocol does not try again). ``step(k)`` executes candidate k (close, lift;
a lifted object leaves the scene), renders and plans again. Every step of this loop is
:class:`graspsim.tabletop.clutter.ClutterEpisode`'s, the same code the ``graspsim scene``
benchmark runs; only the choice is the policy's.

Observation (``Dict``):

* ``cloud`` (N, 3) float32: a fixed-size sample (repeats when fewer) of the depth frame's
  back-projected points above the fitted table, thinned to the planner's 3 mm grid,
  world frame (z up, table top z = 0) [m], clipped to +-2 m; zeros when none;
* ``segment`` (N,) int64: each cloud point's segment (-1: noise, or an empty slot);
* ``candidates`` (K, F) float32: one row per candidate, columns :data:`CLUTTER_FEATURES`
  (the segment it grasps, the wrist pose in the world -- position [m], quaternion w, x,
  y, z -- the jaw opening [m], the robust score against the whole scene, the map's
  grade, the gripper's clearance to the observed points [m], clipped to +-5 cm); zeros
  in invalid slots;
* ``action_mask`` (K,) int8: 1 for the valid candidates (also ``info["action_mask"]``
  and :meth:`ClutterClearEnv.action_masks`);
* ``depth`` (H, W) float32 [m], with ``depth_image=True``: the depth image (0: no depth).

Action: ``Discrete(K)``. Reward: 1 when the grasp lifts its target (the object most of
the chosen segment's points show) out of the scene, else 0 -- the protocol's success; a
grasp that lifts another object gets 0 (``info["outcome"] == "success_other_object"``),
though that object leaves the scene too.
Termination: the table is clear, ``max_failures`` (2) consecutive grasps failed, or no
grasp with a robust score > 0 is left (with ``robot="panda"``: or none the arm reaches,
``"unreachable"``); also a masked (invalid) choice, which ends the
episode with reward 0 and ``info["outcome"] == "invalid_action"`` without a grasp.
With ``robot="panda"`` the Panda arm executes the chosen grasp (``graspsim scene --robot
panda``'s execution); one it cannot reach or approach is a failed grasp, never executed.
Truncation: ``max_attempts`` grasps (default 2 x objects + 2) were executed. ``info``
has ``stop`` (None while running; else :data:`graspsim.tabletop.clutter.STOPS` or
``"invalid_action"``), ``removed``, ``attempts``, ``objects_left`` and, after a grasp, its
``outcome`` (the cause: ``success``, ``start_collision_neighbour``, ...), ``success``,
``target`` and ``picked``. ``reset(options={"scene": TableScene})`` plays a given scene.
"""

from __future__ import annotations

import contextlib
import time

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from graspsim.envs.clutter_config import ClutterEnvConfig, make_clutter_config
from graspsim.errors import GraspsimError, InvalidParameterError, NoFeasibleGraspError

__all__ = ["ClutterClearEnv", "CLUTTER_FEATURES"]

#: Columns of the ``candidates`` observation.
CLUTTER_FEATURES = ("segment", "x", "y", "z", "qw", "qx", "qy", "qz", "opening", "score", "grade", "clearance")
CLOUD_BOUND = 2.0  # [m]
MAX_SEGMENTS = 255
MAX_DEPTH = 10.0  # [m]
_CLEARANCE_CAP = 0.05
_BAR_DELAY = 2.0  # [s] progress bars show once work takes longer (cached meshes and stored maps: quiet)
#: terminated ("unreachable": with an arm); "max_attempts": truncated
_ENDS = {"cleared", "failures", "no_grasp", "unreachable", "invalid_action"}


class ClutterClearEnv(gym.Env):
    """Clear a table-top scene grasp by grasp (see the module docstring). Keyword
    arguments are :class:`~graspsim.envs.clutter_config.ClutterEnvConfig` fields."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 2}

    def __init__(self, render_mode: str | None = None, *, config: ClutterEnvConfig | None = None, **kwargs):
        from graspsim.geometry.camera import rig
        from graspsim.grippers import get_gripper
        from graspsim.maps.database import MapDatabase
        from graspsim.sim.noise import ExecutionNoise
        from graspsim.sim.trial_scene import contact_settings
        from graspsim.tabletop.clutter import ClutterConfig, ClutterRobot, scene_settings
        from graspsim.tabletop.depth_noise import DepthNoise

        self.config = c = make_clutter_config(config, **kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidParameterError(
                f"render_mode {render_mode!r} not supported; valid: {self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self.db = MapDatabase(c.db_root, gripper=get_gripper(c.gripper), config=c.map_config)
        self.clutter_config = ClutterConfig(
            scene=scene_settings(c.kind, neighbours=c.neighbours), depth_noise=DepthNoise() if c.depth_noise else None,
            execution=ExecutionNoise() if c.execution_error else None, max_failures=c.max_failures,
            max_attempts=c.max_attempts, good_enough=None,  # the candidates: every object's best grasps
            robot=None if c.robot == "none" else ClutterRobot(name=c.robot, base=c.robot_base),
            sim=contact_settings(c.contacts))
        self.camera = rig(1)[0]
        K, N, F = c.n_candidates, c.cloud_size, len(CLUTTER_FEATURES)
        lo = np.array([0, *[-CLOUD_BOUND] * 3, *[-1.0] * 4, 0, 0, 0, -_CLEARANCE_CAP], np.float32)
        hi = np.array([MAX_SEGMENTS, *[CLOUD_BOUND] * 3, *[1.0] * 4, self.db.gripper.max_opening, 1, 1,
                       _CLEARANCE_CAP], np.float32)
        obs = {"cloud": spaces.Box(-CLOUD_BOUND, CLOUD_BOUND, (N, 3), np.float32),
               "segment": spaces.Box(-1, MAX_SEGMENTS, (N,), np.int64),
               "candidates": spaces.Box(np.tile(lo, (K, 1)), np.tile(hi, (K, 1)), (K, F), np.float32),
               "action_mask": spaces.MultiBinary(K)}
        if c.depth_image:
            k = self.camera.intrinsics
            obs["depth"] = spaces.Box(0.0, MAX_DEPTH, (k.height, k.width), np.float32)
        self.observation_space = spaces.Dict(obs)
        self.action_space = spaces.Discrete(K)
        self.episode = None  # the ClutterEpisode
        self._look = None  # the ClutterFrame the candidates come from
        self._frame = None  # the latest depth frame
        self._obs: dict | None = None
        self._stop: str | None = None
        self._scenes: dict[int, object] = {}  # drawn scenes by seed (a seeded reset settles once)
        self._prepared = False  # the object set's meshes prepared (the first reset that draws a scene)
        self.timing: dict[str, float] = {}

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        opts = dict(options or {})
        given = opts.pop("scene", None)
        if opts:
            raise InvalidParameterError(f"unknown reset option(s) {sorted(opts)}; valid: ['scene']")
        t0 = time.perf_counter()
        tries = 1 if given is not None else self.config.max_redraws
        with self._bars():
            if given is None and not self._prepared:  # the set's meshes, once (graspsim scene does the same)
                from graspsim.tabletop.scene_objects import prepare_objects

                prepare_objects(self.config.object_set, self.db.gripper, progress=self.config.progress,
                                delay=_BAR_DELAY)
                self._prepared = True
            for _ in range(tries):
                scene = given if given is not None else self._draw_scene()
                ep_rng, sample_rng = np.random.default_rng(int(self.np_random.integers(0, 2**63))).spawn(2)
                self._start(scene, ep_rng, sample_rng)
                if self._look is not None:
                    break
        if self._look is None:
            what = "the given scene" if given is not None else f"{tries} scenes drawn"
            raise NoFeasibleGraspError(f"{what} offered no grasp with a robust score > 0 in the first frame")
        self.timing = {"reset": time.perf_counter() - t0, "planning": self._look.planning}
        return self._observation(), self._info()

    @contextlib.contextmanager
    def _bars(self):
        """Progress bars (``config.progress``) for FS maps built while planning, unless the
        caller set its own: each drawn at once when the reset or step has already taken
        ``_BAR_DELAY`` (several short builds in a row are not silent), else after the rest of it."""
        from graspsim.maps.database import BUILD_PROGRESS

        if not self.config.progress or BUILD_PROGRESS.get() is not None:
            yield
            return
        from graspsim._progress import map_build_bar

        shown = time.monotonic() + _BAR_DELAY  # bars once the reset or step has taken that long

        def bar(shape):
            return map_build_bar(shape, delay=max(0.0, shown - time.monotonic()))

        token = BUILD_PROGRESS.set(bar)
        try:
            yield
        finally:
            BUILD_PROGRESS.reset(token)

    def _draw_scene(self):
        from graspsim.tabletop.table_scene import make_scene

        c = self.config
        seed = int(self.np_random.integers(0, 2**31))
        if seed not in self._scenes:
            if len(self._scenes) >= 8:
                self._scenes.pop(next(iter(self._scenes)))
            sim = self.clutter_config.sim
            self._scenes[seed] = make_scene(c.n_objects, c.kind, seed, object_set=c.object_set,
                                            gripper=self.db.gripper, **({} if sim is None else {"settings": sim}))
        return self._scenes[seed]

    def _start(self, scene, ep_rng: np.random.Generator, sample_rng: np.random.Generator) -> None:
        from graspsim.tabletop.clutter import ClutterEpisode
        from graspsim.tabletop.table_scene import TableScene

        if not isinstance(scene, TableScene):
            raise InvalidParameterError(f"options['scene'] must be a TableScene, got {type(scene).__name__}")
        if self.episode is not None:
            self.episode.close()
        self.episode = ClutterEpisode(scene, db=self.db, rng=ep_rng, config=self.clutter_config,
                                      camera=self.camera, rgb=self.render_mode == "rgb_array")
        self._sample_rng = sample_rng
        self._stop = None
        self._look = self.episode.observe()
        self._observe()

    # ------------------------------------------------------------------ step
    def step(self, action):
        ep = self.episode
        if ep is None or self._stop is not None:
            raise GraspsimError("the episode has ended: call reset() first")
        a = int(action)
        if not 0 <= a < self.config.n_candidates:
            raise InvalidParameterError(f"action must be in [0, {self.config.n_candidates}), got {action!r}")
        t0 = time.perf_counter()
        mask = self._obs["action_mask"]
        if not mask[a]:
            self._stop = "invalid_action"
            info = self._info(outcome="invalid_action", success=False, target=None, picked=None, candidate=a)
            return self._observation(), 0.0, True, False, info
        attempt = ep.execute(self._look, self._look.candidates[a])
        with self._bars():
            self._look = ep.observe() if ep.stop is None else None
        self._stop = ep.stop
        self._observe()
        self.timing = {"step": time.perf_counter() - t0,
                       "planning": self._look.planning if self._look is not None else 0.0}
        info = self._info(outcome=attempt.cause, success=attempt.success, target=attempt.target,
                          picked=attempt.outcome["picked"], candidate=a)
        return (self._observation(), float(attempt.success), self._stop in _ENDS, self._stop == "max_attempts",
                info)

    # ------------------------------------------------------------------ observations
    def _observe(self) -> None:
        """The observation of the latest look, or of a fresh frame when the episode
        ended (nothing planned: no candidates)."""
        c = self.config
        look = self._look
        if look is not None:
            frame, per = look.frame, look.plan.perception
        else:
            frame, per = self._perceive_final()
        pts = per.points if per is not None else np.zeros((0, 3))
        labels = per.segment if per is not None else np.zeros(0, int)
        n = c.cloud_size
        pick = self._sample_rng.choice(len(pts), n, replace=len(pts) < n) if len(pts) else np.zeros(0, int)
        cloud = np.zeros((n, 3), np.float32)
        segment = np.full(n, -1, np.int64)
        cloud[:len(pick)] = np.clip(pts[pick], -CLOUD_BOUND, CLOUD_BOUND)
        segment[:len(pick)] = np.minimum(labels[pick], MAX_SEGMENTS)
        grasps = look.candidates[:c.n_candidates] if look is not None else ()
        mask = np.zeros(c.n_candidates, np.int8)
        mask[:len(grasps)] = 1
        self._frame = frame
        self._obs = {"cloud": cloud, "segment": segment, "candidates": _features(grasps, c.n_candidates),
                     "action_mask": mask}
        if c.depth_image:
            self._obs["depth"] = np.asarray(frame.depth, np.float32)

    def _perceive_final(self):
        """A fresh frame of the ended episode and its table and segments (None when the
        camera sees too little for a table fit)."""
        from graspsim.errors import PointCloudError
        from graspsim.geometry.camera import backproject
        from graspsim.planning.scene import perceive_scene

        frame = self.episode.render()
        try:
            per = perceive_scene(backproject(frame).world(), self._sample_rng, self.clutter_config.scene)
        except PointCloudError:
            per = None
        return frame, per

    def _observation(self) -> dict:
        return {k: v.copy() for k, v in self._obs.items()}

    def _info(self, **extra) -> dict:
        ep = self.episode
        return {"action_mask": self._obs["action_mask"].copy(), "stop": self._stop, "removed": ep.removed,
                "attempts": len(ep.attempts), "objects_left": list(ep.sim.objects_left()),
                "segments": 0 if self._look is None else self._look.plan.perception.n_segments, **extra}

    def action_masks(self) -> np.ndarray:
        """(K,) bool: the valid candidates now."""
        if self._obs is None:
            raise GraspsimError("no episode yet: call reset() first")
        return self._obs["action_mask"].astype(bool)

    # ------------------------------------------------------------------ rendering
    def render(self):
        """The camera's colour image (H, W, 3) uint8 of the latest frame (``rgb_array``)."""
        if self.render_mode != "rgb_array" or self._frame is None or self._frame.rgb is None:
            return None
        return np.array(self._frame.rgb, np.uint8)

    def close(self):
        if self.episode is not None:
            self.episode.close()


def _features(grasps, K: int) -> np.ndarray:
    """(K, F) float32 :data:`CLUTTER_FEATURES` rows of SceneGrasps (zeros past them)."""
    from graspsim.transforms import matrix_to_quat

    out = np.zeros((K, len(CLUTTER_FEATURES)), np.float32)
    for i, g in enumerate(grasps):
        T = g.T_world_wrist
        out[i] = [min(g.segment, MAX_SEGMENTS), *np.clip(T[:3, 3], -CLOUD_BOUND, CLOUD_BOUND),
                  *matrix_to_quat(T[:3, :3]), g.opening, np.clip(g.score, 0, 1), np.clip(g.grade, 0, 1),
                  np.clip(g.clearance, -_CLEARANCE_CAP, _CLEARANCE_CAP)]
    return out
