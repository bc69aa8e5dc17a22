"""What both grasp environments share: an object on a table, its sensor cloud, trials.

Frames. The environment's *world* has z up and the table top at z = 0. An episode's
object rests on the table in its stable pose (``graspsim.sim.resting_pose``), turned
by a random yaw and moved to a random (x, y): ``T_world_obj``. The sensor cloud is in
the world frame (a calibrated camera), with the table segmented out (points below
``table_cut``). The trial scene of :mod:`graspsim.sim` holds the same object at rest
over its own origin; since the table is a uniform plane the two are the same physics,
and a world wrist pose is simulated as ``T_obj_wrist = inv(T_world_obj) @ T_world_wrist``
in the true object frame (perception errors of the planner's estimated frame carry
over, as on a real robot).

Every random draw of an episode comes from one generator spawned off the
environment's ``np_random`` at reset, split into independent streams (object, cloud,
planner, candidates, execution noise), so an episode is a function of the seed.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from graspsim.envs.candidates import PooledDatabase
from graspsim.envs.env_config import EnvConfig, View, make_config
from graspsim.envs.object_sets import DrawnObject, draw_object, resolve_object_set
from graspsim.envs.render import FrameRenderer
from graspsim.envs.rewards import trial_reward
from graspsim.errors import InvalidParameterError
from graspsim.maps.database import PAPER_SHAPES
from graspsim.primitives import Compound, Primitive, synthetic_cloud
from graspsim.sim.batch import run_trials
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.objects import object_from_shape
from graspsim.sim.outcomes import TrialOutcome
from graspsim.sim.protocols import Protocol, make_protocol
from graspsim.sim.results import TrialResults
from graspsim.sim.trial_scene import Scene, SimSettings, build_scene
from graspsim.transforms import invert_transform, make_transform, matrix_to_quat

__all__ = ["TableEpisode", "TableTask", "pose_vector", "database"]

log = logging.getLogger(__name__)

#: Bound of every observed coordinate [m] (objects land within ~0.35 m of the origin).
WORLD_BOUND = 1.0


@functools.lru_cache(maxsize=4)
def database(root: str | None, map_config, pool_size: int, gripper=None) -> PooledDatabase:
    """The pooled map database at ``root`` of ``gripper`` (a name, spec .json or spec;
    None: the Festo), with the five reference FS maps built on first use."""
    from graspsim.grippers import get_gripper

    db = PooledDatabase(root, gripper=get_gripper(gripper), config=map_config, pool_size=pool_size)
    missing = [s for s in PAPER_SHAPES.values() if not db.contains(s)]
    if missing:
        log.info("building %d reference FS maps in %s (first use)", len(missing), db.root)
        db.build(PAPER_SHAPES.values())
    return db


def pose_vector(T: np.ndarray) -> np.ndarray:
    """(..., 7) float32 position [m] and quaternion (w, x, y, z) of transforms (..., 4, 4)."""
    T = np.asarray(T, float)
    return np.concatenate([T[..., :3, 3], matrix_to_quat(T[..., :3, :3])], axis=-1).astype(np.float32)


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class TableEpisode:
    """One object on the table. scene: the trial scene; T_world_obj: (4, 4) the true
    object pose in the world; points: (M, 3) the segmented sensor cloud, world [m];
    cloud: (N, 3) float32 the observed fixed-size sample of it; viewpoint: (3,) the
    camera's position, world [m], for a single view (None: seen all round)."""

    drawn: DrawnObject
    scene: Scene
    T_world_obj: np.ndarray
    points: np.ndarray
    cloud: np.ndarray
    viewpoint: np.ndarray | None = None


class TableTask(gym.Env):
    """Base class: configuration, episode drawing, trials, rewards and rendering."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, render_mode: str | None = None, *, config: EnvConfig | None = None, **kwargs):
        self.config = make_config(config, **kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidParameterError(
                f"render_mode {render_mode!r} not supported; valid: {self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        c = self.config
        self.kinds = resolve_object_set(c.objects)
        if isinstance(c.protocol, Protocol):
            self.protocol = c.protocol
        elif isinstance(c.protocol, str):
            self.protocol = make_protocol(c.protocol)
        else:
            raise InvalidParameterError(
                f"protocol must be a name ('lift_place', 'tug') or a Protocol, got {c.protocol!r}")
        self.settings = SimSettings()
        self.noise = (ExecutionNoise(c.position_noise, c.rotation_noise)
                      if c.position_noise > 0 or c.rotation_noise > 0 else None)
        self.db = database(c.db_root, c.map_config, c.pool_size, c.gripper)
        self.gripper = self.db.gripper
        self._renderer: FrameRenderer | None = None
        self.episode: TableEpisode | None = None
        self._executed: tuple[np.ndarray, float] | None = None  # (T_world_wrist, width) of the trial
        self.timing: dict[str, float] = {}

    # ------------------------------------------------------------------ episodes
    @staticmethod
    def _object_option(options: dict | None):
        """The ``object`` reset option (a shape to use instead of a random draw), the
        only one the environments take."""
        opts = dict(options or {})
        shape = opts.pop("object", None)
        if opts:
            raise InvalidParameterError(f"unknown reset option(s) {sorted(opts)}; valid: ['object']")
        return shape

    def _draw_episode(self, rng: np.random.Generator, shape=None) -> TableEpisode:
        """An object (``shape`` or a random member of the set) placed on the table and
        its sensor cloud, from the generator ``rng``."""
        c = self.config
        obj_rng, place_rng, cloud_rng, sample_rng = rng.spawn(4)
        if shape is None:
            drawn = draw_object(self.kinds, obj_rng, lying=c.lying, gripper=self.gripper)
        elif isinstance(shape, (Primitive, Compound)):
            drawn = DrawnObject("custom", shape)
        else:
            raise InvalidParameterError(
                f"options['object'] must be a Primitive or Compound, got {type(shape).__name__}")
        scene = build_scene(object_from_shape(drawn.shape), self.gripper, self.settings,
                            table=self.protocol.table, gravity=self.protocol.gravity)
        T_rest = scene.T_world_obj if self.protocol.table else _rest_for_cloud(drawn.shape, scene)
        xy = place_rng.uniform(-c.placement, c.placement, 2)
        T_place = make_transform(_yaw(place_rng.uniform(0.0, 2.0 * math.pi)), [xy[0], xy[1], 0.0])
        T_world_obj = T_place @ T_rest
        camera = None
        if c.view is View.SINGLE:
            az, el = place_rng.uniform(0.0, 2.0 * math.pi), place_rng.uniform(math.radians(25), math.radians(65))
            eye = T_world_obj[:3, 3] + c.camera_distance * np.array(
                [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
            camera = (invert_transform(T_world_obj) @ np.append(eye, 1.0))[:3]
        sc = synthetic_cloud(drawn.shape, cloud_rng, resolution=c.cloud_resolution, noise=c.cloud_noise,
                             outliers=c.cloud_outliers, camera=camera, T_world_obj=T_world_obj)
        pts = sc.points[sc.points[:, 2] > c.table_cut]
        pts = np.clip(pts, -WORLD_BOUND, WORLD_BOUND)
        n = c.cloud_size
        pick = (sample_rng.choice(len(pts), n, replace=len(pts) < n) if len(pts) else np.zeros(n, int))
        cloud = (pts[pick] if len(pts) else np.zeros((n, 3))).astype(np.float32)
        return TableEpisode(drawn, scene, T_world_obj, pts, cloud, None if camera is None else eye)

    # ------------------------------------------------------------------ trials
    def _trials(self, T_world_wrist: np.ndarray, widths: np.ndarray, threads: int = 1) -> TrialResults:
        """Simulate world wrist poses (n, 4, 4) with contact widths (n,) [m] on the
        episode's object (no further noise: the caller applied it)."""
        ep = self.episode
        T_obj = invert_transform(ep.T_world_obj) @ np.asarray(T_world_wrist, float).reshape(-1, 4, 4)
        return run_trials(ep.scene, T_obj, np.asarray(widths, float).reshape(-1), self.protocol,
                          threads=threads, noise=None)

    def _noise(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 4, 4) execution errors T_wrist_executed to right-multiply onto wrist poses
        (identity without noise), drawn once per episode so a candidate's trial is fixed."""
        if self.noise is None:
            return np.repeat(np.eye(4)[None], n, axis=0)
        return self.noise.sample(n, rng, pivot=self.gripper.nominal_tcp)

    def _outcome_info(self, results: TrialResults, i: int = 0) -> tuple[float, dict]:
        """Reward and info entries of trial ``i`` of ``results``."""
        code = int(results.outcome[i])
        metrics = {k: (float(v[i]) if np.isfinite(v[i]) else None) for k, v in results.metrics.items()}
        reward = trial_reward(self.config.reward, code, metrics, results.protocol)
        return reward, {"outcome": TrialOutcome(code).label, "outcome_code": code,
                        "success": code == TrialOutcome.SUCCESS, "metrics": metrics,
                        "start_penetration": float(results.start_penetration[i])}

    @staticmethod
    def _invalid_info() -> dict:
        return {"outcome": "invalid_action", "outcome_code": -1, "success": False, "metrics": {},
                "start_penetration": None}

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode != "rgb_array" or self.episode is None:
            return None
        if self._renderer is None:
            self._renderer = FrameRenderer()
        ep = self.episode
        if self._executed is None:
            return self._renderer.scene_frame(ep.scene)
        T_world_wrist, width = self._executed
        T_scene = ep.scene.T_world_obj @ invert_transform(ep.T_world_obj) @ T_world_wrist
        return self._renderer.trial_frame(ep.scene, T_scene, width, self.protocol)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _rest_for_cloud(shape, scene: Scene) -> np.ndarray:
    """Without a table (``tug``) the object still stands on the table for the camera:
    its resting pose (the scene itself keeps it at the origin)."""
    from graspsim.sim.trial_scene import resting_pose

    return resting_pose(scene.obj)
