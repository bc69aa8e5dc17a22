"""``graspsim/GraspSelect-v0``: pick one of K planned grasps (a contextual bandit).

Each episode is one step. ``reset`` puts a random object on the table (see
:mod:`graspsim.envs.table_task`), takes its sensor cloud, runs the planner on it (paper
2.2-2.5: identification, known/familiar lookup, scaling, combination) and offers K
grasps of the adapted map, drawn at random among those whose gripper stays clear of the
table in the estimated object pose (the planner itself does not know the table). With
``perception="model"`` the planner is given the true primitives and pose instead of the
cloud (no identification error; a much cheaper reset).
``step(k)`` executes candidate k as one trial of the protocol (``lift_place``: grasp,
lift 12 cm, hold, place back) with the robot's execution error, and ends the episode.
The jaws open to the candidate's pre-grasp opening plus the extra gap per side its
robust score chose among ``EnvConfig.openings`` (the ``extra_opening`` column;
``openings=(0.0,)`` executes the map's opening, as the paper).

Observation (``Dict``):

* ``cloud`` (N, 3) float32: the sensor cloud, world frame (z up, table top z = 0) [m];
* ``candidates`` (K, F) float32: one row per candidate, columns
  :data:`~graspsim.envs.candidates.CANDIDATE_FEATURES` (wrist pose in the *estimated*
  object frame, grade and its components, contact width, the planner's robust score
  and clearance to the observed cloud, the extra opening per side the trial uses);
  zeros in invalid slots;
* ``object_pose`` (7,) float32: the estimated object frame in the world, position [m]
  and quaternion (w, x, y, z) -- world pose of a candidate = object_pose @ its pose;
* ``action_mask`` (K,) int8: 1 for the valid candidates (also ``info["action_mask"]``
  and :meth:`GraspSelectEnv.action_masks`, as masking RL libraries expect).

Action: ``Discrete(K)``. An invalid (masked) choice ends the episode with reward 0 and
``info["outcome"] == "invalid_action"``, without a trial. Reward: 1 for SUCCESS, else 0
(``reward="shaped"``: partial credit, see :mod:`graspsim.envs.rewards`). ``info`` has
``outcome`` (label), ``outcome_code``, ``success``, ``metrics`` (slip and force metrics
of the trial; None where not simulated), ``start_penetration``, the chosen
candidate's ``grade`` and the pad gap the jaws opened to, ``opening`` [m].

The execution error of every candidate is drawn at reset, so the trial of candidate k
is fixed for the episode: :meth:`GraspSelectEnv.evaluate_candidates` simulates all of
them (the oracle, or full-information logging) with exactly the outcomes ``step``
would give, without ending the episode.

Vectorised: one-step episodes want ``autoreset_mode=AutoresetMode.SAME_STEP``
(``gymnasium.make_vec(..., vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP})``):
every ``step`` then returns the reward of the chosen grasp and already the *next*
episode's observation (the finished one in ``info["final_obs"]``). With the default
NEXT_STEP mode every other ``step`` call is a reset that ignores its action and
returns reward 0.
"""

from __future__ import annotations

import logging
import time

import numpy as np
from gymnasium import spaces

from graspsim.envs.candidates import CANDIDATE_FEATURES, candidate_features, feature_bounds
from graspsim.envs.env_config import EnvConfig, Perception
from graspsim.envs.table_task import WORLD_BOUND, TableTask, pose_vector
from graspsim.errors import GraspsimError, InvalidParameterError, NoFeasibleGraspError
from graspsim.geometry.table import TablePlane
from graspsim.maps.robust import RobustConfig, executed_width
from graspsim.maps.scaling import ScalingConfig
from graspsim.perception import IdentifyConfig
from graspsim.planning.planner import PlannerConfig, PlanResult, plan, plan_shape

__all__ = ["GraspSelectEnv"]

log = logging.getLogger(__name__)


class GraspSelectEnv(TableTask):
    """Choose one of K candidate grasps of an object seen as a point cloud (see the
    module docstring). Keyword arguments are :class:`EnvConfig` fields."""

    def __init__(self, render_mode: str | None = None, *, config: EnvConfig | None = None, **kwargs):
        super().__init__(render_mode, config=config, **kwargs)
        c = self.config
        K, N, F = c.n_candidates, c.cloud_size, len(CANDIDATE_FEATURES)
        lo, hi = feature_bounds()
        self.observation_space = spaces.Dict({
            "cloud": spaces.Box(-WORLD_BOUND, WORLD_BOUND, (N, 3), np.float32),
            "candidates": spaces.Box(np.tile(lo, (K, 1)), np.tile(hi, (K, 1)), (K, F), np.float32),
            "object_pose": spaces.Box(-WORLD_BOUND, WORLD_BOUND, (7,), np.float32),
            "action_mask": spaces.MultiBinary(K),
        })
        self.action_space = spaces.Discrete(K)
        # small scaling batches go to the branch-and-bound collision check, which needs
        # no per-object set-up: the fastest for pools of a few hundred grasps; the table
        # (world z = 0) is known, so robust scores count perturbations into it; no
        # observed-points filter and no feature grasps: the candidates are the planner's
        # scored grasps as the environments' baselines (E06, E08) were measured with, and
        # a feature grasp's score leaves out the primitives term the others include
        self.planner_config = PlannerConfig(
            identify=IdentifyConfig(repetitions=c.identify_repetitions),
            scaling=ScalingConfig(first_batch=48, growth=1.0), build_missing=False,
            table=TablePlane(height=0.0, clearance=c.table_margin),
            robust=RobustConfig(openings=c.openings, **c.robust_sigmas()), clear_observed=False, features=None)
        self.plan_result: PlanResult | None = None
        self._obs: dict | None = None
        self._cand: dict | None = None
        self._done = True

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        shape = self._object_option(options)
        c = self.config
        t0 = time.perf_counter()
        for draw in range(c.max_redraws):
            rng = np.random.default_rng(int(self.np_random.integers(0, 2**63)))
            ep_rng, plan_rng, pick_rng, noise_rng = rng.spawn(4)
            episode = self._draw_episode(ep_rng, shape)
            t1 = time.perf_counter()
            if c.perception is Perception.MODEL:
                result = plan_shape(episode.drawn.shape, episode.T_world_obj, db=self.db,
                                    config=self.planner_config, source="graspsim.envs")
            else:
                result = plan(episode.points, db=self.db, rng=plan_rng, config=self.planner_config,
                              source="graspsim.envs", viewpoint=episode.viewpoint)
            t_plan = time.perf_counter() - t1
            gmap = result.map
            T_world_wrist = result.T_cloud_obj @ gmap.T_obj_wrist  # the cloud frame is the world
            clear = np.zeros(len(gmap), bool)
            if len(gmap):
                clear = self.gripper.lowest_point(
                    T_world_wrist, self.gripper.pregrasp_opening(gmap.width)) > c.table_margin
            if clear.any():
                break
            log.debug("redraw %d (%s): %s plan, %d grasps, none clear of the table", draw + 1,
                      episode.drawn.kind, result.status.value, len(gmap))
        else:
            raise NoFeasibleGraspError(
                f"no object drawn in {c.max_redraws} tries offered a grasp clear of the table "
                f"(objects={c.objects!r}); raise max_redraws or check the map database at {self.db.root}")
        K = c.n_candidates
        rows = pick_rng.permutation(np.flatnonzero(clear))[:K]
        mask = np.zeros(K, np.int8)
        mask[:len(rows)] = 1
        T_nominal = np.repeat(np.eye(4)[None], K, axis=0)
        T_nominal[:len(rows)] = T_world_wrist[rows]
        map_width = np.zeros(K)
        map_width[:len(rows)] = gmap.width[rows]
        width = map_width.copy()  # the jaws open width + 2 x (approach clearance + extra)
        width[:len(rows)] = executed_width(gmap, rows)
        self.episode = episode
        self.plan_result = result
        noise = self._noise(K, noise_rng)
        self._cand = {"rows": rows, "T_world_wrist": T_nominal, "width": width, "map_width": map_width,
                      "mask": mask, "noise": noise, "noise_extra": self._noise(1, noise_rng)[0]}
        self._obs = {"cloud": episode.cloud, "candidates": candidate_features(gmap, rows, K),
                     "object_pose": np.clip(pose_vector(result.T_cloud_obj), -WORLD_BOUND, WORLD_BOUND),
                     "action_mask": mask}
        self._executed = None
        self._done = False
        self.timing = {"reset": time.perf_counter() - t0, "plan": t_plan, "draws": draw + 1,
                       **{f"plan_{k}": v for k, v in result.timing.items() if isinstance(v, float)}}
        info = {"action_mask": mask.copy(), "object": episode.drawn.to_dict(),
                "plan_status": result.status.value, "parts": [p.primitive.kind for p in result.parts],
                "n_grasps": len(gmap), "n_clear": int(clear.sum()), "redraws": draw}
        return self._observation(), info

    def _observation(self) -> dict:
        return {k: v.copy() for k, v in self._obs.items()}

    # ------------------------------------------------------------------ step
    def step(self, action):
        if self._done or self._cand is None:
            raise GraspsimError("the episode has ended (one grasp per episode): call reset() first")
        a = int(action)
        if not 0 <= a < self.config.n_candidates:
            raise InvalidParameterError(f"action must be in [0, {self.config.n_candidates}), got {action!r}")
        t0 = time.perf_counter()
        cand = self._cand
        if cand["mask"][a]:
            T = cand["T_world_wrist"][a] @ cand["noise"][a]
            results = self._trials(T[None], cand["width"][a:a + 1])
            reward, info = self._outcome_info(results)
            self._executed = (T, float(cand["width"][a]))
        else:
            reward, info = 0.0, self._invalid_info()
        self._done = True
        self.timing = {**self.timing, "step": time.perf_counter() - t0}
        info.update(action_mask=cand["mask"].copy(), candidate=a,
                    grade=float(self._obs["candidates"][a, CANDIDATE_FEATURES.index("grade")]),
                    opening=float(self.gripper.pregrasp_opening(cand["width"][a])) if cand["mask"][a] else None)
        return self._observation(), float(reward), True, False, info

    # ------------------------------------------------------------------ helpers
    @property
    def candidate_rows(self) -> np.ndarray:
        """(n,) rows of ``plan_result.map`` offered as the valid candidates, in slot order."""
        if self._cand is None:
            raise GraspsimError("no episode yet: call reset() first")
        return self._cand["rows"].copy()

    def action_masks(self) -> np.ndarray:
        """(K,) bool: the valid candidates of the current episode."""
        if self._cand is None:
            raise GraspsimError("no episode yet: call reset() first")
        return self._cand["mask"].astype(bool)

    def evaluate_map_rows(self, rows, *, execution_error: bool = True) -> np.ndarray:
        """TrialOutcome codes (n,) int8 of rows of ``plan_result.map`` -- offered or not
        -- executed as a candidate would be (the jaws at the opening its robust score
        chose), each with one more execution error draw of the episode (not a
        candidate's). For policies that pick from the whole map instead of the K
        candidates (e.g. the planner's robust best) in experiments; not something a
        policy may call."""
        if self._cand is None or self.plan_result is None:
            raise GraspsimError("no episode yet: call reset() first")
        gmap = self.plan_result.map
        rows = np.asarray(rows, int).reshape(-1)
        if len(rows) and (rows.min() < 0 or rows.max() >= len(gmap)):
            raise InvalidParameterError(f"rows must index the plan's map of {len(gmap)} grasps, got {rows!r}")
        if not len(rows):
            return np.zeros(0, np.int8)
        T = self.plan_result.T_cloud_obj @ gmap.T_obj_wrist[rows]
        if execution_error:
            T = T @ self._cand["noise_extra"]
        return self._trials(T, executed_width(gmap, rows)).outcome.astype(np.int8)

    def evaluate_candidates(self, threads: int | None = None, *, execution_error: bool = True,
                            map_opening: bool = False, slots=None) -> dict[str, np.ndarray]:
        """Simulate every valid candidate of the current episode as ``step`` would (same
        execution error), without ending it: ``outcome`` (K,) int8 TrialOutcome codes
        (-1 for invalid slots), ``reward`` (K,) float32, ``success`` (K,) bool. With
        ``execution_error=False`` the nominal poses are simulated instead (what the
        episode would give without execution error). With ``map_opening=True`` the jaws
        open to the map's pre-grasp opening instead of the one the robust score chose
        (``EnvConfig.openings``; the same when that is ``(0.0,)``). ``slots``: simulate
        only these candidates (the others read as invalid). For oracles,
        ablations and full-information logging; not something a policy may call."""
        if self._cand is None:
            raise GraspsimError("no episode yet: call reset() first")
        cand = self._cand
        K = self.config.n_candidates
        idx = np.flatnonzero(cand["mask"])
        if slots is not None:
            idx = np.intersect1d(idx, np.asarray(slots, int).reshape(-1))
        outcome = np.full(K, -1, np.int8)
        reward = np.zeros(K, np.float32)
        if len(idx):
            T = cand["T_world_wrist"][idx]
            if execution_error:
                T = T @ cand["noise"][idx]
            width = cand["map_width" if map_opening else "width"][idx]
            res = self._trials(T, width, threads=threads or self.config.threads)
            outcome[idx] = res.outcome
            for j, i in enumerate(idx):
                reward[i] = self._outcome_info(res, j)[0]
        return {"outcome": outcome, "reward": reward, "success": outcome == 0}
