"""Simulation conditions of calibration trials, and the named presets.

A :class:`SimCondition` is the physics calibration trials run under: pad friction, grip force,
object mass and execution noise. Two presets are named (:data:`CONDITIONS`):

* ``default``: the planner's own assumptions -- pad mu 0.5, the gripper's 250 N per jaw,
  the map's mass (density 500 kg/m^3: 0.02-0.25 kg for the paper primitives), no noise.
  Success here says little about the grade: 2 x 0.5 x 250 N of friction holds any of
  these objects a hundred times over, so almost every feasible grasp that touches the
  object with both pads lifts it, whatever its grade.
* ``friction_limited``: 8 N per jaw on a 0.5 kg object (success against mass at this
  force: ``experiments/golden_regression.py --scan-masses``). Two pads
  at mu 0.5 give 8 N of friction against 4.9 N of weight, and the min-jerk lift adds up
  to 0.44 g, so only a grasp close to antipodal and close to the centre of mass (small
  torque about the grasp axis) holds: the two terms of the paper's grade. This is the
  condition the success-rate regression and the calibration run where grades must
  matter. Its reach is bounded by the simulator: MuJoCo's soft contacts on edges and
  corners decide the marginal grasps, and an independent engine (PyBullet, same
  geometry, masses, forces and friction; a one-off cross-check, not in this repository) agreed on nearly all
  high-grade grasps but on far fewer low-grade ones (MuJoCo the stricter on edge and
  corner contacts) -- the low-grade rates are MuJoCo's, not ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from graspsim.checks import POSITIVE, check_fields, or_none
from graspsim.contacts import DEFAULT_CONTACTS, check_contacts
from graspsim.errors import InvalidParameterError

if TYPE_CHECKING:  # graspsim.sim loads mujoco
    from graspsim.sim.noise import ExecutionNoise

__all__ = ["SimCondition", "FRICTION_LIMITED", "CONDITIONS", "condition", "conditioned_object"]


@dataclass(frozen=True)
class SimCondition:
    """Physics of calibration trials: pad friction mu, grip force per jaw [N] (None: the
    gripper spec's), object mass [kg] (None: the map's), then scaled by ``mass_scale``,
    execution noise (an :class:`~graspsim.sim.ExecutionNoise`; None = exact execution),
    contacts: the simulation's contact model (:func:`graspsim.sim.contact_model`)."""

    name: str = "default"
    friction: float = 0.5
    grip_force: float | None = None
    mass_scale: float = 1.0
    noise: ExecutionNoise | None = None
    mass: float | None = None
    contacts: str = DEFAULT_CONTACTS

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE, "friction", "mass_scale", owner="SimCondition")
        check_contacts(self.contacts)  # an unknown name: one line naming the valid ones
        if self.noise is not None:
            from graspsim.sim.noise import ExecutionNoise

            if not isinstance(self.noise, ExecutionNoise):
                raise InvalidParameterError(f"SimCondition.noise must be an ExecutionNoise or None, "
                                            f"got {self.noise!r}")
        check_fields(self, or_none(POSITIVE.saying("> 0 N")), "grip_force", owner="SimCondition")
        check_fields(self, or_none(POSITIVE.saying("> 0 kg")), "mass", owner="SimCondition")

    @property
    def noisy(self) -> bool:
        n = self.noise
        return n is not None and (n.position_sigma > 0 or n.rotation_sigma > 0)

    def to_dict(self) -> dict:
        """A flat record (the noise as ``noise_position`` [m], ``noise_rotation`` [rad])."""
        n = self.noise
        return {"name": self.name, "friction": self.friction, "grip_force": self.grip_force,
                "mass_scale": self.mass_scale, "noise_position": n.position_sigma if n else 0.0,
                "noise_rotation": n.rotation_sigma if n else 0.0, "mass": self.mass,
                **({} if self.contacts == DEFAULT_CONTACTS else {"contacts": self.contacts})}


FRICTION_LIMITED = SimCondition("friction_limited", grip_force=8.0, mass=0.5)

CONDITIONS: dict[str, SimCondition] = {"default": SimCondition(), "friction_limited": FRICTION_LIMITED}


def condition(name: str, **changes) -> SimCondition:
    """The preset ``name`` (see :data:`CONDITIONS`), with fields replaced by ``changes``
    (e.g. ``condition("friction_limited", mass=0.25)``)."""
    if name not in CONDITIONS:
        raise InvalidParameterError(f"unknown simulation condition {name!r}; valid: {sorted(CONDITIONS)}")
    return replace(CONDITIONS[name], **changes) if changes else CONDITIONS[name]


def conditioned_object(obj, cond: SimCondition):
    """The :class:`graspsim.sim.SimObject` ``obj`` with the condition's mass: ``mass``
    (if given) times ``mass_scale``; inertia scales with it (same shape, same density
    distribution)."""
    s = (cond.mass / obj.mass if cond.mass is not None else 1.0) * cond.mass_scale
    if s == 1.0:
        return obj
    return replace(obj, mass=obj.mass * s, inertia=obj.inertia * s)
