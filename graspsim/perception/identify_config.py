"""Settings of the primitive identification, with the paper and robust presets."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from graspsim.checks import Rule, check_fields
from graspsim.errors import InvalidParameterError

__all__ = ["MODES", "MAX_REPETITIONS", "IdentifyConfig"]

#: Most MLESAC repetitions per model: every hypothesis is scored against every point of
#: the cluster (repetitions x points residuals), so this bounds identification's memory
#: (1000 x 20000 points: ~0.2 GB per array). The paper's experiments use up to 400.
MAX_REPETITIONS = 1000

#: identification modes: the paper's rules alone, or the paper's rules then more
MODES: tuple[str, ...] = ("paper", "robust")


@dataclass(frozen=True)
class IdentifyConfig:
    """repetitions: MLESAC samples per model; theta: split threshold theta_th of eq. (1);
    min_cluster_points: smallest cluster a split may leave; noise: sensor sigma [m]
    (None: estimated from the cloud); sample_quantile: samples are drawn from the points
    whose surface variation is below this quantile (most reliable normals); max_parts:
    cap on clusters; link_factor, min_connected: a cluster is one continuous surface
    when its largest connected component, linking points closer than link_factor times
    the median point spacing, holds min_connected of its points; max_noise_ratio: the
    noise may be at most this fraction of the cluster's bounding-box diagonal;
    min_fit_rate, fit_margin, symmetry_tol, taper_tol: the classifier's thresholds (see
    classify); max_extent_ratio: a model may extend along each of its axes at most
    this many times as far as its cluster (one view sees at least half of a convex
    body: 2); min_coverage, max_uncovered_extent: a candidate model whose surface has
    cluster points near less than min_coverage of it (one view covers up to ~1/2, see
    support) may extend along its axes at most max_uncovered_extent times as far as its
    cluster; max_points: a denser cloud is voxel-downsampled to at most this many points
    before anything else (:func:`~graspsim.perception.prepare.voxel_downsample`).

    mode: ``"paper"`` runs the paper's loop and nothing else (a cluster left unexplained
    when no split is allowed fails the identification); ``"robust"`` (the default) runs
    the same loop first -- where it explains the cloud, the result is the paper's -- and
    then keeps going on the clusters it left (see
    :mod:`~graspsim.perception.decompose`). Robust-only settings: max_theta: splits are
    tried at thresholds up to this; band: a point is explained by a model within
    ``band`` times the scale of the data (noise and point spacing, see
    :func:`~graspsim.perception.acceptance.inlier_band`); approx_fit_rate: a part whose
    model explains at least this fraction of its points within the band is used,
    flagged ``approximate`` when that is below min_fit_rate; min_handle_points: fewest
    points a peeled handle may have; settle_rate: an identified part explaining this
    fraction of its points within the band is not decomposed further; robust_points: when
    the paper's loop leaves something to decompose, a denser cloud is voxel-downsampled
    to at most this many points and identified again (the decomposition fits many
    candidate clusters; part indices still refer to every input point); fit_points: in
    robust mode a cloud denser than this is voxel-downsampled to at most this many points
    before anything else (None, the default: only ``max_points`` applies; scene planning
    sets it, see :class:`~graspsim.planning.scene.SceneConfig`; on a dense cloud with
    noise above its spacing, thinning loses what the noise estimate and the refinements
    gain from many points: a weak taper, the end of a side); paper mode never applies
    it. Build either with :meth:`preset`."""

    repetitions: int = 10
    theta: float = 0.5
    min_cluster_points: int = 30
    noise: float | None = None
    remove_outliers: bool = True  # drop statistical outliers first (perception.normals.remove_outliers)
    refine: bool = True  # refine MLESAC's best model by robust least squares on its inliers, kept if likelier
    sample_quantile: float = 0.7
    max_parts: int = 16
    link_factor: float = 4.0
    min_connected: float = 0.5
    max_noise_ratio: float = 0.03
    min_fit_rate: float = 0.85  # a candidate model's least fit rate (fraction of the cluster's points)
    fit_margin: float = 0.03  # ... and at most this far (a fraction) below the best model's fit rate
    symmetry_tol: float = 2.5  # rotationally symmetric below this many noise sigmas (feature 3)
    taper_tol: float = 3.0  # tapered: halves' radii differ by over this many noise sigmas and 5 % of the radius
    max_extent_ratio: float = 2.5  # (new fields last: positional construction still works)
    min_coverage: float = 0.3
    max_uncovered_extent: float = 1.25
    max_points: int = 20000
    mode: str = "robust"
    max_theta: float = 0.9
    band: float = 3.0
    approx_fit_rate: float = 0.6
    min_handle_points: int = 30
    settle_rate: float = 0.97
    robust_points: int = 1200
    fit_points: int | None = None

    def __post_init__(self) -> None:
        finite = math.isfinite
        checks = [
            ("repetitions", lambda v: _whole(v) and 1 <= v <= MAX_REPETITIONS,
             f"an integer in [1, {MAX_REPETITIONS}]"),
            ("theta", lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("min_cluster_points", lambda v: v >= 10, ">= 10"),
            ("noise", lambda v: v is None or (finite(v) and v > 0), "finite and > 0 m, or None"),
            ("sample_quantile", lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("max_parts", lambda v: v >= 1, ">= 1"),
            ("link_factor", lambda v: finite(v) and v > 0, "> 0"),
            ("min_connected", lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("max_noise_ratio", lambda v: finite(v) and v > 0, "> 0"),
            ("max_extent_ratio", lambda v: v >= 1.0, ">= 1"),
            ("min_coverage", lambda v: 0.0 <= v < 1.0, "in [0, 1)"),
            ("max_uncovered_extent", lambda v: v >= 1.0, ">= 1"),
            ("min_fit_rate", lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("fit_margin", lambda v: 0.0 <= v < 1.0, "in [0, 1)"),
            ("symmetry_tol", lambda v: finite(v) and v > 0, "> 0"),
            ("taper_tol", lambda v: finite(v) and v > 0, "> 0"),
            ("max_points", lambda v: _whole(v) and v >= 1000, ">= 1000, an integer"),
            ("mode", lambda v: v in MODES, f"one of {MODES}"),
            ("max_theta", lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("band", lambda v: finite(v) and v > 0, "> 0"),
            ("approx_fit_rate", lambda v: 0.0 < v <= self.min_fit_rate, "in (0, min_fit_rate]"),
            ("min_handle_points", lambda v: _whole(v) and v >= 10, ">= 10"),
            ("settle_rate", lambda v: self.min_fit_rate <= v <= 1.0, "in [min_fit_rate, 1]"),
            ("robust_points", lambda v: _whole(v) and v >= 500, ">= 500, an integer"),
            ("fit_points", lambda v: v is None or (_whole(v) and v >= 300), "None or >= 300, an integer"),
        ]
        for name, ok, valid in checks:
            check_fields(self, Rule(ok, valid), name)

    @classmethod
    def preset(cls, mode: str, **changes) -> IdentifyConfig:
        """The named preset: ``"paper"`` reproduces the paper's identification exactly
        (theta_th 0.5, 85 % explained, the MLESAC inlier rule, no further decomposition);
        ``"robust"`` is the default (the paper's loop, then decomposition that keeps
        going). ``changes`` override single settings."""
        if mode not in MODES:
            raise InvalidParameterError(f"identification mode must be one of {MODES}, got {mode!r}")
        return cls(**{"mode": mode, **changes})

    @property
    def is_robust(self) -> bool:
        return self.mode == "robust"

    @property
    def point_limit(self) -> int:
        """Most points identification fits on (a denser cloud is downsampled first):
        ``max_points``, and in robust mode ``fit_points`` where that is lower."""
        if self.is_robust and self.fit_points is not None:
            return int(min(self.max_points, self.fit_points))
        return int(self.max_points)


def _whole(v) -> bool:
    return isinstance(v, (int, np.integer)) or (isinstance(v, float) and v.is_integer())
