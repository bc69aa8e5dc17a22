"""Whether an arm reaches a wrist pose: inverse kinematics with mink, joint limits,
collisions from MuJoCo's own collision detection.

:class:`ArmKinematics` works on any compiled model holding an arm built by
:func:`graspsim.robots.arm.add_arm` (the bare robot above the table, or a trial scene
with the object): ``ik`` solves for the wrist frame with mink's differential IK (a
:class:`mink.FrameTask` on the ``wrist`` site, a small posture task toward the seed that
settles the arm's redundancy, :class:`mink.ConfigurationLimit`'s rows keeping every
iterate inside the joint limits), iterated to convergence; ``contacts`` poses the arm (and the
gripper's jaws at an opening) and sorts MuJoCo's contacts into self-collisions, the
table, and the rest of the scene. :func:`check_reach` applies both to a grasp: its wrist
pose, the pre-grasp pose ``approach`` back along the approach axis, and the straight
line between them (the Cartesian approach), each solved from the one before.
"""

from __future__ import annotations

import ctypes
import enum
import math
from dataclasses import dataclass

import mujoco
import numpy as np
import qpsolvers

from graspsim.errors import InvalidParameterError
from graspsim.robots.arm import ArmSpec

__all__ = ["ArmKinematics", "IKResult", "Reach", "ReachCheck", "check_reach", "pose_error", "POS_TOL", "ROT_TOL"]

#: IK convergence: wrist position [m] and orientation [rad] errors a solution may keep
POS_TOL = 1e-4
ROT_TOL = math.radians(0.05)


def _joint_limit(model: mujoco.MjModel):
    """The joint-position limit of mink's IK for ``model``: :class:`mink.ConfigurationLimit`'s
    rows, computed without its per-step allocations when every limited joint is a hinge
    or a slide (the arms' and grippers' joints); mink's own limit otherwise."""
    import mink

    limited = [j for j in range(model.njnt)
               if model.jnt_limited[j] and int(model.jnt_type[j]) != mujoco.mjtJoint.mjJNT_FREE]
    if any(int(model.jnt_type[j]) == mujoco.mjtJoint.mjJNT_BALL for j in limited):
        return mink.ConfigurationLimit(model)

    class _HingeSlideLimit(mink.Limit):
        """``gain * (q_min - q) <= dq <= gain * (q_max - q)`` on the limited joints: the
        values of mink.ConfigurationLimit (whose ``mj_differentiatePos`` of a hinge or a
        slide is ``q2 - q1``), the same rows in the same order."""

        def __init__(self) -> None:
            ref = mink.ConfigurationLimit(model)
            self.gain = ref.gain
            self.indices = ref.indices  # dof addresses, increasing
            dof_to_q = np.full(model.nv, -1)
            for j in range(model.njnt):
                if int(model.jnt_type[j]) in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
                    dof_to_q[model.jnt_dofadr[j]] = model.jnt_qposadr[j]
            self.qadr = dof_to_q[self.indices]
            self.lower, self.upper = ref.lower[self.qadr].copy(), ref.upper[self.qadr].copy()
            self.G = np.vstack([ref.projection_matrix, -ref.projection_matrix])
            self.G.setflags(write=False)

        def compute_qp_inequalities(self, configuration, dt):
            del dt
            q = configuration.q[self.qadr]
            return mink.Constraint(G=self.G, h=np.concatenate([self.gain * (self.upper - q),
                                                              self.gain * (q - self.lower)]))

    return _HingeSlideLimit() if limited else mink.ConfigurationLimit(model)


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(translation [m], rotation angle [rad]) between two poses (4, 4)."""
    dR = T_a[:3, :3].T @ T_b[:3, :3]
    ang = math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1.0) / 2.0)))
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), ang


@dataclass(frozen=True)
class IKResult:
    """q (7,): the arm's joints; ok: converged within (POS_TOL, ROT_TOL) inside the
    joint limits; pos_err [m], rot_err [rad]: what is left; iterations used."""

    q: np.ndarray
    ok: bool
    pos_err: float
    rot_err: float
    iterations: int


class Reach(enum.IntEnum):
    """What the reachability check found for a grasp (first failure wins)."""

    REACHABLE = 0
    NO_IK = 1            # a pose of the grasp (wrist, pre-grasp, approach line) has no IK solution
    SELF_COLLISION = 2   # the arm meets itself at a pose
    TABLE = 3            # the arm or gripper is in the table at a pose
    SCENE = 4            # the arm meets the object or the scene at a pose (the gripper: along the approach)
    START = 5            # the gripper penetrates the object at the grasp pose (infeasible for any robot)

    @property
    def label(self) -> str:
        return self.name.lower()


class ArmKinematics:
    """IK and collision queries of the arm in a compiled ``model`` (module doc)."""

    def __init__(self, model: mujoco.MjModel, arm: ArmSpec, *, ik_model: mujoco.MjModel | None = None,
                 wrist_site: str = "wrist", table_geom: str = "table", iterations: int = 60,
                 stall: int = 8, posture_cost: float = 1e-3, damping: float = 1e-4, solver: str = "daqp") -> None:
        import mink

        from graspsim.robots.arm import ARM_PREFIX

        self.model, self.arm = model, arm
        self.joint_ids = np.array([model.joint(ARM_PREFIX + j).id for j in arm.joints])
        self.qadr = model.jnt_qposadr[self.joint_ids].copy()
        self.dadr = model.jnt_dofadr[self.joint_ids].copy()
        self.lower, self.upper = model.jnt_range[self.joint_ids].T.copy()
        self.site = model.site(wrist_site).id
        self.iterations, self.damping, self.solver = int(iterations), float(damping), solver
        root = model.body(ARM_PREFIX + arm.links[0]).id
        body_root = model.body_rootid[model.geom_bodyid]
        collide = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        self.robot_geom = collide & (body_root == root)
        wrist = model.body("wrist").id
        sub = np.zeros(model.nbody, bool)
        for b in range(model.nbody):  # the wrist's subtree: the gripper
            c = b
            while c > 0 and c != wrist:
                c = model.body_parentid[c]
            sub[b] = c == wrist
        self.gripper_geom = self.robot_geom & sub[model.geom_bodyid]
        tid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, table_geom)
        self.table_geom = np.zeros(model.ngeom, bool)
        if tid >= 0:
            self.table_geom[tid] = True
        self.scene_geom = collide & ~self.robot_geom & ~self.table_geom
        self.data = mujoco.MjData(model)
        self.q0 = model.qpos0.copy()
        # IK runs on ``ik_model`` when given: the same arm and gripper at the same base
        # without the scene (fewer degrees of freedom for mink to carry)
        im = model if ik_model is None else ik_model
        self._ik_qadr = im.jnt_qposadr[[im.joint(ARM_PREFIX + j).id for j in arm.joints]].copy()
        self._ik_q0 = im.qpos0.copy()
        self.stall = int(stall)
        self._cfg = mink.Configuration(im)
        self._task = mink.FrameTask(wrist_site, "site", position_cost=1.0, orientation_cost=1.0)
        self._posture = mink.PostureTask(im, cost=posture_cost)
        self._limits = [_joint_limit(im)]
        self._mink = mink
        # the joints mink may move: the arm's; everything else (the jaws, the scene) is frozen
        ik_dadr = im.jnt_dofadr[[im.joint(ARM_PREFIX + j).id for j in arm.joints]]
        others = np.setdiff1d(np.arange(im.nv), ik_dadr)
        self._frozen = mink.DofFreezingTask(im, dof_indices=others.tolist()) if len(others) else None

    def set_scene(self, qpos: np.ndarray) -> None:
        """Pose the rest of the model (the scene's objects) as in ``qpos`` (a full qpos of
        ``model``, e.g. a table scene's state now) for every later collision query; the
        arm's own joints in it are ignored."""
        q = np.asarray(qpos, float)
        if q.shape != self.q0.shape:
            raise InvalidParameterError(f"qpos must have {self.q0.shape[0]} entries, got {q.shape}")
        self.q0 = q.copy()

    # -- kinematics ---------------------------------------------------------------
    def full_q(self, q: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
        out = (self.q0 if base is None else base).copy()
        out[self.qadr] = q
        return out

    def fk(self, q: np.ndarray) -> np.ndarray:
        """T_world_wrist (4, 4) at arm joints ``q`` (7,)."""
        d = self.data
        d.qpos[:] = self.full_q(np.asarray(q, float))
        mujoco.mj_kinematics(self.model, d)
        T = np.eye(4)
        T[:3, :3] = d.site_xmat[self.site].reshape(3, 3)
        T[:3, 3] = d.site_xpos[self.site]
        return T

    def within_limits(self, q: np.ndarray, tol: float = 1e-6) -> bool:
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    def ik(self, T_world_wrist: np.ndarray, seed: np.ndarray | None = None) -> IKResult:
        """Joints putting the wrist frame at ``T_world_wrist`` (4, 4), solved from
        ``seed`` (7,; default the arm's home): mink's step iterated until the pose is
        met (POS_TOL, ROT_TOL), ``iterations`` ran out, or ``stall`` steps in a row did not
        cut the error by 1 %."""
        mink = self._mink
        T = np.asarray(T_world_wrist, float)
        q = np.clip(np.asarray(self.arm.home if seed is None else seed, float), self.lower, self.upper)
        cfg = self._cfg
        q_full = self._ik_q0.copy()
        q_full[self._ik_qadr] = q
        cfg.update(q_full)
        self._task.set_target(mink.SE3.from_matrix(T))
        self._posture.set_target(cfg.q)
        tasks = [self._task, self._posture]
        constraints = [self._frozen] if self._frozen is not None else None
        pe = re = np.inf
        it = 0
        best, since = np.inf, 0
        while it < self.iterations:
            it += 1
            # mink.solve_ik less its limit check (a warning at most: the limits are a
            # constraint of the QP, and every iterate is checked against them below)
            problem = mink.build_ik(cfg, tasks, 1.0, self.damping, self._limits, constraints)
            cfg.integrate_inplace(self._solve_qp(problem), 1.0)
            err = self._task.compute_error(cfg)
            ep, er = err[:3], err[3:]  # np.linalg.norm of a vector is sqrt(x.dot(x)): the same values
            pe, re = math.sqrt(ep.dot(ep)), math.sqrt(er.dot(er))
            if pe <= POS_TOL and re <= ROT_TOL:
                break
            e = pe + 0.1 * re  # [m]: 0.1 m per radian
            if e < 0.99 * best:
                best, since = e, 0
            else:
                since += 1
                if since >= self.stall:  # stuck (a joint limit, a singularity, out of reach)
                    break
        q = cfg.q[self._ik_qadr].copy()
        ok = pe <= POS_TOL and re <= ROT_TOL and self.within_limits(q)
        return IKResult(q=q, ok=bool(ok), pos_err=pe, rot_err=re, iterations=it)

    def _solve_qp(self, problem) -> np.ndarray:
        """The QP's solution: DAQP called as qpsolvers calls it (the same arrays, so the
        same result) without qpsolvers' per-call dispatch; any other solver through
        qpsolvers."""
        mink = self._mink
        if self.solver != "daqp" or problem.lb is not None or problem.ub is not None:
            sol = qpsolvers.solve_problem(problem, solver=self.solver)
            if not sol.found:
                raise mink.NoSolutionFound(self.solver)
            return sol.x
        import daqp

        G, h, A, b = problem.G, problem.h, problem.A, problem.b
        parts = [(M, v) for M, v in ((G, h), (A, b)) if M is not None]
        if not parts:
            return qpsolvers.solve_problem(problem, solver="daqp").x
        Atot = parts[0][0] if len(parts) == 1 else np.vstack([G, A])
        upper = parts[0][1] if len(parts) == 1 else np.concatenate([h, b])
        sense = np.zeros(len(upper), dtype=ctypes.c_int)
        if A is not None:
            sense[len(upper) - len(b):] = 5  # DAQP's equality rows
        x, _, exitflag, _ = daqp.solve(problem.P, problem.q, Atot, upper, np.full(len(upper), -1e30), sense)
        if not exitflag > 0:
            raise mink.NoSolutionFound(self.solver)
        return x

    def spread_seeds(self, n: int = 6) -> np.ndarray:
        """(n, 7) fixed configurations spread over the joint ranges (a seeded draw, the
        same every call): more starts for an IK that the first seeds leave in a local
        minimum."""
        if getattr(self, "_spread", None) is None or len(self._spread) != n:
            rng = np.random.default_rng(20_260_839)
            self._spread = self.lower + (self.upper - self.lower) * rng.uniform(0.15, 0.85, (n, len(self.lower)))
        return self._spread

    # -- collisions ---------------------------------------------------------------
    def contacts(self, q: np.ndarray, jaws: np.ndarray | None = None, *, tol: float = 0.0,
                 base: np.ndarray | None = None) -> dict[str, float]:
        """Deepest penetration [m] (0: none deeper than ``tol``) of the robot posed at
        ``q`` (jaw joints set from ``jaws``: (addresses, values); the rest of the state
        from ``base``, a full qpos, default the model's) with itself ("self"), the table
        by the arm and by the gripper ("arm_table", "gripper_table"), and the rest of the
        scene by the arm and by the gripper ("arm_scene", "gripper_scene")."""
        m, d = self.model, self.data
        d.qpos[:] = self.full_q(np.asarray(q, float), base)
        if jaws is not None:
            d.qpos[jaws[0]] = jaws[1]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        out = dict.fromkeys(("self", "arm_table", "gripper_table", "arm_scene", "gripper_scene"), 0.0)
        if not d.ncon:
            return out
        depth = -d.contact.dist[: d.ncon]
        deep = depth > tol
        if not deep.any():  # the usual case: every contact within the tolerance
            return out
        g = d.contact.geom[: d.ncon][deep]
        depth = depth[deep]
        r0, r1 = self.robot_geom[g[:, 0]], self.robot_geom[g[:, 1]]
        t0, t1 = self.table_geom[g[:, 0]], self.table_geom[g[:, 1]]
        s0, s1 = self.scene_geom[g[:, 0]], self.scene_geom[g[:, 1]]
        gr = self.gripper_geom[g[:, 0]] | self.gripper_geom[g[:, 1]]
        table, scene = (r0 & t1) | (r1 & t0), (r0 & s1) | (r1 & s0)
        kinds = {"self": r0 & r1, "arm_table": table & ~gr, "gripper_table": table & gr,
                 "arm_scene": scene & ~gr, "gripper_scene": scene & gr}
        for k, sel in kinds.items():
            if sel.any():
                out[k] = float(depth[sel].max())
        return out


@dataclass(frozen=True, eq=False)
class ReachCheck:
    """The check of one grasp: ``reach`` (:class:`Reach`), the joints at the pre-grasp
    (``q_pre``) and at the approach's waypoints ending at the grasp (``q_approach``,
    (K, 7)), where it failed (``stage``: "grasp", "pre_grasp", "approach") and the
    wrist-pose error of the grasp's IK."""

    reach: Reach
    stage: str
    q_pre: np.ndarray | None = None
    q_approach: np.ndarray | None = None
    pos_err: float = float("nan")
    rot_err: float = float("nan")
    contacts: dict | None = None  # the failing pose's penetrations (ArmKinematics.contacts)
    q: np.ndarray | None = None  # the failing pose's joints (the grasp's solution of a START)

    @property
    def ok(self) -> bool:
        return self.reach == Reach.REACHABLE


def _verdict(c: dict[str, float], *, at_grasp: bool) -> Reach | None:
    """The first failure of a pose's contacts; at the grasp pose the gripper's own
    collisions (object or table) are the start collision of the floating harness."""
    if at_grasp and max(c["gripper_scene"], c["gripper_table"]) > 0:
        return Reach.START
    if c["self"] > 0:
        return Reach.SELF_COLLISION
    if max(c["arm_table"], c["gripper_table"]) > 0:
        return Reach.TABLE
    if max(c["arm_scene"], c["gripper_scene"]) > 0:
        return Reach.SCENE
    return None


def check_reach(kin: ArmKinematics, T_world_wrist: np.ndarray, *, approach: float = 0.10, step: float = 0.01,
                jaws: np.ndarray | None = None, seeds=(), tol: float = 0.001,
                max_joint_step: float = 0.5) -> ReachCheck:
    """Can the arm reach the grasp ``T_world_wrist`` (4, 4) from its pre-grasp pose
    ``approach`` [m] back along the wrist's z axis, moving straight in, without
    collisions (penetration > ``tol`` [m]; jaws posed by ``jaws``: (addresses, values))?

    Order (first failure wins, each IK seeded by the previous solution): the grasp pose
    (IK from each of ``seeds``, the home and the arm's spread seeds until one converges
    to a collision-free configuration; the gripper in the object or the table there is
    :attr:`Reach.START`, as the floating harness's start collision), the
    pre-grasp pose, then waypoints every ``step`` [m] of the approach line from the
    pre-grasp in (the gripper touching the scene on the way is :attr:`Reach.SCENE`), the
    last being the grasp again on the approach's branch; a joint moving more than
    ``max_joint_step`` [rad] between waypoints (a jump between IK branches, not a
    straight line) is :attr:`Reach.NO_IK` too."""
    if not (approach >= 0 and step > 0):
        raise InvalidParameterError(f"approach must be >= 0 m and step > 0 m, got {approach!r}, {step!r}")
    T = np.asarray(T_world_wrist, float)
    first = None
    for seed in [*seeds, None, *kin.spread_seeds()]:
        res = kin.ik(T, seed)
        if not res.ok:
            continue
        c = kin.contacts(res.q, jaws, tol=tol)
        v = _verdict(c, at_grasp=True)
        if v is None:
            break
        if v == Reach.START:  # the gripper's own collision: no other arm pose changes it
            return ReachCheck(v, "grasp", pos_err=res.pos_err, rot_err=res.rot_err, contacts=c, q=res.q)
        first = first or ReachCheck(v, "grasp", pos_err=res.pos_err, rot_err=res.rot_err, contacts=c)
    else:
        return first or ReachCheck(Reach.NO_IK, "grasp", pos_err=res.pos_err, rot_err=res.rot_err)
    k = max(1, int(math.ceil(approach / step)))
    back = T[:3, 2]
    poses = []
    for i in range(k + 1):  # pre-grasp first, grasp last
        P = T.copy()
        P[:3, 3] = T[:3, 3] - back * approach * (1.0 - i / k)
        poses.append(P)
    pre = kin.ik(poses[0], res.q)
    if not pre.ok:
        return ReachCheck(Reach.NO_IK, "pre_grasp", pos_err=res.pos_err, rot_err=res.rot_err)
    qs = [pre.q]
    for P in poses[1:]:  # the last is the grasp again, reached from the approach's side (one branch)
        r = kin.ik(P, qs[-1])
        if not r.ok or np.abs(r.q - qs[-1]).max() > max_joint_step:  # no solution, or a jump between branches
            return ReachCheck(Reach.NO_IK, "approach", pos_err=res.pos_err, rot_err=res.rot_err)
        qs.append(r.q)
    for i, q in enumerate(qs):
        c = kin.contacts(q, jaws, tol=tol)
        v = _verdict(c, at_grasp=i == len(qs) - 1)
        if v is not None:
            return ReachCheck(v, "pre_grasp" if i == 0 else "approach", pos_err=res.pos_err, rot_err=res.rot_err,
                              contacts=c)
    return ReachCheck(Reach.REACHABLE, "", q_pre=qs[0], q_approach=np.array(qs), pos_err=res.pos_err,
                      rot_err=res.rot_err)
