"""A vendored (externally authored) gripper model in the trial harness.

The model file ``mjcf/<model>/<model>.xml`` is attached as it is under the harness's
wrist body (the same mocap target, free wrist and weld as the generated box model, see
:mod:`graspsim.sim.model`), at the pose its :class:`~graspsim.grippers.Mount` gives.
What the harness sets on the attached model, as it does on the box model:

* gravity compensation of its bodies (the arm carries the gripper);
* on the two pad geoms: the scene's friction and condim, and the pad priority, solref
  and solimp of :class:`~graspsim.sim.model.GripperPhysics` (contact settings are the
  scene's choice, for every gripper alike);
* the grip force: the actuator's gain (the model's own, the spec's ``rated_force``,
  unless a force is asked for), and the finger damping = force / the spec's closing
  speed, so the fingers travel at the closing speed whatever the force.

Geometry, joints, masses, the coupling and the force limit stay the model's.
"""

from __future__ import annotations

import mujoco

from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.grippers.spec import GripperSpec
from graspsim.sim.model import NAMES, GripperNames, GripperPhysics, add_weld, add_wrist, drive_force

__all__ = ["build_vendored_gripper_spec", "PREFIX"]

PREFIX = "gripper/"


def _load(xml) -> mujoco.MjSpec:
    """The model's MjSpec with absolute mesh paths (it is attached into another spec)."""
    try:
        child = mujoco.MjSpec.from_file(str(xml))
    except ValueError as err:
        raise SimulationError(f"gripper model {xml} does not load: {' '.join(str(err).split())}") from err
    meshdir = xml.parent / child.meshdir
    for mesh in child.meshes:
        mesh.file = str(meshdir / mesh.file)
    child.meshdir = ""
    return child


def build_vendored_gripper_spec(
    gripper: GripperSpec,
    physics: GripperPhysics = GripperPhysics(),
    *,
    grip_force: float | None = None,
    friction: tuple[float, float, float] = (1.0, 0.005, 0.0001),
    condim: int = 4,
    home_pos: tuple[float, float, float] = (0.0, 0.0, 0.35),
    home_quat: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0),
) -> tuple[mujoco.MjSpec, GripperNames]:
    """A new ``MjSpec`` with the vendored model of ``gripper.model`` on the harness's
    wrist, and the names of its elements the harness uses (same arguments as
    :func:`~graspsim.sim.model.build_gripper_spec`; grip_force per finger [N])."""
    from graspsim.grippers import mount

    if gripper.model is None:
        raise InvalidParameterError(f"gripper {gripper.name!r} has no vendored model")
    mnt = mount(gripper.model)
    force = drive_force(gripper, grip_force, condim)
    spec = mujoco.MjSpec()
    spec.modelname = gripper.name
    spec.compiler.degree = False
    wrist = add_wrist(spec, gripper, home_pos, home_quat)
    frame = wrist.add_frame(pos=list(mnt.pos), quat=list(mnt.quat))
    child = _load(mnt.xml)
    for opt in ("timestep", "impratio", "integrator", "cone", "enableflags", "disableflags"):
        setattr(spec.option, opt, getattr(child.option, opt))  # the model's options (no attach
    spec.attach(child, prefix=PREFIX, frame=frame)             # conflict); a scene sets its own
    add_weld(spec, physics)

    root = spec.body(PREFIX + mnt.root_body)
    for body in [root, *root.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
        body.gravcomp = 1.0
    for name in mnt.pad_geoms:
        pad = spec.geom(PREFIX + name)
        pad.friction, pad.condim, pad.priority = list(friction), condim, physics.pad_priority
        pad.solref, pad.solimp = list(physics.pad_solref), list(physics.pad_solimp)
    act = spec.actuator(PREFIX + mnt.actuator)
    if force > act.forcerange[1] + 1e-9:
        raise InvalidParameterError(
            f"grip_force {force} N exceeds the {gripper.model} model's limit {act.forcerange[1]} N")
    act.gainprm[0] = force
    for name in mnt.jaw_joints:
        spec.joint(PREFIX + name).damping[0] = force / gripper.closing_speed
    names = GripperNames(
        sync="", tendon="", actuator=PREFIX + mnt.actuator,
        jaw_neg=PREFIX + mnt.jaw_joints[0], jaw_pos=PREFIX + mnt.jaw_joints[1],
        finger_neg=PREFIX + mnt.pad_geoms[0], finger_pos=PREFIX + mnt.pad_geoms[1], housing="",
        wrist=NAMES.wrist, target=NAMES.target, weld=NAMES.weld)
    return spec, names
