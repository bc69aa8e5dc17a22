"""The vendored Franka hand in the trial harness: attached as it is, on the spec's frame."""

import mujoco
import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.errors import InvalidParameterError
from graspsim.grippers import get_gripper
from graspsim.grippers.franka import hull_points
from graspsim.primitives import Box
from graspsim.sim import LiftPlace, SimSettings, TrialOutcome, build_scene, object_from_shape, run_trials
from graspsim.sim.authored_model import PREFIX, authored_names
from graspsim.sim.harness import build_gripper_spec

FRANKA = get_gripper("franka_hand")
BOX = Box(0.05, 0.05, 0.05)
TOP_DOWN = dict(grasp_point=[0, 0, 0], approach=[0, 0, -1], closing=[1, 0, 0])  # at the centre


@pytest.fixture(scope="module")
def franka_box_scene():
    return build_scene(object_from_shape(BOX), FRANKA)


def test_the_vendored_meshes_are_simulated_not_a_box_copy(franka_box_scene):
    m = franka_box_scene.model
    kinds = {int(m.geom_type[i]) for i in franka_box_scene.gripper_geoms}
    assert kinds == {int(mujoco.mjtGeom.mjGEOM_MESH)} and len(franka_box_scene.gripper_geoms) == 3
    assert m.body(PREFIX + "hand").id > 0 and m.nmesh == 4  # the model's 4 meshes (the box object has none)


@pytest.mark.parametrize("opening", [0.0, 0.03, 0.08])
def test_the_mounted_pads_sit_at_the_spec_gap_and_tips_at_the_spec_fingertip(opening):
    spec, names = build_gripper_spec(FRANKA), authored_names(FRANKA)
    m = spec.compile()
    d = mujoco.MjData(m)
    for j in (names.jaw_neg, names.jaw_pos):
        d.qpos[m.joint(j).qposadr[0]] = opening / 2
    mujoco.mj_kinematics(m, d)
    w = m.body("wrist").id
    for geom, sign in ((names.finger_neg, -1), (names.finger_pos, 1)):
        p = (hull_points(m, d, geom) - d.xpos[w]) @ d.xmat[w].reshape(3, 3)  # wrist frame
        assert (sign * p[:, 0]).min() == pytest.approx(opening / 2, abs=1.5e-4)
        assert p[:, 2].max() == pytest.approx(FRANKA.fingertip_z, abs=1e-5)
    tcp = d.site_xpos[m.site("tcp").id] - d.xpos[w]
    assert np.allclose(tcp @ d.xmat[w].reshape(3, 3), FRANKA.nominal_tcp)


def test_top_down_grasp_of_a_box_lifts_it_with_the_rated_force(franka_box_scene):
    T = grasp_pose(depth=FRANKA.nominal_depth, gripper=FRANKA, **TOP_DOWN)
    r = run_trials(franka_box_scene, T[None], [0.05], LiftPlace(), threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS
    assert r.metrics["lift_height"][0] == pytest.approx(0.12, abs=0.003)
    for k in ("pad_force_neg", "pad_force_pos"):
        assert r.metrics[k][0] == pytest.approx(70.0, rel=0.05)  # the maker's continuous force


def test_grip_force_can_be_raised_to_the_maximum_and_no_further():
    scene = build_scene(object_from_shape(BOX), FRANKA, SimSettings(grip_force=140.0))
    T = grasp_pose(depth=FRANKA.nominal_depth, gripper=FRANKA, **TOP_DOWN)
    r = run_trials(scene, T[None], [0.05], LiftPlace(), threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS
    assert r.metrics["pad_force_neg"][0] == pytest.approx(140.0, rel=0.05)
    with pytest.raises(InvalidParameterError, match="exceeds the franka_hand model's limit 140"):
        build_scene(object_from_shape(BOX), FRANKA, SimSettings(grip_force=200.0))


def test_the_trial_scene_steps_one_second_warning_free_closing_and_opening(franka_box_scene):
    m = franka_box_scene.model
    d = mujoco.MjData(m)
    for ctrl in (-1.0, 1.0):
        d.ctrl[:] = ctrl
        mujoco.mj_step(m, d, nstep=int(round(1.0 / m.opt.timestep)))
        assert all(w.number == 0 for w in d.warning), [w.number for w in d.warning]
        assert np.all(np.isfinite(d.qpos))


def test_the_harness_weld_follows_the_models_own_constraints():
    """The harness adds its weld after the attached model's equality constraints: the
    constraint order (which the solver's results depend on) of the models the model-file
    grippers' trials were measured with; the box model's is held by the committed mjcf/."""
    m = build_gripper_spec(FRANKA).compile()
    assert [m.equality(i).name for i in range(m.neq)] == [PREFIX + "finger_coupling", "wrist_weld"]
