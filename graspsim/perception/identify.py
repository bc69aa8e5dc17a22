"""Primitive identification of a segmented object cloud (paper 2.2-2.3).

The paper's loop: the whole cloud starts as one cluster; each cluster is identified
(MLESAC fits of all five models, four features, rule base); an unidentified cluster
goes back to the hierarchical MVBB fit-and-split; a split is only made while it gains
enough volume (theta* < theta_th, eq. 1) and leaves ``min_cluster_points`` on both
sides. When no split is allowed and clusters remain unidentified, identification has
*failed* and the result still lists the identified parts (for a partial map).

Preprocessing, once per cloud: statistical outlier removal, PCA normals with outward
orientation and the sensor-noise estimate, over neighbourhoods wider than the noise.

Per cluster, beyond the paper's MLESAC fits: a cylinder is also refined as a cone (a
weak taper is ill-posed for four-point cone samples) and an untapered cone yields a
cylinder; cylinder and cone ends nobody saw are cut back to their points; a model
larger than its cluster is no hypothesis, and a candidate that reaches beyond its
points while little of its surface has points near it is rejected (see support).
Every random draw comes from the caller's
generator, clusters are visited breadth first, so the same seed gives the same result.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError, PrimitiveError
from graspsim.perception.classify import Shape, classify
from graspsim.perception.features import ShapeFeatures, shape_features
from graspsim.perception.io import check_cloud
from graspsim.perception.mlesac import ModelFit, fit_from, fit_model, rescore, residual_sigma
from graspsim.perception.mvbb import OrientedBox, min_volume_box
from graspsim.perception.normals import estimate_local_surface, remove_outliers
from graspsim.perception.prepare import Downsampling, check_solid, voxel_downsample
from graspsim.perception.shapes import KINDS, fit_to_object
from graspsim.perception.split import best_split, theta_star
from graspsim.perception.support import extent_ratio, surface_coverage

__all__ = ["IdentificationStatus", "IdentifyConfig", "PartResult", "Identification",
           "identify", "identify_cluster"]

log = logging.getLogger(__name__)


class IdentificationStatus(str, Enum):
    IDENTIFIED = "identified"
    FAILED = "failed"


#: Most MLESAC repetitions per model: every hypothesis is scored against every point of
#: the cluster (repetitions x points residuals), so this bounds identification's memory
#: (1000 x 20000 points: ~0.2 GB per array). The paper's experiments use up to 400.
MAX_REPETITIONS = 1000


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
    before anything else (:func:`~graspsim.perception.prepare.voxel_downsample`)."""

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
        ]
        for name, ok, valid in checks:
            value = getattr(self, name)
            try:
                good = bool(ok(value))
            except (TypeError, ValueError):  # not a number at all
                good = False
            if not good:
                raise InvalidParameterError(f"{name} must be {valid}, got {value!r}")


def _whole(v) -> bool:
    return isinstance(v, (int, np.integer)) or (isinstance(v, float) and v.is_integer())


@dataclass(frozen=True, eq=False)
class PartResult:
    """One cluster. shape: the class; dims: named dims [m] ({} if unidentified);
    T_world_obj (4, 4): object frame of DESIGN.md §3 (the cluster's MVBB frame if
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
                "fit_rates": dict(self.features.fit_rates), "coverage": dict(self.coverage)}


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

    def to_dict(self) -> dict:
        return {"status": self.status.value, "parts": [p.to_dict() for p in self.parts],
                "unidentified": [p.to_dict() for p in self.unidentified],
                "n_points": self.n_points, "n_removed": self.n_removed, "noise": self.noise,
                "n_splits": self.n_splits, "seconds": self.seconds,
                "downsampling": None if self.downsampling is None else self.downsampling.to_dict()}


def _continuity(points: np.ndarray, link_factor: float) -> tuple[float, float, cKDTree]:
    """Fraction of the points in the largest component of the graph linking points
    closer than ``link_factor`` times the median nearest-neighbour distance; that
    distance [m]; the points' KD-tree."""
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    pairs = tree.query_pairs(link_factor * max(spacing, 1e-9), output_type="ndarray")
    n = len(points)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return float(np.bincount(labels).max() / n), spacing, tree


def _off_flat(pool: np.ndarray, normals: np.ndarray, *, share: float = 0.25,
              max_angle_deg: float = 10.0) -> np.ndarray:
    """The sample pool without its largest flat face (``share`` or more of the pool's
    normals within ``max_angle_deg`` of one direction), when enough points remain: a
    frustum seen with its base disc gives cone hypotheses only from side points, and
    four-point samples that mix in disc points are wasted."""
    if len(pool) < 16:
        return pool
    nv = normals[pool]
    cos = np.cos(np.radians(max_angle_deg))
    probe = nv[np.linspace(0, len(pool) - 1, min(len(pool), 256)).astype(int)]  # candidate directions
    counts = (np.abs(probe @ probe.T) > cos).sum(axis=1)
    flat = np.abs(nv @ probe[int(np.argmax(counts))]) > cos
    if flat.sum() < share * len(pool) or len(pool) - flat.sum() < 8:
        return pool
    return pool[~flat]


def identify_cluster(points: np.ndarray, normals: np.ndarray, sample_pool: np.ndarray,
                     noise: float, rng: np.random.Generator, config: IdentifyConfig,
                     indices: np.ndarray | None = None) -> PartResult:
    """Fit all models to one cluster (n, 3) [m] with unit normals (n, 3) and classify.

    sample_pool: indices (into the cluster) that minimal samples are drawn from. A
    cluster that is not one continuous surface, or whose noise is large for its size,
    is unidentified without fitting."""
    indices = np.arange(len(points)) if indices is None else indices
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    reason = ""
    if noise > config.max_noise_ratio * size:
        reason = f"noise {noise * 1000:.2f} mm is too large for a {size * 100:.1f} cm cluster"
    else:
        frac, spacing, tree = _continuity(points, config.link_factor)
        if frac < config.min_connected:
            reason = f"not one continuous surface: largest connected part {100 * frac:.0f} %"
    if reason:
        feats = ShapeFeatures(0.0, 0.0, float("nan"), float("nan"), float("nan"), {})
        return PartResult(Shape.UNIDENTIFIED, {}, np.eye(4), 0.0, float("inf"), indices, feats,
                          noise, {}, reason)
    pools = {k: sample_pool for k in KINDS}
    pools["cone"] = _off_flat(sample_pool, normals)
    fits = {k: fit_model(k, points, normals, rng, repetitions=config.repetitions,
                         sigma=noise, candidates=pools[k], refine=config.refine,
                         max_extent_ratio=config.max_extent_ratio)
            for k in KINDS}
    cone, cyl = fits.get("cone"), fits.get("cylinder")
    if cyl is not None and cyl.fit_rate >= config.min_fit_rate - 0.15:
        # a cylinder is a cone with equal radii: a weak taper (a pencil cup) is found by
        # refining a cylinder that nearly fits as a cone, where four-point cone samples
        # are ill-posed
        seeded = fit_from("cone", points, cyl.R, cyl.t, [cyl.dims[0], cyl.dims[0], cyl.dims[1]], sigma=noise,
                          refine=config.refine, max_extent_ratio=config.max_extent_ratio)
        if cone is None or seeded.loglik > cone.loglik:
            fits["cone"] = seeded
    # second pass on the noise: the spread of the most likely model's residuals is a
    # sharper sigma than the local estimate; all fits are rescored with it. Only
    # downwards: the local estimate is an upper quantile of the local residuals, so a
    # model whose residuals spread wider shows its misfit (a cylinder through a
    # frustum), and a sigma inflated by it would hide the misfit from the features
    ok = [f for f in fits.values() if f is not None]
    if ok:
        top = max(ok, key=lambda f: f.loglik)
        s1 = residual_sigma(top, points)
        if np.isfinite(s1):
            noise = float(np.clip(s1, 0.5 * noise, noise))
            fits = {k: (rescore(f, points, noise) if f is not None else None) for k, f in fits.items()}
    # models good enough to be candidates must also be supported: their surface must
    # be covered by the cluster about as much as one view covers a body
    radius = 3.0 * noise + 2.0 * spacing
    coverage: dict[str, float] = {}

    def supported(f: ModelFit | None) -> ModelFit | None:
        if f is None or f.fit_rate < config.min_fit_rate:
            return f
        if extent_ratio(f.kind, f.R[None], f.t[None], f.dims[None], points, noise)[0] <= config.max_uncovered_extent:
            return f  # within its points' extent: whatever is empty was hidden from view
        coverage[f.kind] = surface_coverage(f.kind, f.R, f.t, f.dims, tree, radius=radius)
        return f if coverage[f.kind] >= config.min_coverage else None

    usable = {k: supported(f) for k, f in fits.items()}
    feats = shape_features(points, usable)
    shape = classify(feats, noise, min_fit_rate=config.min_fit_rate,
                     fit_margin=config.fit_margin, symmetry_tol=config.symmetry_tol,
                     taper_tol=config.taper_tol)
    cone, cyl = usable.get("cone"), usable.get("cylinder")
    if shape is Shape.CYLINDER and cone is not None and (cyl is None or cone.fit_rate > cyl.fit_rate):
        # an untapered cone is a cylinder: fit the cylinder from the cone's axis
        seeded = supported(fit_from("cylinder", points, cone.R, cone.t,
                                    [0.5 * (cone.dims[0] + cone.dims[1]), cone.dims[2]], sigma=noise,
                                    refine=config.refine, max_extent_ratio=config.max_extent_ratio))
        if seeded is not None and seeded.fit_rate >= config.min_fit_rate and (
                cyl is None or seeded.loglik > cyl.loglik):
            fits["cylinder"] = usable["cylinder"] = seeded
            feats = shape_features(points, usable)
        elif cyl is None:
            shape = Shape.CONE  # no cylinder can be made of it: keep what fits
    if shape is Shape.UNIDENTIFIED:
        best = max((f for f in fits.values() if f is not None), key=lambda f: f.fit_rate, default=None)
        if best is None:
            reason = "no model could be hypothesised"
        elif best.fit_rate >= config.min_fit_rate and coverage.get(best.kind, 1.0) < config.min_coverage:
            reason = (f"no model fits: best {best.kind} explains {100 * best.fit_rate:.0f} % of the points "
                      f"but reaches beyond them and only {100 * coverage[best.kind]:.0f} % of its surface "
                      "has points")
        else:
            reason = f"no model fits: best {best.kind} explains {100 * best.fit_rate:.0f} % of the points"
        return PartResult(shape, {}, np.eye(4), best.fit_rate if best else 0.0,
                          best.rms if best else float("inf"), indices, feats, noise, fits, reason, coverage)
    fit = fits[shape.value]
    try:
        prim, T = fit_to_object(shape.value, fit.R, fit.t, fit.dims)
    except PrimitiveError as err:  # a flat or thin cluster: below the primitive floor
        return PartResult(Shape.UNIDENTIFIED, {}, np.eye(4), fit.fit_rate, fit.rms, indices, feats, noise,
                          fits, f"degenerate {shape.value} fit: {err}", coverage)
    return PartResult(shape, prim.dims, T, fit.fit_rate, fit.rms, indices, feats, noise, fits, "", coverage)


def _unidentified(part: PartResult, box: OrientedBox) -> PartResult:
    return replace(part, T_world_obj=box.T_world_box.copy())


def identify(points: np.ndarray, *, rng: np.random.Generator,
             config: IdentifyConfig | None = None) -> Identification:
    """Identify the shape primitives of an object cloud (N, 3), world frame [m]."""
    t0 = time.perf_counter()
    cfg = config or IdentifyConfig()
    pts_all = check_cloud(points, min_points=cfg.min_cluster_points)
    down = voxel = None
    if len(pts_all) > cfg.max_points:
        used, voxel, down = voxel_downsample(pts_all, cfg.max_points)
        pts_all = pts_all[used]
    keep = remove_outliers(pts_all) if cfg.remove_outliers else np.ones(len(pts_all), bool)
    if keep.sum() < cfg.min_cluster_points:
        keep[:] = True
    kept = np.flatnonzero(keep)
    pts = pts_all[kept]
    check_solid(pts)
    surf = estimate_local_surface(pts)
    noise = float(cfg.noise) if cfg.noise is not None else surf.noise
    reliable = surf.flatness <= np.quantile(surf.flatness, cfg.sample_quantile)

    # leaves of the hierarchy: (local indices, MVBB or None for the unsplit root)
    queue: deque[tuple[np.ndarray, OrientedBox | None]] = deque([(np.arange(len(pts)), None)])
    done: list[tuple[PartResult, OrientedBox | None]] = []
    failed: list[tuple[PartResult, OrientedBox]] = []
    n_splits = 0
    while queue:
        idx, box = queue.popleft()
        sub = pts[idx]
        pool = np.flatnonzero(reliable[idx])
        part = identify_cluster(sub, surf.normals[idx], pool, noise, rng, cfg, kept[idx])
        if part.shape is not Shape.UNIDENTIFIED:
            done.append((part, box))
            continue
        box = box if box is not None else min_volume_box(sub)
        n_leaves = len(done) + len(failed) + len(queue) + 1
        split = None
        if n_leaves < cfg.max_parts and len(idx) >= 2 * cfg.min_cluster_points:
            split = best_split(sub, box, min_points=cfg.min_cluster_points)
        if split is not None:
            others = sum(b.volume for _, b in done + failed if b is not None)
            others += sum(b.volume for _, b in queue if b is not None)
            theta = theta_star(box.volume, (split.boxes[0].volume, split.boxes[1].volume), others)
            log.debug("split of %d points: area ratio %.3f, theta* %.3f (threshold %.3f)",
                      len(idx), split.area_ratio, theta, cfg.theta)
            if theta < cfg.theta:
                n_splits += 1
                queue.append((idx[split.mask], split.boxes[0]))
                queue.append((idx[~split.mask], split.boxes[1]))
                continue
        failed.append((_unidentified(part, box), box))
    status = IdentificationStatus.FAILED if failed else IdentificationStatus.IDENTIFIED
    parts, left = (tuple(_expand(p, voxel) for p, _ in group) for group in (done, failed))
    return Identification(status, parts, left, len(pts_all) if down is None else down.input_points,
                          int(len(pts_all) - len(kept)), noise, n_splits, time.perf_counter() - t0, down)


def _expand(part: PartResult, voxel: np.ndarray | None) -> PartResult:
    """The part with the indices of every input point in its voxels (``voxel``: (N,)
    voxel of each input point; None: the cloud was not downsampled)."""
    if voxel is None:
        return part
    member = np.zeros(int(voxel.max()) + 1, bool)
    member[part.indices] = True
    return replace(part, indices=np.flatnonzero(member[voxel]))
