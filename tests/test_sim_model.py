"""The gripper model: generated from the spec, agrees with the planner's boxes, and the
static model folder in mjcf/ is what the spec generates."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.sim.harness import build_gripper_spec
from graspsim.sim.model import NAMES, GripperPhysics
from graspsim.sim.model_folder import default_folder, model_files

MJCF = Path(__file__).resolve().parents[1] / "mjcf"


def _step_warning_free(model: mujoco.MjModel, seconds: float = 1.0, ctrl: float = 0.0) -> mujoco.MjData:
    data = mujoco.MjData(model)
    data.ctrl[:] = ctrl
    mujoco.mj_step(model, data, nstep=int(round(seconds / model.opt.timestep)))
    assert all(w.number == 0 for w in data.warning), [w.number for w in data.warning]
    assert np.all(np.isfinite(data.qpos))
    return data


@pytest.mark.parametrize("path", sorted([*MJCF.rglob("*.xml"), *MJCF.rglob("*.urdf")]),
                         ids=lambda p: str(p.relative_to(MJCF)))
def test_every_mjcf_compiles_and_steps_one_second_without_warnings(path):
    model = mujoco.MjModel.from_xml_path(str(path))
    for ctrl in (-1.0, 1.0):  # jaws driven into both end stops
        _step_warning_free(model, 1.0, ctrl)


def test_model_folder_matches_the_spec():
    folder = default_folder(HGPL_25_60_A)
    for name, text in model_files(HGPL_25_60_A).items():
        assert (folder / name).read_text() == text, (
            f"{folder / name} is stale: regenerate with `python -m graspsim.sim.model_folder`")
    assert (folder / "LICENSE").is_file()


@pytest.mark.parametrize("opening", [0.0, 0.013, 0.05, 0.12])
def test_model_boxes_coincide_with_the_planner_boxes(opening):
    g = HGPL_25_60_A
    m = build_gripper_spec(g).compile()
    d = mujoco.MjData(m)
    d.qpos[m.joint(NAMES.jaw_neg).qposadr[0]] = opening / 2
    d.qpos[m.joint(NAMES.jaw_pos).qposadr[0]] = opening / 2
    mujoco.mj_kinematics(m, d)
    w = m.body(NAMES.wrist).id
    Rw, pw = d.xmat[w].reshape(3, 3), d.xpos[w]
    centers, half = g.boxes_at(opening)
    names = g.collision_boxes().names
    for k, name in enumerate(names):
        if name == "arm":  # planner keep-out, not simulated
            with pytest.raises(KeyError):
                m.geom(name)
            continue
        gid = m.geom(name).id
        c = Rw.T @ (d.geom_xpos[gid] - pw)
        R = Rw.T @ d.geom_xmat[gid].reshape(3, 3)
        np.testing.assert_allclose(c, centers[k], atol=1e-12)
        np.testing.assert_allclose(np.abs(R) @ m.geom_size[gid], half[k], atol=1e-12)
    # the pads' inner faces are the planner's contact planes
    fp, fn = m.geom(NAMES.finger_pos).id, m.geom(NAMES.finger_neg).id
    assert (Rw.T @ (d.geom_xpos[fp] - pw))[0] - m.geom_size[fp][0] == pytest.approx(opening / 2, abs=1e-12)
    assert (Rw.T @ (d.geom_xpos[fn] - pw))[0] + m.geom_size[fn][0] == pytest.approx(-opening / 2, abs=1e-12)


def test_drive_closes_at_the_flow_limit_and_pushes_with_the_grip_force():
    g = GripperSpec(closing_speed=0.1)
    spec = build_gripper_spec(g, grip_force=120.0)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    m = spec.compile()
    d = mujoco.MjData(m)
    d.qpos[m.joint(NAMES.jaw_neg).qposadr[0]] = d.qpos[m.joint(NAMES.jaw_pos).qposadr[0]] = 0.05
    d.ctrl[0] = -1.0  # valve: close
    mujoco.mj_step(m, d, nstep=50)  # 0.1 s: mid-stroke
    v = d.qvel[m.joint(NAMES.jaw_pos).dofadr[0]]
    assert v == pytest.approx(-g.closing_speed, rel=0.02)
    mujoco.mj_step(m, d, nstep=500)  # stalled at the end stop: full force, no motion
    assert abs(d.actuator_force[0]) == pytest.approx(120.0, rel=1e-9)
    assert abs(d.qvel[m.joint(NAMES.jaw_pos).dofadr[0]]) < 1e-6


def test_physics_parameters_are_validated():
    with pytest.raises(InvalidParameterError, match="jaw_armature"):
        GripperPhysics(jaw_armature=0.0)
    with pytest.raises(InvalidParameterError, match="pad_solimp"):
        GripperPhysics(pad_solimp=(0.9, 0.95))
    with pytest.raises(InvalidParameterError, match="grip_force"):
        build_gripper_spec(HGPL_25_60_A, grip_force=-1.0)


def test_import_graspsim_does_not_load_mujoco_until_sim_names_are_used():
    import subprocess
    import sys

    code = ("import sys, graspsim; assert 'mujoco' not in sys.modules; "
            "graspsim.TrialOutcome; assert 'mujoco' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_a_light_object_is_announced_once_a_heavy_one_not(caplog):
    """Under LIGHT_MASS the simulated pads sink millimetres into an object (study_light_objects):
    building one says so, once per object, naming its mass; a heavier one builds silently."""
    import logging

    from graspsim.primitives import Box
    from graspsim.sim.objects import LIGHT_MASS, object_from_shape

    caplog.set_level(logging.WARNING, logger="graspsim.sim.objects")
    object_from_shape(Box(0.05, 0.05, 0.05), mass=10 * LIGHT_MASS)
    assert not caplog.records
    for _ in range(2):
        object_from_shape(Box(0.0123, 0.0123, 0.0123), mass=0.0037)
    (r,) = caplog.records
    assert "3.7 g" in r.getMessage() and "study_light_objects" in r.getMessage()


def test_the_stiff_contact_model_is_the_default_the_soft_one_doubles_the_step_and_unknown_ones_are_named():
    from graspsim.sim import CONTACT_MODELS, SimSettings, contact_model

    assert CONTACT_MODELS[0] == "stiff" and contact_model("stiff") == SimSettings()
    soft = contact_model("soft")
    assert soft.timestep == SimSettings().timestep * 2
    assert soft.physics.pad_solref[0] > SimSettings().physics.pad_solref[0]
    assert soft.physics.pad_solimp[2] > SimSettings().physics.pad_solimp[2]  # the impedance ramp [m]
    for s in (soft, SimSettings()):
        assert s.physics.pad_solref[0] >= 2 * s.timestep  # MuJoCo's floor for a stable contact
    # a model sets its own contacts and keeps the rest of the base settings
    base = contact_model("soft", SimSettings(friction=0.3))
    assert base.friction == 0.3 and contact_model("stiff", base) == SimSettings(friction=0.3)
    with pytest.raises(InvalidParameterError, match="valid: " + ", ".join(CONTACT_MODELS)):
        contact_model("default")


def test_contact_names_resolve_without_the_simulator_and_the_default_leaves_the_callers_settings():
    """graspsim.contacts, the configurations' one check of a model's name, importable without
    MuJoCo; sim.contact_settings resolves it: None for the default (the caller's own
    SimSettings stand), the soft model's settings otherwise."""
    import subprocess
    import sys

    from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS, check_contacts
    from graspsim.sim import contact_model, contact_settings

    assert DEFAULT_CONTACTS == CONTACT_MODELS[0] == "stiff" and check_contacts("soft") == "soft"
    assert contact_settings(DEFAULT_CONTACTS) is None and contact_settings("soft") == contact_model("soft")
    with pytest.raises(InvalidParameterError, match="valid: stiff, soft"):
        contact_settings("default")
    code = ("import sys\nimport graspsim.contacts, graspsim.envs.clutter_config, graspsim.calibration.conditions\n"
            "assert 'mujoco' not in sys.modules")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 0
