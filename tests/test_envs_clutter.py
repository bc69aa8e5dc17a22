"""``graspsim/ClutterClear-v0``: Gymnasium's checker, a short episode whose counts add
up, the stopping rules (two failures in a row terminate, the attempt limit truncates),
masks and bad input. Small packed scenes of primitives on a coarse test database."""

from __future__ import annotations

import math
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import graspsim  # noqa: F401  (registers the environments)
from graspsim.envs import CLUTTER_CLEAR_ID
from graspsim.envs.clutter_clear import CLUTTER_FEATURES
from graspsim.errors import GraspsimError, InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Cylinder, Sphere
from graspsim.tabletop.table_scene import make_scene

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def kw(tmp_path_factory):
    root = tmp_path_factory.mktemp("clutterdb")
    MapDatabase(root, config=FAST).build([Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.2), Sphere(0.035)])
    return dict(n_objects=2, kind="packed", object_set="primitives", db_root=str(root), map_config=FAST,
                n_candidates=6, cloud_size=256)


def _make(kw, **more):
    return gym.make(CLUTTER_CLEAR_ID, **{**kw, **more}).unwrapped


@pytest.mark.slow
def test_check_env(kw):
    env = gym.make(CLUTTER_CLEAR_ID, render_mode="rgb_array", **kw)
    env.unwrapped.reset(seed=123)  # maps of new sizes are built on first use: the database settles first
    check_env(env.unwrapped)
    env.close()


def test_short_episode_rewards_are_lifts_and_it_ends_by_the_protocols_rules(kw):
    env = _make(kw, n_candidates=64)
    obs, info = env.reset(seed=5)
    assert obs in env.observation_space and info["stop"] is None and info["objects_left"] == [0, 1]
    assert obs["candidates"].shape == (64, len(CLUTTER_FEATURES))
    valid = obs["action_mask"].astype(bool)
    assert 0 < valid.sum() < 64 and not obs["candidates"][~valid].any()
    assert set(np.unique(obs["candidates"][valid, 0])) <= set(np.unique(obs["segment"][obs["segment"] >= 0]))
    scores = obs["candidates"][valid, CLUTTER_FEATURES.index("score")]
    assert scores[0] > 0 and np.all(np.diff(scores) <= 1e-6)  # the scene's ranking, best first
    rewards, ended = [], False
    while not ended:
        obs, r, term, trunc, info = env.step(0)  # the robust best, as the benchmark does
        assert r == float(info["success"]) and (not info["success"] or info["picked"] == info["target"])
        rewards.append(r)
        ended = term or trunc
    assert info["removed"] >= sum(rewards) and info["attempts"] == len(rewards) <= 2 * 2 + 2
    assert term != trunc and info["stop"] in ("cleared", "failures", "no_grasp", "max_attempts")
    assert trunc == (info["stop"] == "max_attempts")
    assert (info["stop"] == "cleared") == (info["objects_left"] == []) and not obs["action_mask"].any()
    with pytest.raises(GraspsimError, match="reset"):
        env.step(0)
    env.close()


def _fail_next(env):
    """Move every offered grasp 30 cm up: the next step closes on nothing."""
    look = env._look
    up = tuple(replace(g, T_world_wrist=g.T_world_wrist + np.pad([[0.0], [0.0], [0.3]], ((0, 1), (3, 0))))
               for g in look.candidates)
    env._look = replace(look, candidates=up, best=up[0])


def test_two_failures_in_a_row_terminate_and_a_lift_resets_the_count(kw):
    env = _make(kw, n_objects=3)
    env.reset(seed=1)
    _fail_next(env)
    _, r, term, trunc, info = env.step(0)
    assert (r, term, trunc, info["outcome"], info["stop"]) == (0.0, False, False, "no_contact", None)
    _, r, term, trunc, info = env.step(0)  # the best grasp
    if not info["success"] or term:  # a second failure in a row; or nothing left to grasp
        assert info["stop"] == ("failures" if not info["success"] else "no_grasp") and term and not trunc
        return
    _fail_next(env)  # the lift started the count again: one failure does not end it
    _, r, term, trunc, info = env.step(0)
    assert (r, term, trunc, info["stop"]) == (0.0, False, False, None)
    _fail_next(env)
    _, r, term, trunc, info = env.step(0)
    assert (r, term, trunc, info["stop"]) == (0.0, True, False, "failures")
    env.close()


def test_the_attempt_limit_truncates(kw):
    env = _make(kw, max_attempts=1)
    env.reset(seed=5)
    _, r, term, trunc, info = env.step(0)
    assert info["attempts"] == 1 and info["objects_left"]  # two objects: one grasp cannot clear them
    assert (term, trunc, info["stop"]) == (False, True, "max_attempts")
    env.close()


def test_same_seed_same_episode_and_a_given_scene(kw):
    a, b = _make(kw), _make(kw)
    oa, _ = a.reset(seed=7)
    ob, _ = b.reset(seed=7)
    assert all(np.array_equal(oa[k], ob[k]) for k in oa)
    sa, sb = a.step(0), b.step(0)
    assert sa[1:4] == sb[1:4] and np.array_equal(sa[0]["cloud"], sb[0]["cloud"])
    scene = make_scene(2, "packed", 11, object_set="primitives")
    o1, i1 = a.reset(seed=1, options={"scene": scene})
    assert i1["objects_left"] == [0, 1] and a.episode.scene is scene
    with pytest.raises(InvalidParameterError, match="TableScene"):
        a.reset(options={"scene": "pile.json"})
    with pytest.raises(InvalidParameterError, match="unknown reset option"):
        a.reset(options={"objects": 3})
    a.close()
    b.close()


def test_masked_choice_ends_the_episode_without_a_grasp_and_depth_is_observed(kw):
    env = _make(kw, n_candidates=64, depth_image=True)
    obs, _ = env.reset(seed=5)
    k = env.camera.intrinsics
    assert obs["depth"].shape == (k.height, k.width) and obs["depth"].max() > 0 and obs in env.observation_space
    bad = int(np.flatnonzero(obs["action_mask"] == 0)[0])
    _, r, term, trunc, info = env.step(bad)
    assert (r, term, trunc, info["outcome"], info["attempts"]) == (0.0, True, False, "invalid_action", 0)
    with pytest.raises(InvalidParameterError, match="action must be in"):
        env.reset(seed=5)
        env.step(64)
    env.close()


@pytest.mark.parametrize("bad, message", [
    ({"n_objects": 0}, "n_objects"), ({"kind": "heap"}, "kind"), ({"object_set": "toys"}, "object_set"),
    ({"max_attempts": 0}, "max_attempts"), ({"colour": 1}, "unknown environment option"),
    ({"depth_image": "yes"}, "depth_image"), ({"contacts": "default"}, "valid: stiff, soft"),
])
def test_bad_settings_are_clear_errors(bad, message, kw):
    with pytest.raises(InvalidParameterError, match=message):
        gym.make(CLUTTER_CLEAR_ID, **{**kw, **bad})


def test_the_soft_contact_model_settles_and_simulates_the_drawn_scenes(kw):
    """contacts="soft": the episodes' ClutterConfig carries the soft settings, and the scenes
    reset draws are settled and simulated under them (2 ms steps); the default carries none."""
    from graspsim.sim import contact_model

    assert _make(kw).clutter_config.sim is None
    env = _make(kw, contacts="soft")
    assert env.clutter_config.sim == contact_model("soft")
    env.reset(seed=3)
    assert env.episode.sim.model.opt.timestep == pytest.approx(0.002)
    env.close()
