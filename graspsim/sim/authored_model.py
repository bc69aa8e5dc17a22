"""A gripper model file in the trial harness, simulated as authored.

The model (a vendored ``mjcf/<model>/<model>.xml`` or any model file a spec's
``model`` names) is attached as it is under the harness's wrist body (the same mocap
target, free wrist and weld as the generated box model, see :mod:`graspsim.sim.model`),
at the pose its :class:`~graspsim.grippers.Mount` gives (measured from the file, see
:mod:`graspsim.grippers.model_file`). Its joints, equality constraints, tendons,
actuators, contact excludes and geometry stay the model's. What the harness sets on the
attached model, as it does on the box model:

* gravity compensation of its bodies (the arm carries the gripper);
* on the two pad geoms: the scene's friction and condim, and the pad priority, solref
  and solimp of :class:`~graspsim.sim.model.GripperPhysics` (contact settings are the
  scene's choice, for every gripper alike);
* a grip force other than the model's own (``SimSettings.grip_force``): a force
  actuator's gain scaled by force / the model's force, a position servo's force range
  likewise (a servo with no force range cannot be asked for another force); with a
  force actuator, the damped jaw joints' damping = force / the spec's closing speed
  (the model's own speed unless a spec changes it, e.g. the Franka hand with slow
  fingers; a servo's speed is the model's).

:func:`model_drive` says how the harness poses its joints at an opening and turns the
jaw command (-1 close, 0 hold, +1 open) into the model's actuator controls.
"""

from __future__ import annotations

import mujoco
import numpy as np

from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.grippers.spec import GripperSpec
from graspsim.sim.model import NAMES, GripDrive, GripperNames, GripperPhysics

__all__ = ["attach_model", "authored_names", "model_drive", "PREFIX"]

PREFIX = "gripper/"


def _load(mnt) -> mujoco.MjSpec:
    """The model's MjSpec with absolute mesh paths (it is attached into another spec)."""
    from graspsim.errors import GripperError
    from graspsim.grippers.model_file import _load_spec

    try:
        return _load_spec(mnt.path, dict(mnt.options))
    except GripperError as err:
        raise SimulationError(str(err)) from err


def _is_servo(act) -> bool:
    return act.biastype == mujoco.mjtBias.mjBIAS_AFFINE and act.biasprm[1] < 0


def attach_model(spec: mujoco.MjSpec, wrist: mujoco.MjsBody, gripper: GripperSpec,
                 physics: GripperPhysics, *, force: float, friction: tuple[float, float, float],
                 condim: int) -> GripperNames:
    """Attach ``gripper.model`` as authored under the body ``wrist`` (the wrist frame of the
    spec: the harness's free wrist, or an arm's flange) at its mount pose, with the
    harness's settings (module doc; ``force`` per finger [N], from
    :func:`~graspsim.sim.model.drive_force`); returns the names of its elements."""
    from graspsim.grippers import mount

    if gripper.model is None:
        raise InvalidParameterError(f"gripper {gripper.name!r} has no model file")
    mnt = mount(gripper.model)
    frame = wrist.add_frame(pos=list(mnt.pos), quat=list(mnt.quat))
    child = _load(mnt)
    for opt in ("timestep", "impratio", "integrator", "cone", "enableflags", "disableflags"):
        setattr(spec.option, opt, getattr(child.option, opt))  # the model's options (no attach
    spec.attach(child, prefix=PREFIX, frame=frame)             # conflict); a scene sets its own

    root = spec.body(PREFIX + mnt.root_body)
    for body in [root, *root.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
        body.gravcomp = 1.0
    for name in mnt.pad_geoms:
        pad = spec.geom(PREFIX + name)
        pad.friction, pad.condim, pad.priority = list(friction), condim, physics.pad_priority
        pad.solref, pad.solimp = list(physics.pad_solref), list(physics.pad_solimp)
    scale = force / mnt.model_force
    for name in mnt.actuators:
        act = spec.actuator(PREFIX + name)
        if _is_servo(act):
            if abs(scale - 1.0) > 1e-9:
                if act.forcelimited != mujoco.mjtLimited.mjLIMITED_TRUE and not (
                        act.forcelimited == mujoco.mjtLimited.mjLIMITED_AUTO and act.forcerange[1] > act.forcerange[0]):
                    raise InvalidParameterError(
                        f"grip_force {force} N: the {gripper.model} model's position servo {name!r} has no force "
                        f"range to scale (its force is {mnt.model_force} N)")
                act.forcerange = [act.forcerange[0] * scale, act.forcerange[1] * scale]
        else:
            limited = act.forcelimited == mujoco.mjtLimited.mjLIMITED_TRUE or (
                act.forcelimited == mujoco.mjtLimited.mjLIMITED_AUTO and act.forcerange[1] > act.forcerange[0])
            if limited and force > act.forcerange[1] + 1e-9:
                raise InvalidParameterError(
                    f"grip_force {force} N exceeds the {gripper.model} model's limit {act.forcerange[1]} N")
            act.gainprm[0] = act.gainprm[0] * force / mnt.model_force
    if not any(_is_servo(spec.actuator(PREFIX + n)) for n in mnt.actuators):
        for name in mnt.jaw_joints:  # a force actuator on damped jaws: they close at the spec's speed
            j = spec.joint(PREFIX + name)
            if j.damping[0] > 0:
                j.damping[0] = force / gripper.closing_speed
    return _names(mnt)


def authored_names(gripper: GripperSpec) -> GripperNames:
    """The names of the elements of ``gripper``'s model as :func:`attach_model` attaches
    it (prefixed; no coupling tendon, no housing geom) and of the harness's wrist; a
    gripper without a model file: the names of the box model generated from its spec."""
    from graspsim.grippers import mount

    if gripper.model is None:
        return NAMES
    return _names(mount(gripper.model))


def _names(mnt) -> GripperNames:
    return GripperNames(
        sync="", tendon="", actuator=PREFIX + mnt.actuators[0],
        jaw_neg=PREFIX + mnt.jaw_joints[0], jaw_pos=PREFIX + mnt.jaw_joints[1],
        finger_neg=PREFIX + mnt.pad_geoms[0], finger_pos=PREFIX + mnt.pad_geoms[1], housing="",
        wrist=NAMES.wrist, target=NAMES.target, weld=NAMES.weld)


def model_drive(model: mujoco.MjModel, gripper: GripperSpec) -> GripDrive:
    """The :class:`GripDrive` of ``gripper``'s model file in a compiled scene ``model``."""
    from graspsim.grippers import mount

    mnt = mount(gripper.model)
    j = [model.joint(PREFIX + n).id for n in mnt.joints]
    act = [model.actuator(PREFIX + n).id for n in mnt.actuators]
    if act != list(range(model.nu)) and act != list(range(len(act))):
        raise SimulationError("the gripper's actuators must be the scene's first ones")
    jaws = np.array([mnt.joints.index(n) for n in mnt.jaw_joints])
    half = np.column_stack([mnt.openings / 2, mnt.openings / 2])
    linear = all(np.allclose(mnt.qpos[:, jaws[s]], half[:, s], atol=1e-9) for s in range(2))
    return GripDrive(qadr=model.jnt_qposadr[j].copy(), dadr=model.jnt_dofadr[j].copy(),
                     openings=mnt.openings, qpos=mnt.qpos, jaws=jaws, ctrl_close=mnt.ctrl_close,
                     ctrl_open=mnt.ctrl_open, ctrl_hold=mnt.ctrl_hold if mnt.hold else None,
                     jaw_half=None if linear else half)
