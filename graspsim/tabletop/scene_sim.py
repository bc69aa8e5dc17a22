"""A table with several objects and the gripper, in MuJoCo: settle, look, grasp, remove.

Frames as in :mod:`graspsim.sim.trial_scene`: world z up, the table top is the plane z = 0;
object ``k``'s body frame is its object frame, its pose ``T_world_obj``. The gripper
waits far above the table (``HOME``; its geoms are in geom group 2, hidden from the
camera) until :meth:`SceneSim.execute` puts its wrist at a pose, closes and lifts by the
:class:`~graspsim.sim.protocols.LiftPlace` schedule (settle, close, lift, hold; no
placing: a picked object leaves the scene). A removed object is parked far away, its
collisions off and its weight compensated, so the model compiles once per scene and every
operation is deterministic.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.geometry.camera import Camera, DepthFrame, Intrinsics
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.sim.batch import arm_below_table, simulate
from graspsim.sim.model import NAMES
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.outcomes import TrialOutcome, collision_kind
from graspsim.sim.protocols import LiftPlace
from graspsim.sim.trial_scene import (
    SimSettings,
    _add_object,
    _add_table,
    _set_options,
    add_gripper,
    add_pad_sensors,
    gripper_drive,
    gripper_geoms,
)
from graspsim.tabletop.depth_render import DepthRenderer
from graspsim.tabletop.scene_objects import ObjectSpec
from graspsim.transforms import make_transform, matrix_to_quat, quat_to_matrix

__all__ = ["SceneSim", "SceneOutcome", "collision_kind", "HOME", "GRIPPER_GROUP", "TABLE_REGION"]

log = logging.getLogger(__name__)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
HOME = (0.0, 0.0, 3.0)  # the waiting gripper's wrist [m]
GRIPPER_GROUP = 2
BIN_GROUP = 3
TABLE_REGION = 0.35  # [m]: objects rest within +-this in x and y (the drawn table: +-0.4)
_PALETTE = np.array([[0.85, 0.55, 0.2], [0.2, 0.55, 0.85], [0.3, 0.75, 0.35], [0.85, 0.3, 0.35],
                     [0.6, 0.4, 0.8], [0.9, 0.8, 0.3], [0.3, 0.8, 0.8], [0.55, 0.35, 0.2]])


@dataclass(frozen=True)
class SceneOutcome:
    """One grasp in a scene. outcome: a :class:`TrialOutcome`; picked: the object lifted
    and held (None: none); target: the object meant (None: not said); cause: the outcome
    label, START_COLLISION refined by :func:`collision_kind` to ``start_collision_target |
    _both | _neighbour | _table`` (``_object`` when no target was named),
    ``success_other_object`` when another object than the target came up;
    collided: what the gripper overlaps at t = 0 beyond ``start_penetration`` (object
    ids, "table"); penetration [m]: the deepest overlap; lift_height [m]: how far the
    picked (else the target) object rose; moved: other objects displaced > 1 cm."""

    outcome: TrialOutcome
    picked: int | None
    target: int | None
    cause: str
    collided: tuple = ()
    penetration: float = 0.0
    lift_height: float = 0.0
    moved: tuple[int, ...] = ()
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.picked is not None

    def to_dict(self) -> dict:
        return {"outcome": self.outcome.label, "picked": self.picked, "target": self.target, "cause": self.cause,
                "collided": list(self.collided), "penetration": self.penetration,
                "lift_height": self.lift_height, "moved": list(self.moved), **self.extra}


class SceneSim:
    """The compiled scene. objects: (ObjectSpec or SimObject, T_world_obj (4, 4)) pairs;
    object ids are their indices. table_rolling [m]: rolling resistance on the table (without it a
    dropped ball rolls off); held_height [m]: a picked object rose at least this much;
    bin [m]: walls around [-bin, bin]^2 that hold a pile while it settles (``open_bin``).

    robot: an arm (:class:`graspsim.robots.ArmSpec`) standing at ``base`` (x [m], y [m],
    yaw [rad] on the table top, default :data:`graspsim.robots.arm.DEFAULT_BASE`, or a
    (4, 4) pose) carries the gripper (any: see :mod:`graspsim.robots.arm`) on its flange instead of the
    floating wrist: it waits at its home pose, hidden from the camera like the floating
    gripper; :meth:`plan_arm` checks a grasp's reachability in the scene as it lies
    (:func:`graspsim.robots.execute.plan_grasp`: IK, the approach, collisions with the
    table and every object) and :meth:`execute` drives the arm's servos through the plan
    (:class:`graspsim.robots.ArmLiftPlace`'s move, approach, arrive, then this scene's
    settle, close, lift and hold)."""

    def __init__(self, objects: Sequence[tuple[ObjectSpec, np.ndarray]], *,
                 gripper: GripperSpec = HGPL_25_60_A, settings: SimSettings = SimSettings(),
                 protocol: LiftPlace = LiftPlace(), table_rolling: float = 0.003,
                 held_height: float = 0.05, bin: float | None = None, robot=None, base=None) -> None:
        if not objects:
            raise InvalidParameterError("a scene needs at least one object")
        self.gripper, self.settings, self.protocol, self.held_height = gripper, settings, protocol, held_height
        self.specs = [o for o, _ in objects]
        self.sim_objects = [o.sim_object() if isinstance(o, ObjectSpec) else o for o in self.specs]
        s = settings
        self.robot = robot
        force = gripper.grip_force if s.grip_force is None else s.grip_force
        if robot is None:
            spec, names = add_gripper(gripper, s, force, HOME)
        else:
            spec, names, arm_names = self._arm_spec(robot, base, force)
        for g in spec.geoms:
            g.group = GRIPPER_GROUP
        spec.modelname = f"table_scene_{gripper.name}"
        _set_options(spec, s)
        spec.visual.quality.offsamples = 0  # no multisampling: a 40 % faster renderer, same depth and labels
        _add_table(spec, s, rolling=table_rolling)
        if bin is not None:  # four walls around [-bin, bin]^2, 40 cm high, never drawn
            for i, (x, y, hx, hy) in enumerate([(bin + 0.01, 0, 0.01, bin + 0.02), (-bin - 0.01, 0, 0.01, bin + 0.02),
                                                (0, bin + 0.01, bin + 0.02, 0.01), (0, -bin - 0.01, bin + 0.02, 0.01)]):
                spec.worldbody.add_geom(name=f"bin_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[x, y, 0.2],
                                        size=[hx, hy, 0.2], group=BIN_GROUP, rgba=[0.5, 0.5, 0.5, 0.3])
        for k, (_, T) in enumerate(objects):
            T = np.asarray(T, float)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise InvalidParameterError(f"object {k}'s pose must be a finite 4x4 transform")
            _add_object(spec, self.sim_objects[k], T, s, name=f"obj{k}", rgba=(*_PALETTE[k % len(_PALETTE)], 1.0))
            add_pad_sensors(spec, gripper, names, f"obj{k}", f"_{k}")
        try:
            self.model = m = spec.compile()
        except ValueError as err:
            raise SimulationError(f"the table scene does not compile: {' '.join(str(err).split())}") from err
        n = len(objects)
        self.body = np.array([m.body(f"obj{k}").id for k in range(n)])
        self.qadr = np.array([m.jnt_qposadr[m.joint(f"obj{k}").id] for k in range(n)])
        self.dadr = np.array([m.jnt_dofadr[m.joint(f"obj{k}").id] for k in range(n)])
        self.geom_object = np.full(m.ngeom, -1, np.int32)
        for k, b in enumerate(self.body):
            self.geom_object[m.geom_bodyid == b] = k
        self.table_geom = m.geom("table").id
        self.bin_geoms = np.array([m.geom(f"bin_{i}").id for i in range(4)] if bin is not None else [], int)
        self.drive = gripper_drive(m, gripper)
        self.pad_adr = np.array([[m.sensor_adr[m.sensor(f"pad_{side}_{k}").id] for side in ("neg", "pos")]
                                 for k in range(n)])
        self.qadr_jaws = self.drive.qadr_jaws
        self.data = mujoco.MjData(m)
        if robot is None:
            self.gripper_geoms = gripper_geoms(m)
            self.qadr_wrist = int(m.jnt_qposadr[m.joint(NAMES.wrist).id])
            self.dadr_wrist = int(m.jnt_dofadr[m.joint(NAMES.wrist).id])
        else:
            self._arm_setup(arm_names)
            # the camera's depth range follows the model's extent, which the arm widens: keep the
            # floating gripper's scene's, so that both see the very same depth frames
            twin = SceneSim([(o, T) for o, (_, T) in zip(self.sim_objects, objects)], gripper=gripper,
                            settings=settings, protocol=protocol, table_rolling=table_rolling,
                            held_height=held_height, bin=bin)
            m.stat.extent, m.stat.center[:] = twin.model.stat.extent, twin.model.stat.center
        mujoco.mj_forward(m, self.data)
        self._left = list(range(n))
        self._renderer: DepthRenderer | None = None

    # -- the arm ----------------------------------------------------------------
    def _arm_spec(self, robot, base, force: float):
        """The spec with ``robot`` at ``base`` carrying the gripper (class doc)."""
        from graspsim.robots.arm import DEFAULT_BASE, add_arm, base_transform

        s = self.settings
        self.T_world_base = base_transform(DEFAULT_BASE if base is None else base)
        spec = mujoco.MjSpec()
        spec.compiler.degree = False
        arm_names = add_arm(spec, robot, self.gripper, s.physics, force=force,
                            friction=(s.friction, s.torsional_friction, s.rolling_friction), condim=s.condim,
                            T_world_base=self.T_world_base)
        spec.add_exclude(bodyname1="world", bodyname2=arm_names.bodies[0])  # the base stands on the table
        for site, kind in (("pos", mujoco.mjtSensor.mjSENS_FRAMEPOS), ("quat", mujoco.mjtSensor.mjSENS_FRAMEQUAT)):
            spec.add_sensor(name=f"wrist_{site}", type=kind, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=NAMES.wrist)
        from graspsim.sim.authored_model import authored_names

        return spec, authored_names(self.gripper), arm_names

    def _arm_setup(self, arm_names) -> None:
        """Addresses of the arm; the arm at home, its servos holding it there, the jaws open."""
        from graspsim.robots.arm import build_robot_model
        from graspsim.robots.execute import ArmLiftPlace
        from graspsim.robots.reach import ArmKinematics

        m, d, robot = self.model, self.data, self.robot
        self.qadr_wrist = self.dadr_wrist = None
        self.qadr_arm = m.jnt_qposadr[[m.joint(j).id for j in arm_names.joints]].copy()
        self.dadr_arm = m.jnt_dofadr[[m.joint(j).id for j in arm_names.joints]].copy()
        self.act_arm = np.array([m.actuator(a).id for a in arm_names.actuators])
        self.wrist_sensors = (int(m.sensor_adr[m.sensor("wrist_pos").id]), int(m.sensor_adr[m.sensor("wrist_quat").id]))
        self.arm = robot
        self.arm_protocol = ArmLiftPlace(lift=self.protocol)
        self.kin = ArmKinematics(m, robot, ik_model=build_robot_model(robot, self.gripper, self.T_world_base,
                                                                      table=False))
        self.gripper_geoms = np.flatnonzero(self.kin.gripper_geom)
        self._capability = None
        self._arm_home(d)

    def _arm_home(self, d) -> None:
        """The arm at home at rest, its servos' targets there, the jaws open and commanded open."""
        home = np.asarray(self.arm.home, float)
        d.qpos[self.qadr_arm] = home
        d.qvel[self.dadr_arm] = 0.0
        d.ctrl[self.act_arm] = home
        w = self.gripper.max_opening
        d.qpos[self.drive.qadr] = self.drive.joint_positions([w])[0]
        d.qvel[self.drive.dadr] = 0.0
        grip = self.drive.controls(np.zeros((1, 1)), np.array([w]))[0, 0]
        d.ctrl[:len(grip)] = grip

    def _need_arm(self, what: str) -> None:
        if self.robot is None:
            raise InvalidParameterError(f"{what} needs a scene with an arm (SceneSim(robot=...))")

    def reach_first_cut(self, T_world_wrist: np.ndarray, *, config=None, cache_dir=None) -> tuple[np.ndarray,
                                                                                                   np.ndarray]:
        """The fast first cut of wrist poses (N, 4, 4): the arm's capability map
        (:func:`graspsim.robots.capability_map`, cached) -> (reachable (N,) bool, IK seed
        joints (N, 7), NaN where not)."""
        self._need_arm("the reachability first cut")
        if self._capability is None:
            from graspsim.robots.arm import build_robot_model
            from graspsim.robots.capability import CapabilityConfig, capability_map

            self._capability = capability_map(build_robot_model(self.arm, self.gripper, self.T_world_base), self.arm,
                                              self.T_world_base, config or CapabilityConfig(), cache_dir=cache_dir)
        return self._capability.lookup(np.asarray(T_world_wrist, float).reshape(-1, 4, 4))

    def plan_arm(self, T_world_wrist: np.ndarray, opening: float, seed: np.ndarray | None = None):
        """The arm's plan of the grasp at ``T_world_wrist`` (4, 4) with the jaws open to
        ``opening`` [m], checked against the table and every object where they lie now
        (:func:`graspsim.robots.execute.plan_grasp`; ``seed``: joints to start the IK
        from, e.g. the first cut's): an :class:`~graspsim.robots.execute.ArmPlan` whose
        ``outcome`` is None when it can be executed."""
        from graspsim.robots.execute import plan_grasp

        self._need_arm("plan_arm")
        self.kin.set_scene(self.data.qpos)
        s = () if seed is None or np.isnan(seed).any() else (np.asarray(seed, float),)
        return plan_grasp(self, self.kin, np.asarray(T_world_wrist, float), float(opening), self.arm_protocol,
                          seeds=s)

    # -- state ------------------------------------------------------------------
    @property
    def nstate(self) -> int:
        return mujoco.mj_stateSize(self.model, _FULL)

    def objects_left(self) -> list[int]:
        """Ids of the objects still in the scene."""
        return list(self._left)

    def pose(self, k: int) -> np.ndarray:
        """T_world_obj (4, 4) of object ``k`` now."""
        q = self.data.qpos[self.qadr[k]:self.qadr[k] + 7]
        return make_transform(quat_to_matrix(q[3:]), q[:3])

    def poses(self) -> dict[int, np.ndarray]:
        return {k: self.pose(k) for k in self._left}

    def outside(self, region: float = TABLE_REGION) -> list[int]:
        """Objects left whose centre lies beyond +-``region`` [m] in x or y (off the table:
        knocked away; the simulated table top is unbounded)."""
        return [k for k in self._left if np.any(np.abs(self.data.qpos[self.qadr[k]:self.qadr[k] + 2]) > region)]

    def speeds(self) -> np.ndarray:
        """(n_left, 2) linear [m/s] and angular [rad/s] speed of the objects left."""
        v = np.array([self.data.qvel[a:a + 6] for a in self.dadr[self._left]]).reshape(-1, 6)
        return np.column_stack([np.linalg.norm(v[:, :3], axis=1), np.linalg.norm(v[:, 3:], axis=1)])

    def settle(self, *, max_time: float = 3.0, speed: float = 0.005, spin: float = 0.05) -> float:
        """Step with the gripper away until every object is at rest (below ``speed`` [m/s]
        and ``spin`` [rad/s] for 0.1 s) or ``max_time`` [s] passed; returns the time taken."""
        m, d = self.model, self.data
        dt, calm, t = m.opt.timestep, 0, 0.0
        every = max(1, int(round(0.02 / dt)))
        while t < max_time:
            for _ in range(every):
                mujoco.mj_step(m, d)
            t += every * dt
            v = self.speeds()
            if not np.all(np.isfinite(v)):
                raise SimulationError("the scene's simulation diverged while settling")
            calm = calm + 1 if (len(v) == 0 or (v[:, 0].max() < speed and v[:, 1].max() < spin)) else 0
            if calm * every * dt >= 0.1:
                break
        return t

    def open_bin(self) -> None:
        """Take the bin's walls away (their collisions off): what leaned on them falls."""
        self.model.geom_contype[self.bin_geoms] = 0
        self.model.geom_conaffinity[self.bin_geoms] = 0

    def remove(self, k: int) -> None:
        """Take object ``k`` out of the scene: parked far away, collisions off, weightless."""
        if k not in self._left:
            raise InvalidParameterError(f"object {k} is not in the scene; left: {self._left}")
        m, d = self.model, self.data
        geoms = self.geom_object == k
        m.geom_contype[geoms] = 0
        m.geom_conaffinity[geoms] = 0
        m.body_gravcomp[self.body[k]] = 1.0
        a = self.qadr[k]
        d.qpos[a:a + 7] = [10.0 + 0.5 * k, 10.0, 1.0, 1.0, 0.0, 0.0, 0.0]
        d.qvel[self.dadr[k]:self.dadr[k] + 6] = 0.0
        self._left.remove(k)
        mujoco.mj_forward(m, d)

    # -- looking ----------------------------------------------------------------
    def render(self, camera: Camera, *, noise=None, rng: np.random.Generator | None = None,
               rgb: bool = False, gripper_at: tuple[np.ndarray, float] | None = None) -> DepthFrame:
        """A :class:`DepthFrame` of the scene now, ``labels`` = object id per pixel (-1:
        the table, the gripper or nothing). The gripper is hidden, unless ``gripper_at`` =
        (T_world_wrist (4, 4), opening [m]) shows it there (for pictures of a grasp;
        nothing is simulated and the scene is left as it was)."""
        r = self._renderer_for(camera.intrinsics)
        d = self.data
        if gripper_at is not None:
            if self.robot is not None:
                raise InvalidParameterError("a scene with an arm does not draw the gripper at a pose (gripper_at)")
            d = mujoco.MjData(self.model)
            mujoco.mj_setState(self.model, d, self._start_state(np.asarray(gripper_at[0], float),
                                                                float(gripper_at[1])), _FULL)
            mujoco.mj_forward(self.model, d)
        r.scene_option.geomgroup[GRIPPER_GROUP] = int(gripper_at is not None)
        f = r.render(d, camera, noise=noise, rng=rng, segmentation=True, rgb=rgb)
        labels = np.where(f.segmentation >= 0, self.geom_object[np.maximum(f.segmentation, 0)], -1)
        return DepthFrame(f.depth, camera, f.segmentation, labels.astype(np.int32), f.rgb, f.noise)

    def _renderer_for(self, intrinsics: Intrinsics) -> DepthRenderer:
        if self._renderer is None or self._renderer.intrinsics != intrinsics:
            self.close()
            opt = mujoco.MjvOption()
            opt.geomgroup[GRIPPER_GROUP] = 0
            opt.geomgroup[BIN_GROUP] = 0
            # sites and tendons are markers with no surface a camera could see: a model file's
            # (the Robotiq 2F-85's 5 mm grip-site cylinder, metres long) stood in the depth
            # image over the table as a rod of points, segmented and planned as an object
            opt.sitegroup[:] = 0
            opt.tendongroup[:] = 0
            self._renderer = DepthRenderer(self.model, intrinsics, scene_option=opt)
        return self._renderer

    def close(self) -> None:
        """Free the renderer's GL context (a later render makes a new one)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- grasping ---------------------------------------------------------------
    def _start_state(self, T: np.ndarray, opening: float) -> np.ndarray:
        state = np.empty(self.nstate)
        mujoco.mj_getState(self.model, self.data, state, _FULL)
        q = 1 + self.qadr_wrist
        state[q:q + 3], state[q + 3:q + 7] = T[:3, 3], matrix_to_quat(T[:3, :3])
        state[1 + self.drive.qadr] = self.drive.joint_positions([opening])[0]
        v = 1 + self.model.nq
        state[v:v + self.model.nv] = 0.0
        state[0] = 0.0
        return state

    def _gripper_contacts(self, state: np.ndarray) -> list[tuple[int, object, float]]:
        """(gripper geom id, object id | "table", overlap [m]) of every contact of the
        gripper at ``state`` (kinematics and collision detection only)."""
        m, d = self.model, mujoco.MjData(self.model)
        mujoco.mj_setState(m, d, state, _FULL)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        grip = np.zeros(m.ngeom, bool)
        grip[self.gripper_geoms] = True
        out = []
        for (g1, g2), gap in zip(d.contact.geom[:d.ncon], d.contact.dist[:d.ncon]):
            if grip[g1] == grip[g2]:
                continue
            mine, other = (g1, g2) if grip[g1] else (g2, g1)
            what = "table" if other == self.table_geom else int(self.geom_object[other])
            if what != -1:
                out.append((int(mine), what, -float(gap)))
        return out

    def overlaps(self, T_world_wrist: np.ndarray, opening: float) -> dict[tuple[str, object], float]:
        """Where the gripper at ``T_world_wrist`` with the jaws open to ``opening`` [m]
        would start: {(gripper part's geom name, object id | "table"): deepest overlap
        [m]} over its contacts (touching ones included, overlap <= 0). Nothing is
        simulated or changed (diagnosis of start collisions). The floating gripper's only."""
        if self.robot is not None:
            raise InvalidParameterError("overlaps() poses the floating gripper; a scene with an arm has none")
        state = self._start_state(np.asarray(T_world_wrist, float), float(opening))
        out: dict[tuple[str, object], float] = {}
        for g, what, depth in self._gripper_contacts(state):
            key = (self.model.geom(g).name, what)
            out[key] = max(out.get(key, -np.inf), depth)
        return out

    def _collisions(self, state: np.ndarray, T: np.ndarray) -> tuple[tuple, float]:
        """What the gripper overlaps by more than the tolerance at ``state``, and how deep."""
        hits: dict = {}
        for _, what, depth in self._gripper_contacts(state):
            hits[what] = max(hits.get(what, 0.0), depth)
        arm = float(arm_below_table(self.gripper, T[None])[0])
        if arm > 0:
            hits["table"] = max(hits.get("table", 0.0), arm)
        tol = self.settings.start_penetration
        bad = {k: v for k, v in hits.items() if v > tol}
        keys = sorted(k for k in bad if k != "table") + (["table"] if "table" in bad else [])
        return tuple(keys), max(hits.values(), default=0.0)

    def execute(self, T_world_wrist: np.ndarray, opening: float | None = None, *, width: float | None = None,
                target: int | None = None, noise: ExecutionNoise | None = None,
                rng: np.random.Generator | None = None, commit: bool = True, plan=None) -> SceneOutcome:
        """Grasp at ``T_world_wrist`` (4, 4) with the jaws open to ``opening`` [m] (or give
        a map's contact ``width`` [m]: the jaws open to ``gripper.pregrasp_opening(width)``),
        close and lift. noise: the arm misses the pose by one draw from ``rng`` (the
        outcome's ``extra["T_world_wrist"]`` is the pose executed). commit: keep what
        happened (a picked object is removed, the others settle where the attempt left
        them); False leaves the scene as it was.

        With an arm (class doc): ``plan`` (:meth:`plan_arm` of this pose; None, or a pose
        moved by ``noise``: planned here) is executed by the servos; a plan the check
        refused is not simulated: UNREACHABLE or APPROACH_COLLISION (cause the same; the
        failing stage in ``extra["stage"]``), or START_COLLISION when the gripper is in an
        object or the table at the grasp. A failed execution whose objects had moved more
        than ``ArmLiftPlace.approach_push`` before the close is APPROACH_COLLISION, one
        whose wrist missed its target by more than ``reach_tol`` CONTROLLER_ERROR
        (:func:`graspsim.robots.execute.arm_failures`)."""
        T = np.asarray(T_world_wrist, float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidParameterError(f"T_world_wrist must be a finite 4x4 transform, got shape {T.shape}")
        if (opening is None) == (width is None):
            raise InvalidParameterError("give the jaw opening or the contact width, one of them")
        if width is not None:
            opening = float(self.gripper.pregrasp_opening(np.array([width]))[0])
        if noise is not None:
            if rng is None:
                raise InvalidParameterError("execution noise needs rng (a seeded numpy Generator)")
            T = T @ noise.sample(1, rng, pivot=self.gripper.nominal_tcp)[0]
            plan = None  # the arm aims at the pose it missed by
        if not (self.gripper.min_opening <= opening <= self.gripper.max_opening):
            raise InvalidParameterError(f"opening {opening!r} m outside the gripper's "
                                        f"[{self.gripper.min_opening}, {self.gripper.max_opening}] m")
        if target is not None and target not in self._left:
            raise InvalidParameterError(f"target {target} is not in the scene; left: {self._left}")
        if self.robot is not None:
            out = self._execute_arm(T, opening, target, commit, plan)
            out.extra.update(T_world_wrist=T.tolist(), opening=opening)
            return out
        state0 = self._start_state(T, opening)
        collided, depth = self._collisions(state0, T)
        if collided:
            kind = collision_kind(collided, target)
            return SceneOutcome(TrialOutcome.START_COLLISION, None, target, f"start_collision_{kind}",
                                collided, depth, extra={"T_world_wrist": T.tolist(), "opening": opening})
        out = self._run(T, state0, target, depth, commit, opening)
        out.extra.update(T_world_wrist=T.tolist(), opening=opening)
        return out

    def _run(self, T, state0, target, depth, commit, opening) -> SceneOutcome:
        p, m = self.protocol, self.model
        ph = p.steps(m.opt.timestep)
        c1, h1 = ph["close"][1], ph["hold"][1]
        control = p.controls(self, T[None], np.array([opening]))[:, :h1 + 1]
        states, sens = simulate(self, p, state0[None], np.ascontiguousarray(control))
        return self._judge(states[0], sens[0], target, depth, commit, c1, h1)

    def _judge(self, states, sens, target, depth, commit, c1: int, h1: int, rename=None) -> SceneOutcome:
        """The outcome of a simulated grasp (states (S, nstate), sensors (S, ns); the close
        ends at step ``c1``, the hold at ``h1``); ``rename(outcome, xyz)``: the arm's names
        of a failure (None: the floating gripper's)."""
        p, m = self.protocol, self.model
        qpos = states[:, 1:1 + m.nq]
        left = np.array(self._left, int)
        z = qpos[:, self.qadr[left] + 2]  # (S, n_left)
        pads = np.stack([sens[:, self.pad_adr[left] + i] for i in range(4)], -1)  # (S, n, 2, 4)
        touching = ((pads[..., 0] > 0) & (np.linalg.norm(pads[..., 1:], axis=-1) > 1e-3)).sum(-1)
        rise = z[h1] - z[0]
        held = (touching[h1] == 2) & (rise > self.held_height)
        v = states[:, 1 + m.nq:1 + m.nq + m.nv]
        lin = np.linalg.norm(v[:, self.dadr[left][:, None] + np.arange(3)], axis=-1)  # (S, n_left)
        if not (np.all(np.isfinite(states)) and lin.max(initial=0.0) <= p.max_speed):
            out, picked = TrialOutcome.SIM_UNSTABLE, None
        elif held.any():
            out, picked = TrialOutcome.SUCCESS, int(left[np.argmax(np.where(held, rise, -np.inf))])
        elif not np.any(touching[c1] == 2):
            out, picked = TrialOutcome.NO_CONTACT, None
        elif np.any(touching[h1] == 2):
            out, picked = TrialOutcome.SLIPPED, None
        else:
            out, picked = TrialOutcome.DROPPED, None
        if rename is not None:
            out = rename(out, qpos[:, self.qadr[left][:, None] + np.arange(3)])
        who = picked if picked is not None else target
        lift = float(rise[list(left).index(who)]) if who is not None else 0.0
        xyz = qpos[:, self.qadr[left][:, None] + np.arange(3)]  # (S, n_left, 3)
        moved = tuple(int(k) for k, dd in zip(left, np.linalg.norm(xyz[-1] - xyz[0], axis=1))
                      if k != picked and dd > 0.01)
        if commit:
            self._commit(states[-1], picked)
        cause = "success_other_object" if picked is not None and target not in (None, picked) else out.label
        return SceneOutcome(out, picked, target, cause, (), depth, lift, moved)

    def _commit(self, state: np.ndarray, picked: int | None) -> None:
        """Continue from ``state``: the picked object out, the gripper home, the rest settle."""
        m, d = self.model, self.data
        mujoco.mj_setState(m, d, state, _FULL)
        if self.robot is not None:  # the arm back home (as the floating gripper: put there)
            self._arm_home(d)
        else:
            q, v = self.qadr_wrist, self.dadr_wrist
            d.qpos[q:q + 7] = [*HOME, 0.0, 1.0, 0.0, 0.0]
            d.qpos[self.drive.qadr] = self.drive.joint_positions([self.gripper.max_opening])[0]
            d.qvel[v:v + 6] = 0.0
            d.qvel[self.drive.dadr] = 0.0
        if picked is not None:
            self.remove(picked)
        mujoco.mj_forward(m, d)
        self.settle(max_time=1.0)

    def _execute_arm(self, T, opening, target, commit, plan) -> SceneOutcome:
        """The arm's grasp (:meth:`execute`): the plan, then the servos through the hold."""
        from mujoco import rollout

        from graspsim.robots.execute import arm_controls, arm_failures
        from graspsim.robots.reach import pose_error

        if plan is None:
            plan = self.plan_arm(T, opening)
        extra = {"stage": plan.stage, "reach": plan.check.reach.label}
        if plan.outcome is TrialOutcome.START_COLLISION:  # the gripper in an object or the table at the grasp
            state = np.empty(self.nstate)
            mujoco.mj_getState(self.model, self.data, state, _FULL)
            state[1 + self.qadr_arm] = plan.check.q
            state[1 + self.drive.qadr] = self.drive.joint_positions([opening])[0]
            hits: dict = {}
            for _, what, d in self._gripper_contacts(state):
                hits[what] = max(hits.get(what, 0.0), d)
            bad = {k: v for k, v in hits.items() if v > self.settings.start_penetration}
            collided = tuple(sorted(k for k in bad if k != "table")) + (("table",) if "table" in bad else ())
            kind = collision_kind(collided, target) if collided else "table"
            return SceneOutcome(TrialOutcome.START_COLLISION, None, target, f"start_collision_{kind}", collided,
                                max(hits.values(), default=0.0), extra=extra)
        if plan.outcome is not None:  # refused by the check: never executed
            return SceneOutcome(plan.outcome, None, target, plan.outcome.label, extra=extra)
        ap, m = self.arm_protocol, self.model
        ph = ap.steps(m.opt.timestep)
        c1, h1, k = ph["close"][1], ph["hold"][1], ph["settle"][0] - 1  # k: the arrival's end, before the close
        state0 = np.empty(self.nstate)
        mujoco.mj_getState(m, self.data, state0, _FULL)
        state0[0] = 0.0
        state0[1 + self.qadr_arm] = self.arm.home
        state0[1 + self.drive.qadr] = self.drive.joint_positions([opening])[0]
        state0[1 + m.nq:1 + m.nq + m.nv] = 0.0
        ctrl = arm_controls(self, ap, [plan], np.array([opening]))[:, :h1 + 1]
        states, sens = rollout.rollout([m], [mujoco.MjData(m)], state0[None], np.ascontiguousarray(ctrl),
                                       control_spec=int(mujoco.mjtState.mjSTATE_CTRL), nstep=h1 + 1,
                                       initial_warmstart=np.zeros((1, m.nv)))
        states, sens = states[0], sens[0]
        wp, wq = self.wrist_sensors
        W = make_transform(quat_to_matrix(sens[k, wq:wq + 4]), sens[k, wp:wp + 3])
        err = np.array(pose_error(W, T))
        met = {}

        def rename(out, xyz):
            met["approach_push"] = float(np.linalg.norm(xyz[k] - xyz[0], axis=1).max(initial=0.0))
            return TrialOutcome(int(arm_failures(np.array([out]), [met["approach_push"]], err[None], ap)[0]))

        out = self._judge(states, sens, target, 0.0, commit, c1, h1, rename=rename)
        out.extra.update(extra, reach_lin=float(err[0]), reach_ang=float(err[1]), **met)
        return out
