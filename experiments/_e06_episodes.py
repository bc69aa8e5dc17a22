"""E06's logged episodes of ``graspsim/GraspSelect-v0``: every candidate of an episode
simulated (``evaluate_candidates``, with and without the execution error), its features
and the robust score's ablations recorded, then the highest-grade candidate stepped
(which must agree). Episode i of split s (0 training, 1 test) resets with
``derived_seed(seed, s, i)``, so the log does not depend on the number of workers.
``cfg`` is an ``E06Config`` (``e06_env_baselines.py``)."""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from _common import Clock, derived_seed

from graspsim.envs.baselines import grasp_features, highest_grade_policy
from graspsim.envs.candidates import CANDIDATE_FEATURES
from graspsim.maps.robust import ABLATIONS, cloud_in_object, ranking, score_rows

if TYPE_CHECKING:
    from e06_env_baselines import E06Config

__all__ = ["collect", "run_episode"]

log = logging.getLogger("e06")


_ENV = None


def _env(cfg: E06Config):
    global _ENV
    if _ENV is None:
        import gymnasium as gym

        _ENV = gym.make("graspsim/GraspSelect-v0", **cfg.env_kwargs()).unwrapped
    return _ENV


def ablation_scores(env, cfg: E06Config) -> np.ndarray:
    """(len(ABLATIONS), K) robust scores of the episode's candidates under each ablation
    (0 in invalid slots), from the plan the environment made."""
    res, rows = env.plan_result, env.candidate_rows
    cloud = cloud_in_object(env.episode.points, res.T_cloud_obj) if cfg.perception == "cloud" else None
    out = np.zeros((len(ABLATIONS), cfg.k), np.float32)
    for j, kw in enumerate(ABLATIONS.values()):
        cfg_j = replace(env.planner_config.robust, **kw)
        out[j, :len(rows)] = score_rows(res.map, rows, cloud, cfg_j).robust
    return out


def map_opening_choices(env, obs, cfg: E06Config) -> dict:
    """The paper's setting on the same episode (test split): the highest-grade candidate
    and the best candidate by the robust score at the map's opening only, both executed
    at the map's opening (the candidate's execution error), and the planner's robust
    best of the whole adapted map (not only the K candidates) executed at its chosen
    opening with the episode's extra execution error draw. Outcome codes; -1: none."""
    res, rows = env.plan_result, env.candidate_rows
    cloud = cloud_in_object(env.episode.points, res.T_cloud_obj) if cfg.perception == "cloud" else None
    at_map = score_rows(res.map, rows, cloud, replace(env.planner_config.robust, openings=(0.0,))).robust
    grade = obs["candidates"][:len(rows), CANDIDATE_FEATURES.index("grade")].astype(float)
    a_hg = highest_grade_policy(obs)
    a_rm = int(np.lexsort((-grade, -np.round(at_map, 6)))[0]) if len(rows) else 0
    ev = env.evaluate_candidates(threads=1, map_opening=True, slots=[a_hg, a_rm])["outcome"]
    planner = -1
    if len(res.map) and (not res.map.has_robust or res.map.robust[ranking(res.map)[0]] > 0):
        planner = int(env.evaluate_map_rows([ranking(res.map)[0]])[0])
    return {"highest_grade_map": int(ev[a_hg]), "robust_map": int(ev[a_rm]), "planner": planner,
            "robust_map_choice": a_rm}


def run_episode(cfg: E06Config, split: int, i: int) -> dict:
    """One logged episode: every candidate simulated, then the highest-grade one stepped."""
    env = _env(cfg)
    c = Clock()
    obs, info = env.reset(seed=derived_seed(cfg.seed, split, i))
    reset = c.record()
    feats = grasp_features(obs, env.gripper)
    feats_map = grasp_features(obs, env.gripper, opening="map")  # as before the robust score
    ablation = ablation_scores(env, cfg) if split == 1 else np.zeros((len(ABLATIONS), cfg.k), np.float32)
    paper = map_opening_choices(env, obs, cfg) if split == 1 else {}
    c = Clock()
    ev = env.evaluate_candidates(threads=1)
    evaluate = c.record()
    # the same candidates at their nominal poses (test split only: the policies learn
    # from the outcomes with the error)
    exact = (env.evaluate_candidates(threads=1, execution_error=False)["outcome"]
             if cfg.noisy and split == 1 else ev["outcome"])
    a = highest_grade_policy(obs)
    c = Clock()
    _, _, _, _, step_info = env.step(a)
    step = c.record()
    return {"split": split, "index": i, "kind": info["object"]["kind"], "pose": info["object"]["pose"],
            "parts": info["parts"], "redraws": info["redraws"], "n_clear": info["n_clear"],
            "features": feats.astype(np.float32), "features_map": feats_map.astype(np.float32),
            "candidates": obs["candidates"],
            "mask": obs["action_mask"], "outcome": ev["outcome"], "outcome_exact": exact, "cloud": obs["cloud"],
            "ablation": ablation, "paper": paper,
            "object_pose": obs["object_pose"],
            "reset_s": reset["wall_s"], "reset_cpu_s": reset["cpu_s"], "plan_s": env.timing.get("plan"),
            "evaluate_s": evaluate["wall_s"], "trials": int(obs["action_mask"].sum()),
            "step_s": step["wall_s"], "step_cpu_s": step["cpu_s"],
            "step_agrees": step_info["outcome_code"] == int(ev["outcome"][a])}


def _chunk(args) -> list[dict]:
    cfg, split, idx = args
    return [run_episode(cfg, split, i) for i in idx]


def collect(cfg: E06Config, split: int, n: int) -> list[dict]:
    chunks = [(cfg, split, list(range(a, min(n, a + 8)))) for a in range(0, n, 8)]
    out: list[dict] = []
    if cfg.workers == 1:
        for ch in chunks:
            out += _chunk(ch)
    else:
        with ProcessPoolExecutor(cfg.workers) as ex:
            for part in ex.map(_chunk, chunks):
                out += part
                if len(out) % 100 < len(part) or len(out) == n:
                    log.info("split %d: %d / %d episodes", split, len(out), n)
    return out
