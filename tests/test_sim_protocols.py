"""Protocol schedules: what the gripper is told to do, step by step."""

import math

import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.errors import InvalidParameterError
from graspsim.primitives import Box
from graspsim.sim import LiftPlace, Tug, build_scene, make_protocol, object_from_shape
from graspsim.sim.protocols import min_jerk


@pytest.fixture(scope="module")
def scenes():
    obj = object_from_shape(Box(0.06, 0.06, 0.06))
    return build_scene(obj), build_scene(obj, table=False, gravity=False)


def test_lift_place_schedule(scenes):
    scene = scenes[0]
    p = LiftPlace()
    T = scene.T_world_obj @ grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0])
    c = p.controls(scene, T[None])[0]
    ph = p.steps(scene.model.opt.timestep)
    assert c.shape == (p.nstep(scene.model.opt.timestep), 8)
    assert np.all(c[: ph["settle"][1] + 1, 0] == 0)  # valve shut while settling
    assert np.all(c[ph["close"][0]: ph["open"][0], 0] == -1)
    assert np.all(c[ph["open"][0]:, 0] == 1)
    z0 = T[2, 3]
    assert c[ph["hold"][0], 3] == pytest.approx(z0 + p.lift_height)
    assert c[ph["open"][0], 3] == pytest.approx(z0 + p.place_clearance)
    # retract backs off along -approach (+x here): 5 cm
    assert c[-1, 1] - T[0, 3] == pytest.approx(p.retract_distance)
    np.testing.assert_allclose(c[:, 4:], np.tile(c[0, 4:], (len(c), 1)))  # orientation kept
    assert abs(sum(d for _, d in p.phases()) - 2.02) < 1e-9


def test_tug_pulls_one_weight_along_each_gripper_direction(scenes):
    scene = scenes[1]
    p = Tug()
    T = grasp_pose([0, 0, 0], [0, 0, -1], [0, 1, 0])  # wrist x = world y
    c = p.controls(scene, T[None])[0]
    nb = scene.model.nbody
    x = c[:, 1:1 + 6 * nb].reshape(len(c), nb, 6)[:, scene.obj_body, :3]
    ph = p.steps(scene.model.opt.timestep)
    mid = (ph["pull0"][0] + ph["pull0"][1]) // 2
    np.testing.assert_allclose(x[mid], scene.obj.mass * 9.81 * (T[:3, :3] @ [1, 0, 0]), atol=1e-9)
    assert np.abs(x[: ph["close"][1] + 1]).max() == 0


def test_min_jerk_profile():
    u = np.linspace(0, 1, 11)
    s = min_jerk(u)
    assert s[0] == 0 and s[-1] == 1 and np.all(np.diff(s) >= 0)


def test_protocols_by_name_and_bad_parameters():
    assert isinstance(make_protocol("tug"), Tug)
    assert make_protocol("lift_place", lift_height=0.15).lift_height == 0.15
    with pytest.raises(InvalidParameterError, match="unknown protocol"):
        make_protocol("shake")
    with pytest.raises(InvalidParameterError, match="lift_height"):
        LiftPlace(lift_height=0.05)
    with pytest.raises(InvalidParameterError):
        LiftPlace(hold_time=-1.0)
    with pytest.raises(InvalidParameterError, match="directions"):
        Tug(directions=((0.0, 0.0, 0.0),))
    assert LiftPlace().to_dict()["place_tilt"] == pytest.approx(math.radians(20))
