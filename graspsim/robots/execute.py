"""Grasps executed by the arm in MuJoCo: the scene, the plan, the trial.

The scene is the trial harness's (:mod:`graspsim.sim.trial_scene`: its solver settings, table
and object, the same pad sensors), with the arm standing on the table top at its base
pose and the gripper on its flange in place of the floating wrist.

For each grasp, :func:`plan_grasp` checks reachability (:func:`~graspsim.robots.reach.check_reach`:
the grasp, its pre-grasp ``approach`` back along the approach axis, the straight line
in), solves the lift (straight up by the protocol's ``lift_height``), the lowering back
and the retreat along the approach, and checks the joint-space move from the arm's home
to the pre-grasp, interpolated every ``path_step`` radians (largest joint), against the
table, the object and the arm itself, with the jaws at their pre-grasp opening. A grasp
that fails any of it is never executed: UNREACHABLE (no IK solution, or a pose that
collides) or APPROACH_COLLISION (the move or the approach meets something); both stay in
the denominator.

:class:`ArmLiftPlace` is the paper's lift-and-place test (:class:`~graspsim.sim.protocols.LiftPlace`,
judged by it on the same phases) preceded by the arm's own motion: ``move`` (joint space,
minimum-jerk), ``approach`` (Cartesian, through the solved waypoints), ``arrive``
(the servos settle). Every step's control is the joint target of each servo and the
gripper's command: what the wrist does is the controller's and the contacts' doing.
Failures are then named by what happened before the close: APPROACH_COLLISION if the
object had moved more than ``approach_push`` by then, CONTROLLER_ERROR if the wrist was
farther than ``reach_tol`` from its target.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass, field
from typing import ClassVar

import mujoco
import numpy as np
from mujoco import rollout

from graspsim.checks import NON_NEGATIVE, POSITIVE, check_fields
from graspsim.errors import SimulationError
from graspsim.grippers.spec import GripperSpec
from graspsim.robots.arm import DEFAULT_BASE, PANDA, ArmSpec, add_arm, base_transform
from graspsim.robots.reach import ArmKinematics, Reach, ReachCheck, check_reach, pose_error
from graspsim.sim.model import GripDrive
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.objects import SimObject
from graspsim.sim.outcomes import Record, TrialOutcome
from graspsim.sim.protocols import LiftPlace, min_jerk, phase_steps
from graspsim.sim.results import TrialResults
from graspsim.sim.trial_scene import OBJECT, SimSettings, add_pad_sensors, gripper_drive, resting_pose
from graspsim.transforms import quat_to_matrix

__all__ = ["ArmScene", "build_arm_scene", "ArmLiftPlace", "ArmPlan", "plan_grasp", "plan_grasps", "plan_counts",
           "run_arm_trials", "arm_controls", "arm_targets", "arm_failures"]

log = logging.getLogger(__name__)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CTRL = mujoco.mjtState.mjSTATE_CTRL


@dataclass(frozen=True, eq=False)
class ArmScene:
    """A compiled scene with the arm: the model, what it holds, and addresses."""

    model: mujoco.MjModel
    arm: ArmSpec
    gripper: GripperSpec
    obj: SimObject
    settings: SimSettings
    T_world_obj: np.ndarray
    T_world_base: np.ndarray
    grip_force: float
    qadr_arm: np.ndarray
    act_arm: np.ndarray
    qadr_obj: int
    dadr_obj: int
    obj_body: int
    pad_sensors: np.ndarray
    wrist_sensors: tuple[int, int]
    drive: GripDrive
    table: bool = True
    gravity: bool = True

    @property
    def nstate(self) -> int:
        return mujoco.mj_stateSize(self.model, _FULL)

    def kinematics(self) -> ArmKinematics:
        """IK and collision queries in this scene (the object where it rests); IK on the
        arm and gripper alone at the same base."""
        from graspsim.robots.arm import build_robot_model

        return ArmKinematics(self.model, self.arm,
                             ik_model=build_robot_model(self.arm, self.gripper, self.T_world_base, table=False))

    def info(self) -> dict:
        return {"object": self.obj.description, "mass": self.obj.mass, "gripper": self.gripper.to_dict(),
                "grip_force": self.grip_force, "settings": self.settings.to_dict(), "table": True,
                "gravity": True, "T_world_obj": self.T_world_obj.tolist(), "mujoco_version": mujoco.__version__,
                "robot": self.arm.to_dict(), "T_world_base": self.T_world_base.tolist()}


def build_arm_scene(obj: SimObject, gripper: GripperSpec, settings: SimSettings = SimSettings(), *,
                    arm: ArmSpec = PANDA, base=DEFAULT_BASE, T_world_obj: np.ndarray | None = None,
                    up: np.ndarray | None = None) -> ArmScene:
    """The trial scene of ``obj`` on the table with ``arm`` at ``base`` (x, y, yaw or a
    (4, 4) pose, see :func:`~graspsim.robots.arm.base_transform`) carrying ``gripper``."""
    from graspsim.sim.model import drive_force
    from graspsim.sim.trial_scene import _add_object, _add_table, _set_options

    s = settings
    force = drive_force(gripper, s.grip_force, s.condim)
    T_base = base_transform(base)
    T_world_obj = resting_pose(obj, up=up) if T_world_obj is None else np.asarray(T_world_obj, float)
    spec = mujoco.MjSpec()
    spec.modelname = f"trial_{arm.name}_{gripper.name}"
    spec.compiler.degree = False
    names = add_arm(spec, arm, gripper, s.physics, force=force,
                    friction=(s.friction, s.torsional_friction, s.rolling_friction), condim=s.condim,
                    T_world_base=T_base)
    _set_options(spec, s)
    _add_table(spec, s, size=1.0)
    spec.add_exclude(bodyname1="world", bodyname2=names.bodies[0])  # the base stands on the table
    _add_object(spec, obj, T_world_obj, s)
    from graspsim.sim.authored_model import authored_names
    from graspsim.sim.model import NAMES

    add_pad_sensors(spec, gripper, authored_names(gripper), OBJECT, "")
    spec.add_sensor(name="wrist_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=NAMES.wrist)
    spec.add_sensor(name="wrist_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=NAMES.wrist)
    try:
        model = spec.compile()
    except ValueError as err:
        raise SimulationError(f"the arm's trial scene does not compile: {' '.join(str(err).split())}") from err
    jid = [model.joint(j).id for j in names.joints]
    oj = model.joint(OBJECT).id
    return ArmScene(
        model=model, arm=arm, gripper=gripper, obj=obj, settings=s, T_world_obj=T_world_obj, T_world_base=T_base,
        grip_force=force, qadr_arm=model.jnt_qposadr[jid].copy(),
        act_arm=np.array([model.actuator(a).id for a in names.actuators]),
        qadr_obj=int(model.jnt_qposadr[oj]), dadr_obj=int(model.jnt_dofadr[oj]), obj_body=int(model.body(OBJECT).id),
        pad_sensors=np.array([model.sensor_adr[model.sensor(f"pad_{k}").id] for k in ("neg", "pos")]),
        wrist_sensors=(int(model.sensor_adr[model.sensor("wrist_pos").id]),
                       int(model.sensor_adr[model.sensor("wrist_quat").id])),
        drive=gripper_drive(model, gripper))


@dataclass(frozen=True)
class ArmLiftPlace:
    """The arm's lift-and-place: its motion to the grasp, then :class:`LiftPlace`.

    move_time [s]: home to pre-grasp (joint space, minimum-jerk; 3 s keeps the Panda's
    joints under 2.2 rad/s for moves up to 3.5 rad); approach [m]: the pre-grasp's
    distance back along the approach axis; approach_time [s]; arrive_time [s]: the servos
    settle at the grasp before the close; step [m]: Cartesian waypoint spacing (IK at
    each); path_step [rad]: largest joint step between checked configurations of the
    move; clearance [m]: penetration a check tolerates (the floating harness's
    ``start_penetration``); approach_push [m]: the object moved this much before the
    close names a failure APPROACH_COLLISION; reach_tol ([m], [rad]): the wrist this far
    off its target at the close names a failure CONTROLLER_ERROR."""

    name: ClassVar[str] = "arm_lift_place"
    lift: LiftPlace = field(default_factory=LiftPlace)
    move_time: float = 3.0
    approach: float = 0.10
    approach_time: float = 0.8
    arrive_time: float = 0.3
    step: float = 0.01
    path_step: float = math.radians(2.0)
    clearance: float = 0.001
    approach_push: float = 0.005
    reach_tol: tuple[float, float] = (0.005, math.radians(3.0))

    def __post_init__(self) -> None:
        check_fields(self, NON_NEGATIVE, "approach", "arrive_time", "clearance", "approach_push", owner="ArmLiftPlace")
        check_fields(self, POSITIVE, "move_time", "approach_time", "step", "path_step", owner="ArmLiftPlace")

    @property
    def metric_names(self) -> tuple[str, ...]:
        return (*self.lift.metric_names, "reach_lin", "reach_ang", "approach_push", "reach")

    def phases(self) -> list[tuple[str, float]]:
        return [("move", self.move_time), ("approach", self.approach_time), ("arrive", self.arrive_time),
                *self.lift.phases()]

    def steps(self, dt: float) -> dict[str, tuple[int, int]]:
        return phase_steps(self.phases(), dt)

    def nstep(self, dt: float) -> int:
        return max(b for _, b in self.steps(dt).values()) + 1

    def to_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k != "lift"}
        d["reach_tol"] = list(self.reach_tol)
        return {"name": self.name, **d, "lift": self.lift.to_dict()}


@dataclass(frozen=True, eq=False)
class ArmPlan:
    """The joints of one grasp's motion: the reachability check, then (when it passed)
    the move's start and end, the approach's waypoints (pre-grasp to grasp), the lift's
    (grasp to lifted), the retreat's (placed to retreated); ``outcome``: None when the
    grasp is executed, else UNREACHABLE / APPROACH_COLLISION / START_COLLISION."""

    check: ReachCheck
    outcome: TrialOutcome | None
    stage: str = ""
    q_home: np.ndarray | None = None
    q_approach: np.ndarray | None = None
    q_lift: np.ndarray | None = None
    q_retreat: np.ndarray | None = None


def _line(kin: ArmKinematics, T0: np.ndarray, delta: np.ndarray, q0: np.ndarray, step: float,
          max_joint_step: float = 0.5):
    """IK along the straight wrist path T0 -> T0 + delta (orientation kept), every ``step``
    [m], each solved from the previous; (K + 1, 7) joints or None if one has no solution
    or a joint jumps more than ``max_joint_step`` [rad] between waypoints."""
    k = max(1, int(math.ceil(np.linalg.norm(delta) / step)))
    qs = [q0]
    for i in range(1, k + 1):
        T = T0.copy()
        T[:3, 3] = T0[:3, 3] + delta * i / k
        r = kin.ik(T, qs[-1])
        if not r.ok or np.abs(r.q - qs[-1]).max() > max_joint_step:  # no solution, or a jump between branches
            return None
        qs.append(r.q)
    return np.array(qs)


def _path_clear(kin: ArmKinematics, qs: np.ndarray, jaws, path_step: float, tol: float) -> str | None:
    """Check the joint path through ``qs`` (K, 7), interpolated so that no joint moves
    more than ``path_step`` between checks: None if clear, else what it meets."""
    for a, b in zip(qs[:-1], qs[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / path_step)))
        for u in np.linspace(0.0, 1.0, n + 1):
            c = kin.contacts(a + (b - a) * u, jaws, tol=tol)
            hit = [k for k, v in c.items() if v > 0]
            if hit:
                return hit[0]
    return None


def plan_grasp(scene: ArmScene, kin: ArmKinematics, T_world_wrist: np.ndarray, opening: float,
               protocol: ArmLiftPlace = ArmLiftPlace(), seeds=()) -> ArmPlan:
    """The reachability check and the motion plan of one grasp (module doc): the jaws
    at ``opening`` [m] throughout; ``seeds``: joints to start the grasp's IK from (e.g.
    the capability map's). ``scene``: an :class:`ArmScene`, or any scene carrying the arm
    with its ``arm`` and gripper ``drive`` (a table scene of several objects,
    :class:`graspsim.tabletop.scene_sim.SceneSim`, whose ``kin`` poses them as they lie)."""
    jaws = (scene.drive.qadr, scene.drive.joint_positions([opening])[0])
    p = protocol
    T = np.asarray(T_world_wrist, float)
    chk = check_reach(kin, T, approach=p.approach, step=p.step, jaws=jaws, seeds=seeds, tol=p.clearance)
    if chk.reach == Reach.START:
        return ArmPlan(chk, TrialOutcome.START_COLLISION, "grasp")
    if chk.reach == Reach.NO_IK or chk.stage == "grasp":  # no IK, or every solution at the grasp collides
        return ArmPlan(chk, TrialOutcome.UNREACHABLE, chk.stage)
    if not chk.ok:  # the pre-grasp or the approach line meets the table, the object or the arm
        return ArmPlan(chk, TrialOutcome.APPROACH_COLLISION, chk.stage)
    q_grasp = chk.q_approach[-1]
    lp = p.lift
    q_lift = _line(kin, T, np.array([0.0, 0.0, lp.lift_height]), q_grasp, p.step)
    if q_lift is None:
        return ArmPlan(chk, TrialOutcome.UNREACHABLE, "lift")
    T_placed = T.copy()
    T_placed[2, 3] += lp.place_clearance
    r = kin.ik(T_placed, q_grasp)
    if not r.ok:
        return ArmPlan(chk, TrialOutcome.UNREACHABLE, "lower")
    q_retreat = _line(kin, T_placed, -T[:3, 2] * lp.retract_distance, r.q, p.step)
    if q_retreat is None:
        return ArmPlan(chk, TrialOutcome.UNREACHABLE, "retreat")
    q_home = np.asarray(scene.arm.home, float)
    hit = _path_clear(kin, np.array([q_home, chk.q_approach[0]]), jaws, p.path_step, p.clearance)
    if hit is not None:
        return ArmPlan(chk, TrialOutcome.APPROACH_COLLISION, f"move ({hit})")
    return ArmPlan(chk, None, "", q_home=q_home, q_approach=chk.q_approach, q_lift=q_lift, q_retreat=q_retreat)


def _along(qs: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Joints (S, 7) at path parameters u (S,) in [0, 1] along waypoints (K + 1, 7)."""
    s = np.clip(u, 0.0, 1.0) * (len(qs) - 1)
    i = np.minimum(np.floor(s).astype(int), len(qs) - 2) if len(qs) > 1 else np.zeros(len(s), int)
    f = (s - i)[:, None]
    if len(qs) == 1:
        return np.repeat(qs[:1], len(u), axis=0)
    return qs[i] * (1 - f) + qs[i + 1] * f


def arm_targets(protocol: ArmLiftPlace, plan: ArmPlan, dt: float) -> np.ndarray:
    """(S, 7) joint targets of the servos at every step of an executed plan."""
    ph, S = protocol.steps(dt), protocol.nstep(dt)
    lp = protocol.lift
    q = np.empty((S, plan.q_home.shape[0]))
    t = (np.arange(S) + 1) * dt

    def u_of(name):
        a, b = ph[name]
        return min_jerk((t[a:b + 1] - a * dt) / ((b - a + 1) * dt))

    a, b = ph["move"]
    q[a:b + 1] = plan.q_home + (plan.q_approach[0] - plan.q_home) * u_of("move")[:, None]
    a, b = ph["approach"]
    q[a:b + 1] = _along(plan.q_approach, u_of("approach"))
    q_grasp = plan.q_approach[-1]
    for name in ("arrive", "settle", "close"):
        a, b = ph[name]
        q[a:b + 1] = q_grasp
    a, b = ph["lift"]
    q[a:b + 1] = _along(plan.q_lift, u_of("lift"))
    a, b = ph["hold"]
    q[a:b + 1] = plan.q_lift[-1]
    # lower: back down the lift's path to the placing height (place_clearance above the grasp)
    a, b = ph["lower"]
    down = 1.0 - (1.0 - lp.place_clearance / lp.lift_height) * u_of("lower")
    q[a:b + 1] = _along(plan.q_lift, down)
    a, b = ph["open"]
    q[a:b + 1] = plan.q_retreat[0]
    a, b = ph["retract"]
    q[a:b + 1] = _along(plan.q_retreat, u_of("retract"))
    a, b = ph["rest"]
    q[a:b + 1] = plan.q_retreat[-1]
    return q


def arm_controls(scene, protocol: ArmLiftPlace, plans: list[ArmPlan], openings: np.ndarray) -> np.ndarray:
    """(N, S, nu) controls of executed plans: the gripper's command (open, closed from the
    close to the open phase) and each servo's joint target (:func:`arm_targets`).
    ``scene``: an :class:`ArmScene` or any arm-carrying scene with ``model``, ``drive``
    and ``act_arm`` (a table scene with the arm, :class:`graspsim.tabletop.scene_sim.SceneSim`)."""
    dt = scene.model.opt.timestep
    ph, S = protocol.steps(dt), protocol.nstep(dt)
    valve = np.zeros((len(plans), S))
    valve[:, ph["close"][0]:ph["open"][0]] = -1.0
    valve[:, ph["open"][0]:] = 1.0
    grip = scene.drive.controls(valve, openings)
    ctrl = np.zeros((len(plans), S, scene.model.nu))
    ctrl[..., :grip.shape[-1]] = grip
    for i, p in enumerate(plans):
        ctrl[i, :, scene.act_arm] = arm_targets(protocol, p, dt).T
    return ctrl


def _initial_states(scene: ArmScene, openings: np.ndarray) -> np.ndarray:
    m = scene.model
    d = mujoco.MjData(m)
    state = np.empty(scene.nstate)
    mujoco.mj_getState(m, d, state, _FULL)
    out = np.repeat(state[None], len(openings), axis=0)
    out[:, 1 + scene.qadr_arm] = scene.arm.home  # the arm starts at home (qpos0 is MuJoCo's reference pose: kept)
    out[:, 1 + scene.drive.qadr] = scene.drive.joint_positions(openings)
    return out


def _record(scene: ArmScene, states: np.ndarray, sens: np.ndarray) -> Record:
    m = scene.model
    qp = states[..., 1:1 + m.nq]
    qv = states[..., 1 + m.nq:1 + m.nq + m.nv]
    o = scene.qadr_obj
    pads = np.stack([sens[..., a:a + 4] for a in scene.pad_sensors], axis=-2)
    wp, wq = scene.wrist_sensors
    return Record(time=states[..., 0], wrist_pos=sens[..., wp:wp + 3], wrist_quat=sens[..., wq:wq + 4],
                  obj_pos=qp[..., o:o + 3], obj_quat=qp[..., o + 3:o + 7],
                  obj_vel=qv[..., scene.dadr_obj:scene.dadr_obj + 6],
                  jaws=scene.drive.half_openings(qp[..., scene.drive.qadr_jaws]), pads=pads)


def _slice(rec: Record, start: int) -> Record:
    return Record(**{k: getattr(rec, k)[:, start:] for k in rec.__dataclass_fields__})


class _LiftView:
    """What :meth:`LiftPlace.judge` reads of a scene (the timestep)."""

    def __init__(self, model):
        self.model = model


def _judge(scene: ArmScene, protocol: ArmLiftPlace, rec: Record, T_target: np.ndarray, obj0: np.ndarray):
    ph = protocol.steps(scene.model.opt.timestep)
    s0 = ph["settle"][0]
    out, met = protocol.lift.judge(_LiftView(scene.model), _slice(rec, s0), obj0)
    k = s0 - 1  # the end of the arrival: the servos' work, before the close
    wrist = np.tile(np.eye(4), (len(out), 1, 1))
    wrist[:, :3, :3] = quat_to_matrix(rec.wrist_quat[:, k])
    wrist[:, :3, 3] = rec.wrist_pos[:, k]
    err = np.array([pose_error(w, t) for w, t in zip(wrist, T_target)]).reshape(-1, 2)
    met["reach_lin"], met["reach_ang"] = err[:, 0], err[:, 1]
    met["approach_push"] = np.linalg.norm(rec.obj_pos[:, k] - obj0[:, :3], axis=-1)
    return arm_failures(out, met["approach_push"], err, protocol), met


def arm_failures(outcome: np.ndarray, push: np.ndarray, wrist_err: np.ndarray, protocol: ArmLiftPlace) -> np.ndarray:
    """The arm's names for failed executions (module doc): of the outcomes (N,) that are
    neither SUCCESS nor SIM_UNSTABLE, APPROACH_COLLISION where an object had moved more
    than ``protocol.approach_push`` [m] before the close (``push`` (N,)), else
    CONTROLLER_ERROR where the wrist was farther than ``protocol.reach_tol`` from its
    target then (``wrist_err`` (N, 2): [m], [rad]); the rest keep their outcome."""
    out = np.asarray(outcome)
    err = np.asarray(wrist_err, float).reshape(-1, 2)
    failed = ~np.isin(out, [TrialOutcome.SUCCESS, TrialOutcome.SIM_UNSTABLE])
    pushed = failed & (np.asarray(push, float) > protocol.approach_push)
    off = failed & ~pushed & ((err[:, 0] > protocol.reach_tol[0]) | (err[:, 1] > protocol.reach_tol[1]))
    out = np.where(pushed, TrialOutcome.APPROACH_COLLISION, np.where(off, TrialOutcome.CONTROLLER_ERROR, out))
    return out.astype(np.int8)


def plan_grasps(scene: ArmScene, T_world_wrist: np.ndarray, openings: np.ndarray,
                protocol: ArmLiftPlace = ArmLiftPlace(), *, capability=None,
                on_progress=None, on_planned=None) -> tuple[list[ArmPlan], np.ndarray, np.ndarray]:
    """The plans of N grasps (wrist poses (N, 4, 4) in the world, jaw openings (N,) [m]),
    as the arm's trials make them (:func:`run_arm_trials`, :func:`graspsim.robots.mark_reach`):
    first the floating harness's start check on the same poses (what it excludes as
    infeasible, the gripper in the object or the table, is excluded alike: START_COLLISION,
    never planned), then :func:`plan_grasp` with the capability map's seed. Returns the
    plans and the start check's penetrations into the object and the table (N,) [m].
    ``on_progress(k)``: the grasps finished (refused) so far; ``on_planned(k)``: the
    grasps judged so far, refused or not."""
    from graspsim.sim.batch import initial_states, start_overlaps
    from graspsim.sim.trial_scene import build_scene

    T_world = np.asarray(T_world_wrist, float).reshape(-1, 4, 4)
    openings = np.asarray(openings, float).reshape(-1)
    n = len(T_world)
    floating = build_scene(scene.obj, scene.gripper, scene.settings, T_world_obj=scene.T_world_obj)
    on_object, on_table = start_overlaps(floating, initial_states(floating, T_world, openings), T_world)
    blocked = np.maximum(on_object, on_table) > scene.settings.start_penetration
    kin = scene.kinematics()
    seeds = capability.lookup(T_world)[1] if capability is not None else np.full((n, 7), np.nan)
    plans = []
    finished = 0  # grasps planned and not to be executed: finished trials
    for i in range(n):
        if blocked[i]:
            plans.append(ArmPlan(ReachCheck(Reach.START, "grasp"), TrialOutcome.START_COLLISION, "grasp"))
        else:
            s = () if np.isnan(seeds[i]).any() else (seeds[i],)
            plans.append(plan_grasp(scene, kin, T_world[i], float(openings[i]), protocol, seeds=s))
        finished += plans[-1].outcome is not None
        if on_progress is not None and i % 8 == 7:
            on_progress(finished)
        if on_planned is not None:
            on_planned(i + 1)
    return plans, on_object, on_table


def run_arm_trials(scene: ArmScene, T_obj_wrist: np.ndarray, widths: np.ndarray,
                   protocol: ArmLiftPlace = ArmLiftPlace(), *, threads: int | None = None, seed: int = 0,
                   noise: ExecutionNoise | None = None, capability=None, on_progress=None) -> TrialResults:
    """Plan and execute N grasps (T_obj_wrist (N, 4, 4), contact widths (N,) [m]) with
    the arm (module doc): the counterpart of :func:`graspsim.sim.batch.run_trials`, with
    the same noise draw, jaw openings and results. ``capability``: a
    :class:`~graspsim.robots.capability.CapabilityMap` whose seeds start the IK.
    ``extra["plan"]`` holds each grasp's reachability verdict and failing stage."""
    t_start = time.perf_counter()
    from graspsim.sim.batch import run_in_chunks, trial_inputs

    T_world, widths, threads = trial_inputs(scene, T_obj_wrist, widths, threads=threads, seed=seed, noise=noise)
    n = len(T_world)
    openings = scene.gripper.pregrasp_opening(widths)
    plans, on_object, on_table = plan_grasps(scene, T_world, openings, protocol, capability=capability,
                                             on_progress=on_progress)
    tol = scene.settings.start_penetration
    blocked = np.maximum(on_object, on_table) > tol
    outcome = np.array([TrialOutcome.SUCCESS if p.outcome is None else p.outcome for p in plans], np.int8)
    metrics = {k: np.full(n, np.nan) for k in protocol.metric_names}
    metrics["reach"] = np.array([float(p.check.reach) for p in plans])  # the Reach code of each grasp
    todo = np.flatnonzero([p.outcome is None for p in plans])
    done = n - len(todo)
    if on_progress is not None:
        on_progress(done)
    m = scene.model
    state0 = _initial_states(scene, openings)
    obj_q = m.qpos0[scene.qadr_obj:scene.qadr_obj + 7]
    chunk = 8 * threads
    S = protocol.nstep(m.opt.timestep)
    with rollout.Rollout(nthread=threads if threads > 1 else 0) as pool:
        datas = [mujoco.MjData(m) for _ in range(threads)]

        def run(idx: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
            ctrl = arm_controls(scene, protocol, [plans[i] for i in idx], openings[idx])
            states, sens = pool.rollout([m] * len(idx), datas, np.ascontiguousarray(state0[idx]),
                                        np.ascontiguousarray(ctrl), control_spec=int(_CTRL), nstep=S,
                                        initial_warmstart=np.zeros((len(idx), m.nv)))
            rec = _record(scene, states, sens)
            return _judge(scene, protocol, rec, T_world[idx], np.repeat(obj_q[None], len(idx), axis=0))

        run_in_chunks(todo, chunk, run, outcome, metrics, done=done, on_progress=on_progress)
    wall = time.perf_counter() - t_start
    arm_start = np.array([p.outcome == TrialOutcome.START_COLLISION and not blocked[i] for i, p in enumerate(plans)])
    depth = np.maximum(on_object, on_table)
    start = np.where(blocked, np.where(on_object > tol, "object", "table"), "")
    for i in np.flatnonzero(arm_start):  # the arm's own check found the gripper in collision at the grasp
        c = plans[i].check.contacts
        depth[i] = max(c["gripper_scene"], c["gripper_table"])
        start[i] = "object" if c["gripper_scene"] > 0 else "table"
    start = start.astype("<U6")
    held = np.isin(outcome, [TrialOutcome.SUCCESS, TrialOutcome.PLACE_FAILED]).astype(np.int8)
    log.info("%d arm trials (%d executed) in %.2f s", n, len(todo), wall)
    return TrialResults(
        outcome=outcome, metrics=metrics, object_in_gripper=held, start_penetration=depth, T_world_wrist=T_world,
        protocol=protocol.to_dict(), scene=scene.info(), seed=int(seed),
        noise=None if noise is None else noise.to_dict(), threads=threads, wall_time=wall,
        simulated_seconds=len(todo) * S * m.opt.timestep, start_kind=start,
        extra={"plan": plan_counts(plans)})


def plan_counts(plans: list[ArmPlan]) -> dict:
    """How many grasps each reachability verdict and each failing stage got."""
    reach, stage = {}, {}
    for p in plans:
        reach[p.check.reach.label] = reach.get(p.check.reach.label, 0) + 1
        if p.outcome is not None:
            stage[p.stage] = stage.get(p.stage, 0) + 1
    return {"reach": reach, "not_executed_at": stage}
