"""The trial harness's gripper: a new ``MjSpec`` holding any gripper on the free wrist.

Every gripper is simulated on the same harness -- a mocap target, a free,
gravity-compensated wrist and the weld pulling one to the other (:mod:`graspsim.sim.model`)
-- and :func:`build_gripper_spec` is where it is decided which model sits on that wrist:
the box model generated from the spec (:func:`~graspsim.sim.model.add_box_gripper`) or,
for a gripper with a ``model``, its model file as authored
(:func:`~graspsim.sim.authored_model.attach_model`).
"""

from __future__ import annotations

import mujoco

from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.sim.authored_model import attach_model
from graspsim.sim.model import IMPRATIO, TIMESTEP, GripperPhysics, add_box_gripper, add_weld, add_wrist, drive_force

__all__ = ["build_gripper_spec", "gripper_xml"]


def build_gripper_spec(
    gripper: GripperSpec = HGPL_25_60_A,
    physics: GripperPhysics = GripperPhysics(),
    *,
    grip_force: float | None = None,
    friction: tuple[float, float, float] = (1.0, 0.005, 0.0001),
    condim: int = 4,
    home_pos: tuple[float, float, float] = (0.0, 0.0, 0.35),
    home_quat: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0),
) -> mujoco.MjSpec:
    """A new ``MjSpec`` holding the gripper on the harness's wrist, its mocap target and
    weld: the box model generated from the spec, its drive and coupling, or (``gripper.model``)
    the model file as authored. The names of its elements:
    :func:`~graspsim.sim.authored_model.authored_names`.

    grip_force: force per jaw [N]; default the spec's (bore x pressure x efficiency, or the
    rated force). friction: pad friction (sliding, torsional, rolling); condim: pad contact
    dimension. home_pos / home_quat (w, x, y, z): the wrist pose in the world at ``qpos0``
    (default: 35 cm up, approach pointing down).
    """
    force = drive_force(gripper, grip_force, condim)
    spec = mujoco.MjSpec()
    spec.modelname = gripper.name
    spec.compiler.degree = False
    wrist = add_wrist(spec, gripper, home_pos, home_quat)
    # the weld keeps its place among the equality constraints of each kind of model (the
    # compiled models, and so the trials, stay as they were measured)
    if gripper.model is None:
        add_weld(spec, physics)
        add_box_gripper(spec, wrist, gripper, physics, force=force, friction=friction, condim=condim)
    else:
        attach_model(spec, wrist, gripper, physics, force=force, friction=friction, condim=condim)
        add_weld(spec, physics)
    return spec


def gripper_xml(gripper: GripperSpec = HGPL_25_60_A,
                physics: GripperPhysics = GripperPhysics()) -> str:
    """MJCF text of the stand-alone gripper (what ``mjcf/<name>/<name>.xml`` holds)."""
    spec = build_gripper_spec(gripper, physics)
    spec.option.timestep = TIMESTEP  # the trials' own step
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = IMPRATIO  # the trials' own friction stiffness
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_DIAGEXACT
    spec.compile()
    return spec.to_xml()
