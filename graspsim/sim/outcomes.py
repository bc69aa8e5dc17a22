"""Trial outcomes (an enum, not a bool) and the motion metrics computed from records.

A trial's record holds, per step, the wrist pose, the object pose and the two pad-object
contact sensors. Metrics express the object's motion in the gripper (wrist) frame, so a
grasp that carries the object rigidly shows zero motion however far it moves in the
world. Every function here is vectorised over trials (leading axis N) and steps (S).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from graspsim.transforms import angle_between, quat_to_matrix

__all__ = ["TrialOutcome", "collision_kind", "Record", "relative_motion", "unstable", "pads_touching"]


class TrialOutcome(enum.IntEnum):
    """How a trial ended. START_COLLISION is an infeasible pose (reported apart), not a
    failed grasp; SIM_UNSTABLE is a failed simulation, never a success.

    A robot arm's trials (:mod:`graspsim.robots`) name three more failures, each counted
    in the denominator: UNREACHABLE (the reachability check found no collision-free IK
    solution for the grasp, its pre-grasp, approach, lift or retreat: never executed);
    APPROACH_COLLISION (the planned motion to the grasp meets the table, the object or
    the arm itself: never executed; or, executed, the grasp failed after the approach
    had pushed the object); CONTROLLER_ERROR (the grasp failed and the arm's servos had
    left the wrist off its target when the jaws closed)."""

    SUCCESS = 0
    START_COLLISION = 1
    NO_CONTACT = 2
    SLIPPED = 3
    DROPPED = 4
    PLACE_FAILED = 5
    SIM_UNSTABLE = 6
    UNREACHABLE = 7
    APPROACH_COLLISION = 8
    CONTROLLER_ERROR = 9

    @property
    def label(self) -> str:
        return self.name.lower()


def collision_kind(collided: tuple, target: int | None) -> str:
    """What a start collision hit (``collided``: object ids and "table"): "target" (the
    target, maybe the table too), "both" (the target and another object), "neighbour"
    (other objects only, maybe the table), "table" (the table only), "object" (objects,
    no target named)."""
    objects = {c for c in collided if c != "table"}
    if not objects:
        return "table"
    if target is None:
        return "object"
    if target in objects:
        return "both" if len(objects) > 1 else "target"
    return "neighbour"


@dataclass(frozen=True)
class Record:
    """Recorded trajectories of n trials over S steps (state after each step).

    time: (n, S) [s]; wrist_pos (n, S, 3) [m], wrist_quat (n, S, 4) w,x,y,z;
    obj_pos (n, S, 3) [m] (object frame origin), obj_quat (n, S, 4); obj_vel (n, S, 6)
    (linear world [m/s], angular local [rad/s]); jaws (n, S, 2) half openings [m];
    pads (n, S, 2, 4): per pad (neg, pos) contact count and net force xyz [N], world.
    """

    time: np.ndarray
    wrist_pos: np.ndarray
    wrist_quat: np.ndarray
    obj_pos: np.ndarray
    obj_quat: np.ndarray
    obj_vel: np.ndarray
    jaws: np.ndarray
    pads: np.ndarray

    def __len__(self) -> int:
        return self.time.shape[0]

    def pad_force(self, step: int) -> np.ndarray:
        """(n, 2) magnitude of each pad's net contact force on the object [N]."""
        return np.linalg.norm(self.pads[:, step, :, 1:], axis=-1)


def object_in_wrist(rec: Record, steps) -> tuple[np.ndarray, np.ndarray]:
    """Object position (n, k, 3) [m] and rotation (n, k, 3, 3) in the wrist frame."""
    Rw = quat_to_matrix(rec.wrist_quat[:, steps])
    Ro = quat_to_matrix(rec.obj_quat[:, steps])
    d = rec.obj_pos[:, steps] - rec.wrist_pos[:, steps]
    p = np.einsum("...ji,...j->...i", Rw, d)
    R = np.einsum("...ji,...jk->...ik", Rw, Ro)
    return p, R


def relative_motion(rec: Record, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Largest object motion in the wrist frame over steps [start, stop] relative to
    ``start``: translation (n,) [m] and rotation angle (n,) [rad]."""
    steps = np.arange(start, stop + 1)
    p, R = object_in_wrist(rec, steps)
    lin = np.linalg.norm(p - p[:, :1], axis=-1).max(axis=1)
    rel = np.einsum("nji,nsjk->nsik", R[:, 0], R)
    cos = np.clip((np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    return lin, np.arccos(cos).max(axis=1)


def tilt(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Angle (n,) [rad] between the object's z axes at two poses (n, 4) (its tilt)."""
    return angle_between(quat_to_matrix(q0)[..., :, 2], quat_to_matrix(q1)[..., :, 2])


def pads_touching(rec: Record, step: int, min_force: float = 1e-3) -> np.ndarray:
    """(n,) number of pads (0-2) touching the object at ``step``."""
    touching = (rec.pads[:, step, :, 0] > 0) & (rec.pad_force(step) > min_force)
    return touching.sum(axis=1)


def unstable(rec: Record, *, max_speed: float, max_spin: float, max_distance: float,
             start_pos: np.ndarray) -> np.ndarray:
    """(n,) True where the simulation diverged: non-finite values, MuJoCo's automatic
    reset after a bad acceleration (time jumps back), or the object flying off
    (speed, spin or distance from ``start_pos`` (n, 3) beyond the bounds)."""
    finite = np.ones(len(rec), bool)
    for a in (rec.time, rec.obj_pos, rec.obj_vel, rec.wrist_pos, rec.jaws, rec.pads):
        finite &= np.all(np.isfinite(a.reshape(len(rec), -1)), axis=1)
    with np.errstate(invalid="ignore"):
        reset = np.any(np.diff(rec.time, axis=1) <= 0.0, axis=1)
        fast = np.linalg.norm(rec.obj_vel[..., :3], axis=-1).max(axis=1) > max_speed
        spin = np.linalg.norm(rec.obj_vel[..., 3:], axis=-1).max(axis=1) > max_spin
        far = np.linalg.norm(rec.obj_pos - start_pos[:, None], axis=-1).max(axis=1) > max_distance
    return ~finite | reset | fast | spin | far
