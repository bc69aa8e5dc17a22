"""A robot arm carrying a graspsim gripper, as a MuJoCo model.

The arm's model file (a vendored ``mjcf/<name>/<name>.xml``: the Franka Emika Panda) is
attached to the world at the base pose ``T_world_base``; the gripper goes on the arm's
flange as the trial harness puts it on its free wrist: a model file as authored
(:func:`graspsim.sim.authored_model.attach_model`: the same pad, force and
gravity-compensation settings), a gripper simulated from its spec (the Festo
HGPL-25-60-A, a spec ``.json``) as the box model the harness generates from the spec
(:func:`graspsim.sim.model.add_box_gripper`: the same housing, jaws, valve and pads). The
flange carries a ``wrist`` body whose frame is the gripper's wrist frame of
:class:`~graspsim.grippers.GripperSpec` (a model file's root body sits on the flange and
the wrist is where the gripper's :class:`~graspsim.grippers.Mount` puts it; a box
model's wrist, the top of its housing, is the flange), with the harness's ``wrist`` and
``tcp`` sites: maps' wrist poses are targets of that frame. The spec's ``arm`` box (the
planner's keep-out for whatever carries the gripper) is not simulated: the arm's own
links are.

The arm is driven by a position servo on each joint (:class:`ArmServos`, added after
the gripper's actuators so that the gripper's come first, as the harness expects); its
links are gravity-compensated (the arm's own controller carries its weight: what is left
for the servos is the load and the contacts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from graspsim._resources import package_path
from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec
from graspsim.transforms import invert_transform, make_transform, matrix_to_quat, quat_to_matrix

__all__ = ["ArmServos", "ArmSpec", "PANDA", "ARMS", "ROBOTS", "get_arm", "base_transform", "ArmNames",
           "add_arm", "build_robot_model", "ARM_PREFIX", "DEFAULT_BASE"]

ARM_PREFIX = "arm/"
#: default base placement (x [m], y [m], yaw [rad]): beside the table, 0.5 m from the
#: object (which stands over the world origin), facing it
DEFAULT_BASE = (-0.5, 0.0, 0.0)


@dataclass(frozen=True)
class ArmServos:
    """Joint position servos: force = kp (target - q) - kv qdot, clamped to +-force_limit.

    Defaults: the Panda's joint torque limits (87 N m joints 1-4, 12 N m joints 5-7,
    Franka's data sheet) and the gains of MuJoCo Menagerie's Panda (kp 4500 / 3500 /
    2000 N m/rad, kv = kp / 10)."""

    kp: tuple[float, ...] = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
    kv: tuple[float, ...] = (450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0)
    force_limit: tuple[float, ...] = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)

    def __post_init__(self) -> None:
        for name in ("kp", "kv", "force_limit"):
            v = tuple(float(x) for x in getattr(self, name))
            if not all(math.isfinite(x) and x > 0 for x in v):
                raise InvalidParameterError(f"ArmServos.{name} must be numbers > 0, got {v!r}")
            object.__setattr__(self, name, v)


@dataclass(frozen=True)
class ArmSpec:
    """A vendored arm: its folder under ``mjcf/``, joints (base to flange), the flange
    site (where a gripper's root body mounts), a home configuration (hovering above the
    table, clear of an object in front) and its servos."""

    name: str
    folder: str
    joints: tuple[str, ...]
    flange: str
    home: tuple[float, ...]
    links: tuple[str, ...]
    #: links whose convex hulls (what MuJoCo collides) reach over the flange and the
    #: gripper's root at every pose: their contacts with the gripper are excluded
    hull_over_flange: tuple[str, ...] = ()
    servos: ArmServos = field(default_factory=ArmServos)

    @property
    def path(self):
        return package_path("mjcf", self.folder, f"{self.folder}.xml")

    def to_dict(self) -> dict:
        return {"name": self.name, "model": f"mjcf/{self.folder}/{self.folder}.xml", "home": list(self.home),
                "servos": {k: list(v) for k, v in self.servos.__dict__.items()}}


#: The Franka Emika Panda (robosuite 1.5.2's model, mjcf/panda). Home: Franka's "ready"
#: pose (flange 0.31 m in front of the base, 0.59 m up, pointing down).
PANDA = ArmSpec(
    name="panda", folder="panda", joints=tuple(f"joint{i}" for i in range(1, 8)), flange="flange",
    home=(0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4),
    links=tuple(f"link{i}" for i in range(8)), hull_over_flange=("link5",))

ARMS: dict[str, ArmSpec] = {"panda": PANDA}
#: the values of ``--robot``: "none" is the floating gripper of the trial harness
ROBOTS = ("none", *ARMS)


def get_arm(name: str) -> ArmSpec:
    try:
        return ARMS[name]
    except KeyError:
        raise InvalidParameterError(f"unknown robot {name!r}; valid: {list(ARMS)}") from None


def base_transform(base=DEFAULT_BASE) -> np.ndarray:
    """T_world_base (4, 4) of a base placement (x [m], y [m], yaw [rad]) on the table top
    (z = 0); a (4, 4) array is checked and returned."""
    b = np.asarray(base, float)
    if b.shape == (4, 4):
        if not np.all(np.isfinite(b)) or not np.allclose(b[:3, :3].T @ b[:3, :3], np.eye(3), atol=1e-6):
            raise InvalidParameterError("the robot's base pose must be a finite rigid transform")
        return b
    if b.shape != (3,) or not np.all(np.isfinite(b)):
        raise InvalidParameterError(f"the robot's base must be x, y [m] and yaw [rad] (3 numbers), got {base!r}")
    c, s = math.cos(b[2]), math.sin(b[2])
    return make_transform(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([b[0], b[1], 0.0]))


@dataclass(frozen=True)
class ArmNames:
    """Element names of an arm in a compiled model."""

    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    bodies: tuple[str, ...]
    wrist: str = "wrist"


def _load_arm(arm: ArmSpec) -> mujoco.MjSpec:
    path = arm.path
    child = mujoco.MjSpec.from_file(str(path))
    meshdir = path.parent / (child.meshdir or "")
    for mesh in child.meshes:
        mesh.file = str(meshdir / mesh.file)
    child.meshdir = ""
    return child


def _flange_wrist(gripper: GripperSpec) -> np.ndarray:
    """T_flange_wrist (4, 4): the gripper's root body on the flange, so the wrist sits at
    the inverse of the root's mount pose (a generated box model's wrist is its root)."""
    if gripper.model is None:
        return np.eye(4)
    from graspsim.grippers import mount

    mnt = mount(gripper.model)
    return invert_transform(make_transform(quat_to_matrix(np.asarray(mnt.quat, float)), np.asarray(mnt.pos, float)))


def add_arm(spec: mujoco.MjSpec, arm: ArmSpec, gripper: GripperSpec, physics, *, force: float,
            friction: tuple[float, float, float], condim: int, T_world_base: np.ndarray) -> ArmNames:
    """Attach ``arm`` at ``T_world_base`` with ``gripper`` on its flange into ``spec``
    (module doc). The gripper's actuators are added first, the arm's servos after."""
    from graspsim.sim.authored_model import attach_model
    from graspsim.sim.model import NAMES

    child = _load_arm(arm)
    frame = spec.worldbody.add_frame(pos=list(T_world_base[:3, 3]), quat=list(matrix_to_quat(T_world_base[:3, :3])))
    spec.attach(child, prefix=ARM_PREFIX, frame=frame)
    flange = spec.site(ARM_PREFIX + arm.flange)
    T_link_flange = make_transform(quat_to_matrix(np.asarray(flange.quat, float)), np.asarray(flange.pos, float))
    T_link_wrist = T_link_flange @ _flange_wrist(gripper)
    wrist = flange.parent.add_body(name=NAMES.wrist, pos=list(T_link_wrist[:3, 3]),
                                   quat=list(matrix_to_quat(T_link_wrist[:3, :3])))
    wrist.add_site(name="wrist", size=[0.005] * 3, rgba=[0.2, 0.2, 0.9, 0.4], group=4)
    wrist.add_site(name="tcp", pos=gripper.nominal_tcp, size=[0.004] * 3, rgba=[0.2, 0.9, 0.2, 0.4], group=4)
    if gripper.model is None:  # the box model generated from the spec, its wrist on the flange
        from graspsim.sim.model import add_box_gripper

        wrist.gravcomp = 1.0  # as the harness's free wrist: the housing's weight is not the servos' load
        add_box_gripper(spec, wrist, gripper, physics, force=force, friction=friction, condim=condim)
    else:
        attach_model(spec, wrist, gripper, physics, force=force, friction=friction, condim=condim)
    for link in arm.hull_over_flange:
        for body in [wrist, *wrist.find_all(mujoco.mjtObj.mjOBJ_BODY)]:  # the box model's housing is on the wrist
            spec.add_exclude(bodyname1=ARM_PREFIX + link, bodyname2=body.name)
    bodies = tuple(ARM_PREFIX + b for b in arm.links)
    for b in bodies:
        spec.body(b).gravcomp = 1.0
    acts = []
    s = arm.servos
    for i, j in enumerate(arm.joints):
        act = spec.add_actuator(name=f"{ARM_PREFIX}servo{i + 1}", target=ARM_PREFIX + j,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=s.kp[i], kv=s.kv[i])
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-s.force_limit[i], s.force_limit[i]]
        acts.append(act.name)
    return ArmNames(joints=tuple(ARM_PREFIX + j for j in arm.joints), actuators=tuple(acts), bodies=bodies)


def build_robot_model(arm: ArmSpec, gripper: GripperSpec, base=DEFAULT_BASE, *, table: bool = True) -> mujoco.MjModel:
    """The arm with ``gripper`` on its flange at ``base`` (see :func:`base_transform`),
    above the table plane (z = 0) when ``table``: the model reachability is checked on
    when no scene is given."""
    from graspsim.sim.model import GripperPhysics, drive_force
    from graspsim.sim.trial_scene import TABLE

    spec = mujoco.MjSpec()
    spec.modelname = f"{arm.name}_{gripper.name}"
    spec.compiler.degree = False
    add_arm(spec, arm, gripper, GripperPhysics(), force=drive_force(gripper, None, 4), friction=(0.5, 0.005, 0.0001),
            condim=4, T_world_base=base_transform(base))
    if table:
        spec.worldbody.add_geom(name=TABLE, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1.0, 1.0, 0.01])
    return spec.compile()
