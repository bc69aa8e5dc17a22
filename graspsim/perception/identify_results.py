"""What primitive identification returns (:func:`~graspsim.perception.identify.identify`):
the :class:`Identification` of a cloud, its status, and a :class:`PartResult` per
cluster (identified or not)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from graspsim.perception.classify import Shape
from graspsim.perception.mlesac import ModelFit
from graspsim.perception.prepare import Downsampling
from graspsim.perception.shape_features import ShapeFeatures

__all__ = ["IdentificationStatus", "PartResult", "Identification"]


class IdentificationStatus(str, Enum):
    IDENTIFIED = "identified"  # every cluster explained by the rules of the mode
    PARTIAL = "partial"  # robust mode: parts found, but some approximate or some points not covered
    FAILED = "failed"  # the paper's outcome when a cluster is left; robust: nothing found


@dataclass(frozen=True, eq=False)
class PartResult:
    """One cluster. shape: the class; dims: named dims [m] ({} if unidentified);
    T_world_obj (4, 4): object frame of docs/design.md §3 (the cluster's MVBB frame if
    unidentified); fit_rate, rms [m]: of the chosen model (best model if unidentified);
    indices: (n,) indices of the cluster's points in the input cloud; noise: the sigma
    [m] the final fit rates were scored with; reason: why a cluster is unidentified
    ("" when identified); coverage: surface coverage of each model that fitted enough
    points to be a candidate but reaches beyond its cluster (see
    :mod:`~graspsim.perception.support`)."""

    shape: Shape
    dims: dict[str, float]
    T_world_obj: np.ndarray
    fit_rate: float
    rms: float
    indices: np.ndarray
    features: ShapeFeatures
    noise: float
    fits: dict[str, ModelFit | None] = field(repr=False)
    reason: str = ""
    coverage: dict[str, float] = field(default_factory=dict, repr=False)
    approximate: bool = False
    band_rate: float | None = None

    @property
    def n_points(self) -> int:
        return int(len(self.indices))

    def primitive(self):
        """The identified :class:`~graspsim.primitives.Primitive`, or None."""
        if self.shape is Shape.UNIDENTIFIED:
            return None
        from graspsim.primitives import make_primitive

        return make_primitive(self.shape.value, **self.dims)

    def to_dict(self) -> dict:
        return {"primitive": self.shape.value, "dims": dict(self.dims),
                "pose": self.T_world_obj.tolist(), "fit_rate": self.fit_rate,
                "rms": self.rms, "points": self.n_points, "noise": self.noise,
                "reason": self.reason,
                "fit_rates": dict(self.features.fit_rates), "coverage": dict(self.coverage),
                "approximate": self.approximate, "band_rate": self.band_rate}


@dataclass(frozen=True, eq=False)
class Identification:
    """status; parts: identified clusters; unidentified: clusters left over when the
    split threshold was reached; n_points: points given; n_removed: outliers dropped
    (of the points used); noise: the cloud's initial sigma estimate [m] (each part
    rescores with a sharper one, ``part.noise``); n_splits: splits made; seconds: wall
    time (the only non-deterministic field); downsampling: how a dense cloud was thinned
    (None: all points used; part indices still refer to every input point)."""

    status: IdentificationStatus
    parts: tuple[PartResult, ...]
    unidentified: tuple[PartResult, ...]
    n_points: int
    n_removed: int
    noise: float
    n_splits: int
    seconds: float
    downsampling: Downsampling | None = None
    mode: str = "paper"

    @property
    def uncovered(self) -> list[dict]:
        """What the parts do not cover: every unidentified cluster and every approximate
        part, with its points and why."""
        out = [{"points": p.n_points, "reason": p.reason} for p in self.unidentified]
        out += [{"points": p.n_points, "reason": f"approximate {p.shape.value}: "
                 f"{100 * (p.band_rate or 0.0):.0f} % within the inlier band"} for p in self.parts if p.approximate]
        return out

    def fit_quality(self, points: np.ndarray, factor: float = 3.0, viewpoint: np.ndarray | None = None):
        """How well the identified parts explain the whole cloud ``points`` (N, 3) the
        identification was made from (:class:`~graspsim.perception.acceptance.FitQuality`):
        every point's distance to the nearest part, with the inlier band ``factor`` x the
        scale of this cloud's noise and spacing (robust mode's band: ``IdentifyConfig.band``);
        ``viewpoint`` (3,): where a single view was seen from (only the parts' surface
        facing it counts as coverable), None: seen all round."""
        from graspsim.geometry.spacing import median_spacing
        from graspsim.perception.acceptance import fit_quality, inlier_band

        P = np.asarray(points, float).reshape(-1, 3)
        spacing = median_spacing(P) if len(P) > 1 else 0.0
        return fit_quality(P, [p.primitive() for p in self.parts], [p.T_world_obj for p in self.parts],
                           inlier_band(self.noise, spacing, factor), spacing, viewpoint)

    def to_dict(self) -> dict:
        return {"status": self.status.value, "parts": [p.to_dict() for p in self.parts],
                "unidentified": [p.to_dict() for p in self.unidentified],
                "n_points": self.n_points, "n_removed": self.n_removed, "noise": self.noise,
                "n_splits": self.n_splits, "seconds": self.seconds,
                "downsampling": None if self.downsampling is None else self.downsampling.to_dict(),
                "mode": self.mode, "uncovered": self.uncovered}
