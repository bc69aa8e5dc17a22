"""Trial protocols: open-loop control schedules and how their records are judged.

A protocol turns N wrist poses into controls for ``mujoco.rollout`` (per step: the jaw
command, the mocap position and quaternion, and for ``tug`` the applied object wrench)
and turns the recorded states back into a :class:`TrialOutcome` and metrics per trial.
Every parameter is a field of the protocol's frozen dataclass and goes into the results.

* :class:`LiftPlace` (default; the paper's section 3.4 test): object resting on the
  table, gripper at the pose with open jaws; settle, close, lift (minimum-jerk) by
  ``lift_height``, hold, lower back, open, retract along the approach, rest. Success:
  the object rose with the gripper, both pads hold it at the end of the hold, and it
  stands on the table again after release.
* :class:`Tug` (table-free and gravity-free, in the style of ACRONYM/GraspDataGen): close,
  then pull the object with ``force_g`` x its weight along each of ``directions``
  (wrist frame) in turn. Success: it never moves more than ``slip_tolerance`` in the hand.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import ClassVar

import mujoco
import numpy as np

from graspsim.checks import NON_NEGATIVE, check_fields
from graspsim.errors import InvalidParameterError
from graspsim.sim.outcomes import Record, TrialOutcome, pads_touching, relative_motion, tilt, unstable
from graspsim.sim.trial_scene import Scene
from graspsim.transforms import matrix_to_quat

__all__ = ["Protocol", "LiftPlace", "Tug", "PROTOCOLS", "make_protocol", "min_jerk"]

_CTRL = mujoco.mjtState.mjSTATE_CTRL
_MPOS = mujoco.mjtState.mjSTATE_MOCAP_POS
_MQUAT = mujoco.mjtState.mjSTATE_MOCAP_QUAT
_XFRC = mujoco.mjtState.mjSTATE_XFRC_APPLIED
G = 9.81


def min_jerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 0 -> 1 for u in [0, 1] (zero speed and acceleration at ends)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _check_positive(obj) -> None:
    """Every float setting of a protocol (times, distances, speeds) is a finite number >= 0."""
    check_fields(obj, NON_NEGATIVE, *(k for k, v in asdict(obj).items() if isinstance(v, float)),
                 owner=type(obj).__name__)


def phase_steps(phases, dt: float) -> dict[str, tuple[int, int]]:
    """Phase name -> (first step, last step) of ``phases`` ((name, duration [s]) in order)
    in a record of step ``dt`` [s]; every phase at least one step."""
    out, k = {}, 0
    for name, dur in phases:
        n = max(1, int(round(dur / dt)))
        out[name] = (k, k + n - 1)
        k += n
    return out


@dataclass(frozen=True)
class Protocol:
    """Base of the protocols: phases (name, duration [s]), the shared checks (every float
    setting a finite number >= 0) and what every protocol judges SIM_UNSTABLE:
    max_speed [m/s] / max_spin [rad/s] / max_distance [m] of the object, beyond which
    (far beyond anything a 300 N squeeze can do: an object squirting out of the jaws
    flies at a few m/s) the simulation diverged."""

    name: ClassVar[str] = ""
    metric_names: ClassVar[tuple[str, ...]] = ()
    table: ClassVar[bool] = True
    gravity: ClassVar[bool] = True
    control_spec: ClassVar[int] = int(_CTRL | _MPOS | _MQUAT)
    max_speed: float = 50.0
    max_spin: float = 2000.0
    max_distance: float = 20.0

    def __post_init__(self) -> None:
        _check_positive(self)

    def phases(self) -> list[tuple[str, float]]:
        raise NotImplementedError

    def steps(self, dt: float) -> dict[str, tuple[int, int]]:
        """Phase name -> (first step, last step) in a record of step ``dt``."""
        return phase_steps(self.phases(), dt)

    def nstep(self, dt: float) -> int:
        return max(b for _, b in self.steps(dt).values()) + 1

    def to_dict(self) -> dict:
        d = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}
        return {"name": self.name, **d}

    # -- shared pieces ------------------------------------------------------------
    def _unstable(self, rec: Record, obj0: np.ndarray) -> np.ndarray:
        """(N,) bool: the trials whose object broke a limit (SIM_UNSTABLE)."""
        return unstable(rec, max_speed=self.max_speed, max_spin=self.max_spin, max_distance=self.max_distance,
                        start_pos=obj0[:, :3])

    def _jaw_and_mocap(self, scene: Scene, T_world_wrist: np.ndarray, n_steps: int):
        n = len(T_world_wrist)
        ctrl = np.zeros((n, n_steps))
        pos = np.repeat(T_world_wrist[:, None, :3, 3], n_steps, axis=1)
        quat = np.repeat(matrix_to_quat(T_world_wrist[:, :3, :3])[:, None], n_steps, axis=1)
        return ctrl, pos, quat


@dataclass(frozen=True)
class LiftPlace(Protocol):
    """The paper's lift-and-place test. Durations [s], distances [m], angles [rad].

    Outcomes, first match wins: SIM_UNSTABLE (diverged); NO_CONTACT (fewer than two
    pads touch the object after closing); DROPPED (fewer than two pads touch it at the
    end of the hold); SLIPPED (held, but it rose less than lift_height - lift_tolerance
    or moved more than hold_slip in the hand during the hold); PLACE_FAILED (after
    release it is not standing where it was: height change, tilt, still moving, or
    stuck to a pad); else SUCCESS. Motion while closing (re-orientation in the hand)
    is recorded, not judged.

    lift_tolerance: the object must rise at least lift_height - lift_tolerance;
    hold_slip: largest object translation in the hand during the hold;
    place_height / place_tilt: largest height change and tilt of the object after release;
    rest_speed: largest object speed at the end of ``rest_time`` after the retract (it
    must be at rest: a tall cylinder placed 10 deg off upright still rocks after 0.1 s,
    and one that is toppling still looks upright); max_speed / max_spin / max_distance:
    see :class:`Protocol`.
    """

    name: ClassVar[str] = "lift_place"
    metric_names: ClassVar[tuple[str, ...]] = (
        "close_lin", "close_ang", "lift_lin", "lift_ang", "hold_lin", "hold_ang", "lift_height",
        "place_error", "place_tilt", "pad_force_neg", "pad_force_pos", "grip_force_closed")
    settle_time: float = 0.02  # [s] gripper and object settle at the grasp pose, the jaws held at their opening
    close_time: float = 0.25  # [s] the valve closes the jaws on the object
    lift_height: float = 0.12  # [m] the wrist rises this far (minimum-jerk) over lift_time; at least 0.10
    lift_time: float = 0.40  # [s]
    hold_time: float = 0.30  # [s] held still at lift_height (slip is measured over it)
    lower_time: float = 0.40  # [s] back down (minimum-jerk) to place_clearance above the grasp height
    place_clearance: float = 0.002  # [m] the wrist's height above its grasp height when it releases the object
    open_time: float = 0.15  # [s] the valve opens the jaws
    retract_distance: float = 0.05  # [m] the wrist then backs off this far along its approach axis
    retract_time: float = 0.20  # [s]
    rest_time: float = 0.30  # [s] the object is left alone before it is judged (rest_speed at the end)
    lift_tolerance: float = 0.02
    hold_slip: float = 0.005
    place_height: float = 0.01
    place_tilt: float = math.radians(20.0)
    rest_speed: float = 0.05

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.lift_height < 0.10:
            raise InvalidParameterError(f"lift_height must be >= 0.10 m (the paper lifts clear of "
                                        f"the table), got {self.lift_height!r}")

    def phases(self):
        return [("settle", self.settle_time), ("close", self.close_time),
                ("lift", self.lift_time), ("hold", self.hold_time), ("lower", self.lower_time),
                ("open", self.open_time), ("retract", self.retract_time), ("rest", self.rest_time)]

    def controls(self, scene: Scene, T_world_wrist: np.ndarray, openings: np.ndarray | None = None) -> np.ndarray:
        """(N, S, ncontrol) controls: the actuators' (the jaw valve: -1 close, +1 open, 0
        hold the start ``openings`` (N,) [m]), mocap pos, quat."""
        dt = scene.model.opt.timestep
        ph, S = self.steps(dt), self.nstep(dt)
        ctrl, pos, quat = self._jaw_and_mocap(scene, T_world_wrist, S)
        ctrl[:, ph["close"][0]:ph["open"][0]] = -1.0  # valve: close
        ctrl[:, ph["open"][0]:] = 1.0  # valve: open
        t = (np.arange(S) + 1) * dt  # time at the end of each step
        up = np.zeros(S)
        for name, a, b in (("lift", 0.0, self.lift_height),
                           ("lower", self.lift_height, self.place_clearance)):
            s0, s1 = ph[name]
            u = (t[s0:s1 + 1] - s0 * dt) / ((s1 - s0 + 1) * dt)
            up[s0:s1 + 1] = a + (b - a) * min_jerk(u)
        up[ph["hold"][0]:ph["hold"][1] + 1] = self.lift_height
        up[ph["open"][0]:] = self.place_clearance
        s0, s1 = ph["retract"]
        back = np.zeros(S)
        back[s0:s1 + 1] = self.retract_distance * min_jerk((t[s0:s1 + 1] - s0 * dt) / ((s1 - s0 + 1) * dt))
        back[s1 + 1:] = self.retract_distance
        approach = T_world_wrist[:, :3, 2]
        pos = pos + up[None, :, None] * np.array([0.0, 0.0, 1.0]) - back[None, :, None] * approach[:, None]
        return np.concatenate([scene.drive.controls(ctrl, openings), pos, quat], axis=-1)

    def judge(self, scene: Scene, rec: Record, obj0: np.ndarray) -> tuple[np.ndarray, dict]:
        """Outcomes (n,) and metrics {name: (n,)} from a record; obj0 (n, 7) the
        object's initial pose (position, quaternion)."""
        ph = self.steps(scene.model.opt.timestep)
        c1, l1, h1, end = ph["close"][1], ph["lift"][1], ph["hold"][1], ph["rest"][1]
        m = {}
        m["close_lin"], m["close_ang"] = relative_motion(rec, 0, c1)
        m["lift_lin"], m["lift_ang"] = relative_motion(rec, c1, l1)
        m["hold_lin"], m["hold_ang"] = relative_motion(rec, l1, h1)
        m["lift_height"] = rec.obj_pos[:, h1, 2] - obj0[:, 2]
        m["place_error"] = np.linalg.norm(rec.obj_pos[:, end] - obj0[:, :3], axis=-1)
        m["place_tilt"] = tilt(obj0[:, 3:], rec.obj_quat[:, end])
        f_hold = rec.pad_force(h1)
        m["pad_force_neg"], m["pad_force_pos"] = f_hold[:, 0], f_hold[:, 1]
        m["grip_force_closed"] = rec.pad_force(c1).min(axis=1)

        bad = self._unstable(rec, obj0)
        no_contact = pads_touching(rec, c1) < 2
        dropped = pads_touching(rec, h1) < 2
        slipped = (m["lift_height"] < self.lift_height - self.lift_tolerance) | (m["hold_lin"] > self.hold_slip)
        speed = np.linalg.norm(rec.obj_vel[:, end, :3], axis=-1)
        placed = ((np.abs(rec.obj_pos[:, end, 2] - obj0[:, 2]) <= self.place_height)
                  & (m["place_tilt"] <= self.place_tilt) & (speed <= self.rest_speed)
                  & (pads_touching(rec, end) == 0))
        out = np.select(
            [bad, no_contact, dropped, slipped, ~placed],
            [TrialOutcome.SIM_UNSTABLE, TrialOutcome.NO_CONTACT, TrialOutcome.DROPPED,
             TrialOutcome.SLIPPED, TrialOutcome.PLACE_FAILED], TrialOutcome.SUCCESS)
        return out.astype(np.int8), m

    def held(self, outcome: np.ndarray) -> np.ndarray:
        """ACRONYM's object_in_gripper: still held after the hold."""
        return np.isin(outcome, [TrialOutcome.SUCCESS, TrialOutcome.PLACE_FAILED])


_DIRECTIONS = ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0),
               (0.0, 0.0, 1.0), (0.0, 0.0, -1.0))


@dataclass(frozen=True)
class Tug(Protocol):
    """Table-free, gravity-free disturbance test. Durations [s], forces in multiples of
    the object's weight, directions (unit vectors, wrist frame). A pull ramps up over
    ``ramp_time``, holds for ``pull_time`` and ramps down over ``ramp_time``.

    Outcomes: SIM_UNSTABLE; NO_CONTACT (fewer than two pads touch after closing);
    DROPPED (fewer than two pads touch at the end, or it moved more than drop_distance
    in the hand); SLIPPED (moved more than slip_tolerance); else SUCCESS."""

    name: ClassVar[str] = "tug"
    metric_names: ClassVar[tuple[str, ...]] = (
        "close_lin", "close_ang", "tug_lin", "tug_ang", "pad_force_neg", "pad_force_pos",
        "grip_force_closed")
    table: ClassVar[bool] = False
    gravity: ClassVar[bool] = False
    control_spec: ClassVar[int] = int(_CTRL | _XFRC | _MPOS | _MQUAT)
    settle_time: float = 0.02  # [s] gripper and object settle at the grasp pose, the jaws held at their opening
    close_time: float = 0.25  # [s] the valve closes the jaws on the object
    force_g: float = 1.0
    directions: tuple[tuple[float, float, float], ...] = _DIRECTIONS
    ramp_time: float = 0.05
    pull_time: float = 0.15
    slip_tolerance: float = 0.01
    drop_distance: float = 0.03

    def __post_init__(self) -> None:
        super().__post_init__()
        d = np.asarray(self.directions, float)
        if d.ndim != 2 or d.shape[1] != 3 or len(d) == 0 or np.any(np.linalg.norm(d, axis=1) < 1e-9):
            raise InvalidParameterError(f"directions must be non-zero 3-vectors, got {self.directions!r}")
        object.__setattr__(self, "directions",
                           tuple(tuple(float(x) for x in r) for r in d / np.linalg.norm(d, axis=1, keepdims=True)))

    def phases(self):
        out = [("settle", self.settle_time), ("close", self.close_time)]
        for i in range(len(self.directions)):
            out.append((f"pull{i}", 2 * self.ramp_time + self.pull_time))
        return out

    def controls(self, scene: Scene, T_world_wrist: np.ndarray, openings: np.ndarray | None = None) -> np.ndarray:
        """(N, S, ncontrol): actuators (the jaw valve), applied wrenches (nbody x 6),
        mocap pos, quat."""
        dt = scene.model.opt.timestep
        ph, S = self.steps(dt), self.nstep(dt)
        ctrl, pos, quat = self._jaw_and_mocap(scene, T_world_wrist, S)
        ctrl[:, ph["close"][0]:] = -1.0  # valve: close
        n, nb = len(T_world_wrist), scene.model.nbody
        xfrc = np.zeros((n, S, nb, 6))
        weight = self.force_g * scene.obj.mass * G
        t = (np.arange(S) + 1) * dt
        for i, d in enumerate(self.directions):
            s0, s1 = ph[f"pull{i}"]
            tt = t[s0:s1 + 1] - s0 * dt
            prof = np.clip(np.minimum(tt / self.ramp_time,
                                      (2 * self.ramp_time + self.pull_time - tt) / self.ramp_time), 0, 1)
            f_world = T_world_wrist[:, :3, :3] @ np.asarray(d)  # (n, 3)
            xfrc[:, s0:s1 + 1, scene.obj_body, :3] = weight * prof[None, :, None] * f_world[:, None]
        return np.concatenate([scene.drive.controls(ctrl, openings), xfrc.reshape(n, S, nb * 6), pos, quat],
                              axis=-1)

    def judge(self, scene: Scene, rec: Record, obj0: np.ndarray) -> tuple[np.ndarray, dict]:
        ph = self.steps(scene.model.opt.timestep)
        c1, end = ph["close"][1], ph[f"pull{len(self.directions) - 1}"][1]
        m = {}
        m["close_lin"], m["close_ang"] = relative_motion(rec, 0, c1)
        m["tug_lin"], m["tug_ang"] = relative_motion(rec, c1, end)
        f = rec.pad_force(c1)
        m["pad_force_neg"], m["pad_force_pos"] = f[:, 0], f[:, 1]
        m["grip_force_closed"] = f.min(axis=1)
        bad = self._unstable(rec, obj0)
        no_contact = pads_touching(rec, c1) < 2
        dropped = (pads_touching(rec, end) < 2) | (m["tug_lin"] > self.drop_distance)
        slipped = m["tug_lin"] > self.slip_tolerance
        out = np.select([bad, no_contact, dropped, slipped],
                        [TrialOutcome.SIM_UNSTABLE, TrialOutcome.NO_CONTACT, TrialOutcome.DROPPED,
                         TrialOutcome.SLIPPED], TrialOutcome.SUCCESS)
        return out.astype(np.int8), m

    def held(self, outcome: np.ndarray) -> np.ndarray:
        return outcome == TrialOutcome.SUCCESS


PROTOCOLS: dict[str, type[Protocol]] = {"lift_place": LiftPlace, "tug": Tug}


def make_protocol(name: str, **params) -> Protocol:
    """A protocol by name (``lift_place`` or ``tug``) with parameters overridden."""
    cls = PROTOCOLS.get(name)
    if cls is None:
        raise InvalidParameterError(f"unknown protocol {name!r}; valid: {sorted(PROTOCOLS)}")
    try:
        return cls(**params)
    except TypeError as err:
        raise InvalidParameterError(f"bad parameters for protocol {name!r}: {err}") from err
