"""The envs take a gripper: its own maps (database keyed by its spec) and its own model."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from graspsim.envs import GRASP_SELECT_ID
from graspsim.envs.baselines import highest_grade_policy
from graspsim.envs.config import EnvConfig
from graspsim.errors import InvalidParameterError
from graspsim.maps.generate import MapConfig

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))


def test_a_bad_gripper_is_refused_in_the_config():
    with pytest.raises(InvalidParameterError, match="unknown gripper 'robotiq'"):
        EnvConfig(gripper="robotiq")
    assert EnvConfig().to_dict()["gripper"] == "festo_hgpl_25_60_a"


@pytest.mark.slow
def test_grasp_select_with_the_franka_hand_uses_its_maps_and_its_model(tmp_path):
    env = gym.make(GRASP_SELECT_ID, db_root=str(tmp_path), map_config=FAST, n_candidates=4, cloud_size=64,
                   pool_size=120, gripper="franka_hand", position_noise=0.0, rotation_noise=0.0).unwrapped
    assert env.gripper.name == "franka_hand" and env.db.gripper.name == "franka_hand"
    assert {e["gripper"] for e in env.db.entries()} == {"franka_hand"}
    obs, info = env.reset(seed=3)
    m = env.episode.scene.model
    assert {int(m.geom_type[i]) for i in env.episode.scene.gripper_geoms} == {int(mujoco.mjtGeom.mjGEOM_MESH)}
    _, reward, terminated, _, info = env.step(highest_grade_policy(obs))
    assert terminated and np.isfinite(reward) and info["outcome"]
    env.close()
