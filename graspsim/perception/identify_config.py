"""Settings of the primitive identification, with the paper and robust presets."""

from __future__ import annotations

from dataclasses import dataclass

from graspsim.errors import InvalidParameterError

__all__ = ["MODES", "IdentifyConfig"]

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
    candidate clusters; part indices still refer to every input point). Build either with :meth:`preset`."""

    repetitions: int = 10
    theta: float = 0.5
    min_cluster_points: int = 30
    noise: float | None = None
    remove_outliers: bool = True
    refine: bool = True
    sample_quantile: float = 0.7
    max_parts: int = 16
    link_factor: float = 4.0
    min_connected: float = 0.5
    max_noise_ratio: float = 0.03
    min_fit_rate: float = 0.85
    fit_margin: float = 0.03
    symmetry_tol: float = 2.5
    taper_tol: float = 3.0
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

    def __post_init__(self) -> None:
        checks = [
            ("repetitions", self.repetitions >= 1 and int(self.repetitions) == self.repetitions, ">= 1, an integer"),
            ("theta", 0.0 < self.theta <= 1.0, "in (0, 1]"),
            ("min_cluster_points", self.min_cluster_points >= 10, ">= 10"),
            ("noise", self.noise is None or self.noise > 0, "> 0 m or None"),
            ("sample_quantile", 0.0 < self.sample_quantile <= 1.0, "in (0, 1]"),
            ("max_parts", self.max_parts >= 1, ">= 1"),
            ("link_factor", self.link_factor > 0, "> 0"),
            ("min_connected", 0.0 < self.min_connected <= 1.0, "in (0, 1]"),
            ("max_noise_ratio", self.max_noise_ratio > 0, "> 0"),
            ("max_extent_ratio", self.max_extent_ratio >= 1.0, ">= 1"),
            ("min_coverage", 0.0 <= self.min_coverage < 1.0, "in [0, 1)"),
            ("max_uncovered_extent", self.max_uncovered_extent >= 1.0, ">= 1"),
            ("min_fit_rate", 0.0 < self.min_fit_rate <= 1.0, "in (0, 1]"),
            ("fit_margin", 0.0 <= self.fit_margin < 1.0, "in [0, 1)"),
            ("symmetry_tol", self.symmetry_tol > 0, "> 0"),
            ("taper_tol", self.taper_tol > 0, "> 0"),
            ("max_points", self.max_points >= 1000 and int(self.max_points) == self.max_points,
             ">= 1000, an integer"),
            ("mode", self.mode in MODES, f"one of {MODES}"),
            ("max_theta", 0.0 < self.max_theta <= 1.0, "in (0, 1]"),
            ("band", self.band > 0, "> 0"),
            ("approx_fit_rate", 0.0 < self.approx_fit_rate <= self.min_fit_rate, "in (0, min_fit_rate]"),
            ("min_handle_points", self.min_handle_points >= 10, ">= 10"),
            ("settle_rate", self.min_fit_rate <= self.settle_rate <= 1.0, "in [min_fit_rate, 1]"),
            ("robust_points", self.robust_points >= 500 and int(self.robust_points) == self.robust_points,
             ">= 500, an integer"),
        ]
        for name, ok, valid in checks:
            if not ok:
                raise InvalidParameterError(f"{name} must be {valid}, got {getattr(self, name)!r}")


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

