"""Execution noise: a real arm never reaches the map pose exactly.

Each trial's wrist pose is perturbed in its own (wrist) frame by a translation drawn
from N(0, position_sigma^2 I) and a rotation whose rotation vector is drawn from
N(0, rotation_sigma^2 I). Draws come from an explicit ``np.random.Generator``, one per
trial in trial order, so a seed fixes every trial's pose whatever the thread count.
The rotation turns about the TCP (mid-pad), where a robot's accuracy is specified: about
the flange, 2 deg would swing the fingertips 6 mm. The draw is
:func:`graspsim.maps.robust.wrist_perturbations`, the planner's robustness model.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from graspsim.checks import NON_NEGATIVE, check_fields
from graspsim.maps.robust import POSITION_SIGMA, ROTATION_SIGMA, wrist_perturbations

__all__ = ["ExecutionNoise"]


@dataclass(frozen=True)
class ExecutionNoise:
    """Wrist pose error per trial: position_sigma [m], rotation_sigma [rad]
    (defaults 3 mm and 2 deg, ``graspsim.maps.robust.POSITION_SIGMA`` / ``ROTATION_SIGMA``:
    a typical industrial arm with hand-eye calibration)."""

    position_sigma: float = POSITION_SIGMA
    rotation_sigma: float = ROTATION_SIGMA

    def __post_init__(self) -> None:
        check_fields(self, NON_NEGATIVE)

    def sample(self, n: int, rng: np.random.Generator,
               pivot: np.ndarray = np.zeros(3)) -> np.ndarray:
        """(n, 4, 4) perturbations T_wrist_noisy, to right-multiply onto wrist poses.

        pivot: (3,) wrist-frame point the rotation turns about and the translation is
        measured at (the TCP, where a robot's accuracy is specified) [m].
        """
        return wrist_perturbations(n, rng, self.position_sigma, self.rotation_sigma, pivot)

    def to_dict(self) -> dict:
        return asdict(self)
