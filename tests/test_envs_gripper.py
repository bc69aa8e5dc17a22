"""The envs take a gripper: its own maps (database keyed by its spec) and its own model."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from graspsim.envs import GRASP_SELECT_ID
from graspsim.envs.baselines import highest_grade_policy
from graspsim.envs.env_config import EnvConfig
from graspsim.errors import InvalidParameterError
from graspsim.maps.map_config import MapConfig

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


def _widths(d):
    """The widths a grasp of a drawn object must span (the ones drawn within the limits)."""
    shape = d.shape if d.pose == "upright" else d.shape.parts[0]
    if d.kind == "box":
        return [shape.x, shape.y]
    if d.kind in ("cylinder", "sphere"):
        return [2 * shape.radius]
    if d.kind == "cone":
        return [2 * shape.bottom_radius]
    if d.kind == "mug":
        return [2 * d.shape.parts[0].radius]
    return []


@pytest.mark.slow
def test_object_sizes_follow_the_grippers_stroke():
    from graspsim.envs.object_sets import COMPOUND_KINDS, PRIMITIVE_KINDS, draw_object, size_limits
    from graspsim.grippers import get_gripper
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.maps.database import PAPER_SHAPES

    franka = get_gripper("franka_hand")
    lim = size_limits(franka)
    assert lim.widest == pytest.approx(0.07) and lim.narrowest == 0.0  # 80 mm - 2 x 5 mm clearance
    assert size_limits(HGPL_25_60_A).widest == pytest.approx(0.11)
    widest = {}
    for kind in PRIMITIVE_KINDS + COMPOUND_KINDS:
        rng_a, rng_b, rng_f = (np.random.default_rng(7) for _ in range(3))
        for _ in range(60):
            festo = draw_object((kind,), rng_a, gripper=HGPL_25_60_A)
            assert festo.to_dict() == draw_object((kind,), rng_b).to_dict()  # the default is the Festo
            d = draw_object((kind,), rng_f, gripper=franka)
            w = _widths(d)
            assert all(v <= lim.widest + 1e-12 for v in w), (kind, w)
            widest[kind] = max([widest.get(kind, 0.0), *w])
            if kind in PRIMITIVE_KINDS:  # still within the planner's scaling range of the reference
                shape = d.shape if d.pose == "upright" else d.shape.parts[0]
                ref, dims = PAPER_SHAPES[kind].dims, shape.dims
                if kind == "box":
                    dims = dict(zip("xyz", sorted(dims.values())))
                assert all(1 / 3 <= v / ref[k] <= 3 for k, v in dims.items()), (kind, dims)
    assert widest["sphere"] > 0.9 * lim.widest  # cut to the limit, not shrunk below it


def test_the_franka_hand_can_take_the_widest_objects_it_is_given():
    from graspsim.errors import NoFeasibleGraspError
    from graspsim.grippers import get_gripper
    from graspsim.maps.generate import generate_fs_map
    from graspsim.primitives import Sphere

    franka = get_gripper("franka_hand")
    coarse = MapConfig(surface_step=0.01, rotation_step=math.radians(30))
    fs = generate_fs_map(Sphere(0.035), franka, config=coarse, threads=1)  # the widest sphere drawn for it
    assert np.sum(fs.grade > 0.7) > 0
    with pytest.raises(NoFeasibleGraspError):  # the Festo's widest sphere (r 5 cm) it cannot take
        generate_fs_map(Sphere(0.05), franka, config=coarse, threads=1)


def test_a_gripper_too_small_for_an_object_set_is_one_clear_error():
    from dataclasses import replace

    from graspsim.envs.object_sets import draw_object
    from graspsim.errors import GripperError
    from graspsim.grippers.spec import HGPL_25_60_A

    tiny = replace(HGPL_25_60_A, name="tiny", stroke_per_jaw=0.015)  # opens 30 mm: 20 mm chords
    with pytest.raises(GripperError, match="no sphere diameter of the object set fits"):
        draw_object(("sphere",), np.random.default_rng(0), gripper=tiny)
