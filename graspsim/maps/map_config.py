"""The resolution of the surface-to-voxel scan (:class:`MapConfig`, paper 3.1 defaults)
and what it implies before any map is generated: closing directions per first contact
(:func:`closing_direction_count`) and rolls about the closing axis (:func:`roll_count`),
which the generator and the memory preflight both read."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from graspsim.checks import POSITIVE, check_fields
from graspsim.errors import InvalidParameterError

__all__ = ["MapConfig", "closing_direction_count", "ring_sizes", "roll_count"]


@dataclass(frozen=True)
class MapConfig:
    """Resolution of the surface-to-voxel scan (paper 3.1 defaults).

    surface_step: spacing of first contacts on the surface [m] (paper: 0.5 cm).
    rotation_step: angular step of closing directions and roll [rad] (paper: 11 deg).
    closing_cone: largest angle between a closing direction and the inward normal at
        the first contact [rad]; two rotation steps (22 deg) by default, covering the
        friction cone of the default mu = 0.5 (26.6 deg). Grasps still leave the cone
        through the second contact (alpha is the larger of both angles), so maps keep
        q_fc = 0 grasps; widen the cone for calibration studies.
    depth_step: spacing of contact depths along the finger pad [m]; 1 cm gives four
        depths on the default 4 cm pad (near the tip, middle, towards the root).
    min_width: thinnest chord accepted as a grasp [m].
    collision_step: spacing of the coarse collision samples [m].
    collision_tolerance: poses closer than this to touching count as colliding [m];
        the fine collision samples are spaced to guarantee it.
    collision_refine: resolve poses near the coarse level's margin with the fine level;
        off, every pose within the coarse margin (a few mm) counts as colliding.
    density: object density for the recorded mass [kg/m^3] (ignored if mass given).
    """

    surface_step: float = 0.005
    rotation_step: float = math.radians(11.0)
    closing_cone: float = math.radians(22.0)
    depth_step: float = 0.010
    min_width: float = 0.002
    collision_step: float = 0.004
    collision_tolerance: float = 0.00025
    collision_refine: bool = True
    density: float = 500.0

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE, "surface_step", "rotation_step", "depth_step", "min_width",
                     "collision_step", "collision_tolerance", "density", owner="MapConfig")
        if not 0 <= self.closing_cone < math.pi / 2:
            raise InvalidParameterError(
                f"closing_cone must be in [0, pi/2) rad, got {self.closing_cone!r}")
        if self.rotation_step > math.pi / 2:
            raise InvalidParameterError(f"rotation_step must be <= pi/2, got {self.rotation_step!r}")

    def to_dict(self) -> dict:
        return asdict(self)


def ring_sizes(cone: float, step: float) -> list[int]:
    """Directions on each ring of :func:`closing_directions` (ring 0: the normal)."""
    rings = int(math.floor(cone / step + 1e-9))
    return [1] + [max(1, round(2 * math.pi * math.sin(k * step) / step)) for k in range(1, rings + 1)]


def closing_direction_count(cone: float, step: float) -> int:
    """Closing directions per first contact (K of :func:`closing_directions`). Beyond
    10^5 rings (a step far too fine to generate) the sum is taken as its integral, so
    a memory estimate costs no time (saturating at 2^62)."""
    rings = math.floor(cone / step + 1e-9)
    if rings <= 100_000:
        return sum(ring_sizes(cone, step))
    return 1 + int(min(2.0 * math.pi / step * ((1.0 - math.cos(min(rings * step, math.pi))) / step), 2.0**62))


def roll_count(cfg: MapConfig) -> int:
    """Rolls about the closing axis (length of :func:`roll_angles`)."""
    return max(1, round(min(2 * math.pi / cfg.rotation_step, 2.0**62)))
