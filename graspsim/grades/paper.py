"""Grasp quality of two-contact grasps: force-closure angle, stability distance, grade.

Paper section 2.1 and its ref. [9]; docs/design.md §5. For contacts p1, p2 with outward
normals n1, n2 and closing line u = (p2 - p1) / |p2 - p1|:

* force-closure angle alpha = max(angle(-n1, u), angle(-n2, -u)); the grasp is in force
  closure iff alpha <= atan(mu); q_fc = clip(1 - alpha / atan(mu), 0, 1);
* stability distance d = distance from the centre of mass to the grasp point (the
  midpoint of the contacts) -- or to the closing line, if chosen;
  q_st = clip(1 - d / d_ref, 0, 1) with d_ref the object's circumradius about its
  centre of mass unless given;
* grade q = w * q_fc + (1 - w) * q_st in [0, 1]; accepted when q > threshold (0.7).

Everything is vectorised over (N, 3) arrays and invariant to rigid motions of the
whole grasp (angles and distances only).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.transforms import angle_between

__all__ = ["QualityModel", "GraspQuality", "force_closure_angle", "stability_distance"]

STABILITY_MODES = ("grasp_point", "closing_line")


def force_closure_angle(
    p1: np.ndarray, p2: np.ndarray, n1: np.ndarray, n2: np.ndarray
) -> np.ndarray:
    """Force-closure angle alpha (N,) [rad] of contact pairs.

    p1, p2: (N, 3) contact points; n1, n2: (N, 3) outward unit surface normals.
    """
    u = np.asarray(p2, float) - np.asarray(p1, float)
    a1 = angle_between(-np.asarray(n1, float), u)
    a2 = angle_between(-np.asarray(n2, float), -u)
    return np.maximum(a1, a2)


def stability_distance(
    p1: np.ndarray, p2: np.ndarray, com: np.ndarray, mode: str = "grasp_point"
) -> np.ndarray:
    """Distance (N,) [m] from the centre of mass ``com`` (3,) to the grasp point
    (midpoint of the contacts) or, with ``mode="closing_line"``, to the closing line."""
    p1, p2, com = np.asarray(p1, float), np.asarray(p2, float), np.asarray(com, float)
    gp = 0.5 * (p1 + p2)
    if mode == "grasp_point":
        return np.linalg.norm(gp - com, axis=-1)
    if mode == "closing_line":
        u = p2 - p1
        u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-300)
        r = com - gp
        return np.linalg.norm(r - np.sum(r * u, axis=-1, keepdims=True) * u, axis=-1)
    raise InvalidParameterError(f"stability mode {mode!r} unknown; valid: {STABILITY_MODES}")


@dataclass(frozen=True)
class GraspQuality:
    """Quality columns for N grasps: fc_angle [rad], q_fc, stability_distance [m],
    q_st, grade -- all (N,) float arrays."""

    fc_angle: np.ndarray
    q_fc: np.ndarray
    stability_distance: np.ndarray
    q_st: np.ndarray
    grade: np.ndarray


@dataclass(frozen=True)
class QualityModel:
    """The paper's grade: force-closure angle + stability distance, weighted.

    friction: Coulomb coefficient mu the planner assumes at the pads.
    fc_weight: w, the weight of the force-closure term (1 - w for stability).
    stability_mode: ``"grasp_point"`` (paper) or ``"closing_line"``.
    stability_reference: d_ref [m]; None = the object's circumradius about its COM.
    threshold: grade above which a grasp is accepted (paper: 0.7).
    """

    friction: float = 0.5
    fc_weight: float = 0.5
    stability_mode: str = "grasp_point"
    stability_reference: float | None = None
    threshold: float = 0.7
    name: str = "paper"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.friction) and self.friction > 0):
            raise InvalidParameterError(f"friction must be > 0, got {self.friction!r}")
        if not 0.0 <= self.fc_weight <= 1.0:
            raise InvalidParameterError(f"fc_weight must be in [0, 1], got {self.fc_weight!r}")
        if self.stability_mode not in STABILITY_MODES:
            raise InvalidParameterError(
                f"stability_mode {self.stability_mode!r} unknown; valid: {STABILITY_MODES}"
            )
        if self.stability_reference is not None and not self.stability_reference > 0:
            raise InvalidParameterError(
                f"stability_reference must be > 0 m or None, got {self.stability_reference!r}"
            )
        if not 0.0 <= self.threshold <= 1.0:
            raise InvalidParameterError(f"threshold must be in [0, 1], got {self.threshold!r}")

    @property
    def friction_angle(self) -> float:
        """atan(mu) [rad]: the half-angle of the friction cone."""
        return math.atan(self.friction)

    def reference_distance(self, circumradius: float) -> float:
        return float(self.stability_reference or circumradius)

    def evaluate(
        self,
        p1: np.ndarray,
        p2: np.ndarray,
        n1: np.ndarray,
        n2: np.ndarray,
        com: np.ndarray,
        d_ref: float,
    ) -> GraspQuality:
        """Grade N contact pairs (arrays (N, 3)) of an object with centre of mass
        ``com`` and stability reference distance ``d_ref`` [m]."""
        if not d_ref > 0:
            raise InvalidParameterError(f"d_ref must be > 0 m, got {d_ref!r}")
        alpha = force_closure_angle(p1, p2, n1, n2)
        q_fc = np.clip(1.0 - alpha / self.friction_angle, 0.0, 1.0)
        dist = stability_distance(p1, p2, com, self.stability_mode)
        q_st, grade = self.combine(q_fc, dist, d_ref)
        return GraspQuality(alpha, q_fc, dist, q_st, grade)

    def combine(self, q_fc: np.ndarray, dist: np.ndarray, d_ref: float) -> tuple[np.ndarray, np.ndarray]:
        """Stability score and grade (N,) from q_fc and the stability distance [m] --
        how a grasp is re-graded when only its centre of mass moves (force closure is
        a property of the contacts, unchanged)."""
        q_st = np.clip(1.0 - np.asarray(dist, float) / d_ref, 0.0, 1.0)
        return q_st, self.fc_weight * np.asarray(q_fc, float) + (1.0 - self.fc_weight) * q_st

    def accepted(self, grade: np.ndarray) -> np.ndarray:
        return np.asarray(grade) > self.threshold

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_meta(cls, quality: dict) -> QualityModel:
        """The paper-grade model behind a map's ``meta.quality`` record (which also holds
        the reference distance used, and, for re-graded maps, the grade's own fields)."""
        base = quality.get("base_quality", quality) if isinstance(quality, dict) else quality
        if not isinstance(base, dict):
            raise InvalidParameterError(f"a quality record must be a dict, got {base!r}")
        fields = cls.__dataclass_fields__
        try:
            return cls(**{k: v for k, v in base.items() if k in fields})
        except (TypeError, ValueError) as err:
            raise InvalidParameterError(f"bad quality model parameters {base!r}: {err}") from err

    @classmethod
    def from_dict(cls, d: dict) -> QualityModel:
        try:
            return cls(**d)
        except (TypeError, ValueError) as err:
            raise InvalidParameterError(f"bad quality model parameters {d!r}: {err}") from err
