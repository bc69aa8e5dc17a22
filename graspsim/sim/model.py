"""The gripper as a MuJoCo model, generated from a :class:`~graspsim.grippers.spec.GripperSpec`.

One spec drives the planner's boxes and this model, so the pad faces of the model at an
opening ``w`` coincide with ``GripperSpec.boxes_at(w)`` (tests prove it). Structure::

    wrist_target (mocap) ──weld── wrist (free joint, gravity-compensated)
                                    ├─ housing (box)
                                    ├─ jaw_neg (slide −x) ─ jaw box + finger box (pad)
                                    └─ jaw_pos (slide +x) ─ jaw box + finger box (pad)

* The wrist is a free body pulled by a weld to a mocap target, not the mocap body
  itself: a mocap body has no velocity for friction to see, so it could lift nothing.
* Jaw joints measure half the opening [m]: ``opening = q_neg + q_pos``. An equality
  keeps them synchronised (the HGPL's rack and pinion); the fixed tendon ``opening``
  (coefficients 1, 1) carries the drive.
* The drive is a throttled pneumatic cylinder: the actuator ``grip`` is a 5/3 valve,
  control in [-1, 1] (-1 close, +1 open, 0 exhaust), pushing each jaw with
  ``ctrl x grip_force``; the throttle is joint damping ``grip_force / closing_speed``,
  so the jaws travel at the flow-limited ``closing_speed`` in free motion and push with
  exactly the grip force once blocked (damping is integrated implicitly; a clamped
  velocity servo, by contrast, overshoots into bang-bang motion at 2 ms).
* Light, heavily damped jaws pushed by 250 N against stiff pads chatter (measured: the
  gap jumps by 5 mm and the pad force overshoots 50 % with 10 g of armature). The model
  prevents it with the reflected inertia of piston and rack (``jaw_armature`` 0.25 kg)
  and the exact constraint diagonal (``diagexact``, set by the scene): still at 500 N.

The "arm" box of the spec is a planner keep-out, not a simulated part.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec

__all__ = ["GripperPhysics", "GripperNames", "NAMES", "add_box_gripper",
           "add_wrist", "add_weld", "drive_force", "GripDrive", "box_drive"]


@dataclass(frozen=True)
class GripperNames:
    """Element names of the generated model (MuJoCo namespaces are per type)."""

    wrist: str = "wrist"
    target: str = "wrist_target"
    weld: str = "wrist_weld"
    sync: str = "jaw_sync"
    tendon: str = "opening"
    actuator: str = "grip"
    jaw_neg: str = "jaw_neg"
    jaw_pos: str = "jaw_pos"
    finger_neg: str = "finger_neg"
    finger_pos: str = "finger_pos"
    housing: str = "housing"


NAMES = GripperNames()


@dataclass(frozen=True, eq=False)
class GripDrive:
    """How the harness poses and commands a gripper in a compiled model.

    qadr / dadr (J,): qpos / qvel addresses of the gripper's joints; openings (K,) [m]
    and qpos (K, J): the joints at each pad gap of the opening table (interpolated
    between rows); jaws (2,): which of the J joints are the (neg, pos) jaws, and
    jaw_half (K, 2): their half pad gap at each row (None: the jaw joint's value is the
    half gap, as on the box model). The jaw command (-1 close, 0 hold, +1 open, the
    harness's valve convention) becomes the actuators' controls: ctrl_close,
    ctrl_open (nu,), and ctrl_hold (K, nu) the controls that hold each row (None: 0)."""

    qadr: np.ndarray
    dadr: np.ndarray
    openings: np.ndarray
    qpos: np.ndarray
    jaws: np.ndarray
    ctrl_close: np.ndarray
    ctrl_open: np.ndarray
    ctrl_hold: np.ndarray | None = None
    jaw_half: np.ndarray | None = None

    @property
    def qadr_jaws(self) -> np.ndarray:
        return self.qadr[self.jaws]

    def joint_positions(self, openings) -> np.ndarray:
        """(N, J) joint positions at pad gaps ``openings`` (N,) [m]."""
        w = np.atleast_1d(np.asarray(openings, float))
        return np.stack([np.interp(w, self.openings, self.qpos[:, j]) for j in range(self.qpos.shape[1])], -1)

    def controls(self, command: np.ndarray, openings=None) -> np.ndarray:
        """(N, S, nu) controls of jaw commands (N, S) in [-1, 1], for trials started at pad
        gaps ``openings`` (N,) (what 0 holds; None: the widest)."""
        c = np.asarray(command, float)[..., None]
        if self.ctrl_hold is None:
            hold = np.zeros((1, 1, len(self.ctrl_close)))
        else:
            w = np.full(c.shape[0], self.openings[-1]) if openings is None else np.asarray(openings, float)
            hold = np.stack([np.interp(w, self.openings, self.ctrl_hold[:, a])
                             for a in range(self.ctrl_hold.shape[1])], -1)[:, None]
        return np.where(c < 0, hold - c * (self.ctrl_close - hold), hold + c * (self.ctrl_open - hold))

    def half_openings(self, q_jaws: np.ndarray) -> np.ndarray:
        """(..., 2) half pad gaps [m] of jaw joint positions (..., 2)."""
        if self.jaw_half is None:
            return q_jaws
        out = np.empty_like(np.asarray(q_jaws, float))
        for s in range(2):
            x = self.qpos[:, self.jaws[s]]
            o = np.argsort(x)
            out[..., s] = np.interp(q_jaws[..., s], x[o], self.jaw_half[o, s])
        return out


def box_drive(model: mujoco.MjModel, gripper: GripperSpec) -> GripDrive:
    """The drive of the box model generated from ``gripper`` (jaw value = half gap)."""
    j = [model.joint(n).id for n in (NAMES.jaw_neg, NAMES.jaw_pos)]
    w = np.array([gripper.min_opening, gripper.max_opening])
    return GripDrive(qadr=model.jnt_qposadr[j].copy(), dadr=model.jnt_dofadr[j].copy(), openings=w,
                     qpos=np.column_stack([w / 2, w / 2]), jaws=np.array([0, 1]),
                     ctrl_close=np.array([-1.0]), ctrl_open=np.array([1.0]))


@dataclass(frozen=True)
class GripperPhysics:
    """Simulation parameters of the gripper that a data sheet would not give.

    jaw_armature: reflected inertia of piston + rack on each jaw joint [kg]; with
        100 g jaws alone, 300 N against a 2 ms contact chatters.
    pad_solref: (time constant [s], damping ratio) of pad contacts and jaw end stops: as
        stiff as the default 1 ms step allows (MuJoCo's default 20 ms would let 300 N sink
        the pads ~1 cm into the object).
    pad_solimp: MuJoCo solimp of pad contacts and jaw end stops. The impedance ramps over
        2 mm: with MuJoCo's 1 mm, pads on overlapping CoACD parts fell into a limit
        cycle (contacts on/off every ~20 steps, the object reported as dropped); with the
        5 mm of the ``soft`` contact model (``graspsim.sim.contact_model``) 250 N sank
        the pads 4.6 mm into a 3.3 g domino and squeezed it out, 1.5 mm with these.
    pad_priority: pads decide the contact parameters of pad-object pairs.
    weld_solref: stiffness of the arm (the mocap weld), (time constant [s], damping).
    jaw_frictionloss: dry friction of the jaw guides [N].
    """

    jaw_armature: float = 0.25
    pad_solref: tuple[float, float] = (0.002, 1.0)
    pad_solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.002, 0.5, 2.0)
    pad_priority: int = 1
    weld_solref: tuple[float, float] = (0.01, 1.0)
    jaw_frictionloss: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.jaw_armature) and self.jaw_armature > 0):
            raise InvalidParameterError(f"jaw_armature must be > 0 kg, got {self.jaw_armature!r}")
        if not self.jaw_frictionloss >= 0:
            raise InvalidParameterError(
                f"jaw_frictionloss must be >= 0 N, got {self.jaw_frictionloss!r}")
        for name, n in (("pad_solref", 2), ("pad_solimp", 5), ("weld_solref", 2)):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) != n:
                raise InvalidParameterError(f"{name} needs {n} numbers, got {v!r}")
            object.__setattr__(self, name, v)

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


_BOX = mujoco.mjtGeom.mjGEOM_BOX
_GREY = (0.55, 0.57, 0.6, 1.0)
_DARK = (0.25, 0.27, 0.3, 1.0)
_PAD = (0.15, 0.15, 0.15, 1.0)


IMPRATIO = 100.0  # MuJoCo friction stiffness of every simulation (why: graspsim.sim.trial_scene's docstring)
TIMESTEP = 0.001  # [s] the default step of every simulation (SimSettings; why: trial_scene.CONTACT_MODELS)


def drive_force(gripper: GripperSpec, grip_force: float | None, condim: int) -> float:
    """The grip force per jaw [N] a model is built with (``grip_force`` or the spec's),
    validated with the pad contact dimension."""
    force = float(gripper.grip_force if grip_force is None else grip_force)
    if not (np.isfinite(force) and force > 0):
        raise InvalidParameterError(f"grip_force must be > 0 N, got {grip_force!r}")
    if condim not in (1, 3, 4, 6):
        raise InvalidParameterError(f"condim must be 1, 3, 4 or 6, got {condim!r}")
    return force


def add_box_gripper(spec: mujoco.MjSpec, wrist: mujoco.MjsBody, gripper: GripperSpec, physics: GripperPhysics, *,
                    force: float, friction: tuple[float, float, float], condim: int) -> GripperNames:
    """The box model generated from ``gripper`` (module doc: housing, jaws on synchronised
    slides, the valve driving the ``opening`` tendon) on the body ``wrist``, whose frame
    is the spec's wrist frame: the harness's free wrist, or an arm's flange; ``force``
    per jaw [N] (:func:`drive_force`). Returns the names of its elements."""
    g, n = gripper, NAMES
    boxes = g.collision_boxes()
    parts = dict(zip(boxes.names, zip(boxes.centers, boxes.half_extents)))
    c, h = parts["housing"]
    wrist.add_geom(name=n.housing, type=_BOX, pos=c, size=h, mass=g.housing_mass, rgba=_GREY)

    for side, sign in (("neg", -1.0), ("pos", 1.0)):
        jaw = wrist.add_body(name=f"jaw_{side}", gravcomp=1.0)
        jaw.add_joint(
            name=f"jaw_{side}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[sign, 0, 0],
            range=[0.5 * g.min_opening, 0.5 * g.max_opening], limited=mujoco.mjtLimited.mjLIMITED_TRUE,
            armature=physics.jaw_armature, frictionloss=physics.jaw_frictionloss,
            damping=force / g.closing_speed,
            solref_limit=physics.pad_solref, solimp_limit=physics.pad_solimp,
        )
        c, h = parts[f"jaw_{side}"]
        jaw.add_geom(name=f"jaw_{side}", type=_BOX, pos=c, size=h, mass=g.jaw_mass, rgba=_DARK)
        c, h = parts[f"finger_{side}"]
        jaw.add_geom(
            name=f"finger_{side}", type=_BOX, pos=c, size=h, mass=g.finger_mass, rgba=_PAD,
            friction=friction, condim=condim, priority=physics.pad_priority,
            solref=physics.pad_solref, solimp=physics.pad_solimp,
        )
    spec.add_exclude(bodyname1=n.jaw_neg, bodyname2=n.jaw_pos)

    sync = spec.add_equality(name=n.sync, type=mujoco.mjtEq.mjEQ_JOINT,
                             objtype=mujoco.mjtObj.mjOBJ_JOINT, name1=n.jaw_pos, name2=n.jaw_neg)
    sync.data[:5] = [0, 1, 0, 0, 0]

    tendon = spec.add_tendon(name=n.tendon)
    tendon.wrap_joint(n.jaw_neg, 1.0)
    tendon.wrap_joint(n.jaw_pos, 1.0)
    act = spec.add_actuator(name=n.actuator, target=n.tendon,
                            trntype=mujoco.mjtTrn.mjTRN_TENDON)
    act.set_to_motor()
    act.gainprm[0] = force
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = [-1.0, 1.0]
    return n


def add_wrist(spec: mujoco.MjSpec, gripper: GripperSpec, home_pos, home_quat) -> mujoco.MjsBody:
    """The mocap target and the free, gravity-compensated wrist body with its ``wrist``
    and ``tcp`` sites (the wrist frame of :class:`GripperSpec`); returns the wrist."""
    n = NAMES
    target = spec.worldbody.add_body(name=n.target, mocap=True, pos=home_pos, quat=home_quat)
    target.add_site(name="wrist_target", size=[0.005] * 3, rgba=[0.9, 0.2, 0.2, 0.4], group=4)
    wrist = spec.worldbody.add_body(name=n.wrist, pos=home_pos, quat=home_quat, gravcomp=1.0)
    wrist.add_freejoint(name=n.wrist)
    wrist.add_site(name="wrist", size=[0.005] * 3, rgba=[0.2, 0.2, 0.9, 0.4], group=4)
    wrist.add_site(name="tcp", pos=gripper.nominal_tcp,
                   size=[0.004] * 3, rgba=[0.2, 0.9, 0.2, 0.4], group=4)
    return wrist


def add_weld(spec: mujoco.MjSpec, physics: GripperPhysics) -> None:
    """The weld pulling the wrist to its mocap target (the arm)."""
    weld = spec.add_equality(name=NAMES.weld, type=mujoco.mjtEq.mjEQ_WELD,
                             objtype=mujoco.mjtObj.mjOBJ_BODY, name1=NAMES.wrist, name2=NAMES.target)
    weld.data[:11] = [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1]
    weld.solref = physics.weld_solref
