"""One cluster of a cloud identified (paper 2.2): the four primitives fitted by MLESAC,
their shape features and the rule-based classification (:func:`identify_cluster`), and
the prepared cloud the hierarchy and the robust decomposition both cut into clusters
(:class:`Cloud`). The whole cloud's identification is :func:`graspsim.perception.identify.identify`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from graspsim.errors import PrimitiveError
from graspsim.geometry.spacing import median_spacing
from graspsim.perception.classify import Shape, classify
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.identify_results import PartResult
from graspsim.perception.mlesac import ModelFit, fit_from, fit_model, rescore, residual_sigma
from graspsim.perception.shape_features import ShapeFeatures, shape_features
from graspsim.perception.support import extent_ratio, surface_coverage
from graspsim.primitives.sdf import KINDS, fit_to_object

__all__ = ["Cloud", "identify_cluster", "other_models"]


def _continuity(points: np.ndarray, link_factor: float) -> tuple[float, float, cKDTree]:
    """Fraction of the points in the largest component of the graph linking points
    closer than ``link_factor`` times the median nearest-neighbour distance; that
    distance [m]; the points' KD-tree."""
    tree = cKDTree(points)
    spacing = median_spacing(points)  # repeated points count once
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


def _precheck(points: np.ndarray, noise: float, config: IdentifyConfig):
    """(reason, spacing, tree): why a cluster is not fitted at all ("" if it is)."""
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    if noise > config.max_noise_ratio * size:
        return f"noise {noise * 1000:.2f} mm is too large for a {size * 100:.1f} cm cluster", 0.0, None
    frac, spacing, tree = _continuity(points, config.link_factor)
    if frac < config.min_connected:
        return f"not one continuous surface: largest connected part {100 * frac:.0f} %", spacing, tree
    return "", spacing, tree


def _fit_all(points, normals, sample_pool, noise, rng, config: IdentifyConfig):
    """MLESAC fits of every model kind (a cylinder also refined as a cone), rescored with
    the sharper noise of the most likely model's residuals; (fits, noise)."""
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
    return fits, noise


def _unexplained_reason(fits, coverage, config: IdentifyConfig) -> tuple[str, ModelFit | None]:
    best = max((f for f in fits.values() if f is not None), key=lambda f: f.fit_rate, default=None)
    if best is None:
        return "no model could be hypothesised", None
    if best.fit_rate >= config.min_fit_rate and coverage.get(best.kind, 1.0) < config.min_coverage:
        return (f"no model fits: best {best.kind} explains {100 * best.fit_rate:.0f} % of the points "
                f"but reaches beyond them and only {100 * coverage[best.kind]:.0f} % of its surface "
                "has points"), best
    return f"no model fits: best {best.kind} explains {100 * best.fit_rate:.0f} % of the points", best


def identify_cluster(points: np.ndarray, normals: np.ndarray, sample_pool: np.ndarray,
                     noise: float, rng: np.random.Generator, config: IdentifyConfig,
                     indices: np.ndarray | None = None, *, check_noise: float | None = None) -> PartResult:
    """Fit all models to one cluster (n, 3) [m] with unit normals (n, 3) and classify
    by the paper's rules (whatever ``config.mode``).

    sample_pool: indices (into the cluster) that minimal samples are drawn from. A
    cluster that is not one continuous surface, or whose noise is large for its size,
    is unidentified without fitting (check_noise: the estimate that decides it, if not
    ``noise``)."""
    indices = np.arange(len(points)) if indices is None else indices
    reason, spacing, tree = _precheck(points, noise if check_noise is None else check_noise, config)
    if reason:
        feats = ShapeFeatures(0.0, 0.0, float("nan"), float("nan"), float("nan"), {})
        return PartResult(Shape.UNIDENTIFIED, {}, np.eye(4), 0.0, float("inf"), indices, feats,
                          noise, {}, reason)
    fits, noise = _fit_all(points, normals, sample_pool, noise, rng, config)
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
        reason, best = _unexplained_reason(fits, coverage, config)
        return PartResult(shape, {}, np.eye(4), best.fit_rate if best else 0.0,
                          best.rms if best else float("inf"), indices, feats, noise, fits, reason, coverage)
    fit = fits[shape.value]
    try:
        prim, T = fit_to_object(shape.value, fit.R, fit.t, fit.dims)
    except PrimitiveError as err:  # a flat or thin cluster: below the primitive floor
        return PartResult(Shape.UNIDENTIFIED, {}, np.eye(4), fit.fit_rate, fit.rms, indices, feats, noise,
                          fits, f"degenerate {shape.value} fit: {err}", coverage)
    return PartResult(shape, prim.dims, T, fit.fit_rate, fit.rms, indices, feats, noise, fits, "", coverage)


@dataclass(frozen=True)
class Cloud:
    """A prepared cloud: points (n, 3) [m] after downsampling and outlier removal, their
    unit normals, which are reliable samples, their indices ``kept`` into the points
    identified, the noise estimate [m] and the estimate its clusters are refused as too
    noisy by (robust mode: one thin walls and edges do not inflate, see
    :func:`~graspsim.perception.normals.estimate_local_surface`; else the same)."""

    points: np.ndarray
    normals: np.ndarray
    reliable: np.ndarray
    kept: np.ndarray
    noise: float
    check_noise: float

    def cluster(self, idx: np.ndarray, rng: np.random.Generator, cfg: IdentifyConfig) -> PartResult:
        """The paper's identification of the cluster of local indices ``idx``."""
        return identify_cluster(self.points[idx], self.normals[idx], np.flatnonzero(self.reliable[idx]),
                                self.noise, rng, cfg, self.kept[idx], check_noise=self.check_noise)


def other_models(part: PartResult, config: IdentifyConfig) -> list[PartResult]:
    """An identified ``part`` as each model its cluster fitted besides its own, best first:
    the other kinds whose fit rate reaches ``config.min_fit_rate``, whose surface was not
    rejected for reaching beyond the points (``coverage`` below ``config.min_coverage``)
    and that make a primitive, by RMS residual (kind name on a tie); none for an
    unidentified part. The rule base chose the part's own model from shape features;
    where that model gives the planner nothing (a Lego brick whose studs make it a sphere
    wider than the brick, its corners outside it) a model its points fit about as well
    may (``SceneConfig.feature_grasps`` ``"fallback"``)."""
    if part.shape is Shape.UNIDENTIFIED:
        return []
    ranked = sorted((f.rms, k, f) for k, f in part.fits.items()
                    if f is not None and k != part.shape.value and f.fit_rate >= config.min_fit_rate
                    and part.coverage.get(k, 1.0) >= config.min_coverage)
    out = []
    for _, kind, fit in ranked:
        try:
            prim, T = fit_to_object(kind, fit.R, fit.t, fit.dims)
        except PrimitiveError:  # below the primitive floor (a slab fitted a mm thick)
            continue
        out.append(PartResult(Shape(kind), prim.dims, T, fit.fit_rate, fit.rms, part.indices, part.features,
                              part.noise, part.fits, "", part.coverage))
    return out
