"""Rewards of the grasp environments from a trial's outcome and metrics.

* binary: 1 for ``SUCCESS``, 0 otherwise (an invalid action or an infeasible start
  pose included).
* shaped: 1 for ``SUCCESS``; a failed trial that held the object for a while earns
  partial credit, at most 0.5, so success always dominates:
  ``lift_place``: 0.5 x (fraction of the lift height reached at the end of the hold,
  clipped to [0, 1]) x exp(-(object slip in the hand during lift and hold) / 1 cm);
  ``tug``: 0.5 x exp(-(slip during the tugs) / 1 cm). NO_CONTACT, START_COLLISION,
  SIM_UNSTABLE and invalid actions earn 0; so do metrics that are missing (NaN).
"""

from __future__ import annotations

import math

from graspsim.envs.env_config import RewardMode
from graspsim.sim.outcomes import TrialOutcome

__all__ = ["trial_reward", "SLIP_SCALE", "PARTIAL_CREDIT"]

SLIP_SCALE = 0.01  # [m]
PARTIAL_CREDIT = 0.5
_HELD_FOR_A_WHILE = (TrialOutcome.SLIPPED, TrialOutcome.DROPPED, TrialOutcome.PLACE_FAILED)


def _finite(x) -> float:
    x = float(x) if x is not None else math.nan
    return x if math.isfinite(x) else math.nan


def trial_reward(mode: RewardMode, outcome: int | None, metrics: dict, protocol: dict) -> float:
    """Reward of one trial. outcome: a :class:`TrialOutcome` code, None for an invalid
    action; metrics: name -> value (None or NaN when missing); protocol: its to_dict()."""
    if outcome is None:
        return 0.0
    outcome = TrialOutcome(int(outcome))
    if outcome is TrialOutcome.SUCCESS:
        return 1.0
    if RewardMode(mode) is RewardMode.BINARY or outcome not in _HELD_FOR_A_WHILE:
        return 0.0
    if protocol.get("name") == "tug":
        slip = _finite(metrics.get("tug_lin"))
        lift = 1.0
    else:
        slip = _finite(metrics.get("lift_lin")) + _finite(metrics.get("hold_lin"))
        lift = _finite(metrics.get("lift_height")) / float(protocol.get("lift_height", 0.12))
    if math.isnan(slip) or math.isnan(lift):
        return 0.0
    return float(PARTIAL_CREDIT * min(1.0, max(0.0, lift)) * math.exp(-max(0.0, slip) / SLIP_SCALE))
