"""Robust identification: decomposition that keeps going where the paper's loop stops.

The paper's loop (2.2) gives up on a cluster when no model explains 85 % of its points
and no split gains enough volume (theta* < theta_th). In robust mode every cluster it
left is decomposed further. Candidate decompositions of the cluster:

* **one part**: the model kind with the best score alone (see
  :func:`~graspsim.perception.acceptance.decomposition_score`);
* **axial pieces**: a near-axisymmetric cluster (a bottle) cut across its axis where its
  radius profile changes (:func:`~graspsim.perception.profile.profile_segments`);
* **handle peeled**: the points outside the best cylinder or cone by more than the
  inlier band (a mug's handle) as a part of their own, the rest as the body;
* **split**: the best MVBB split, at any theta* up to ``max_theta``.

Each piece is identified by the paper's rules first, else as the best-scoring model
that can be used. The candidate with the lowest score -- the BIC-like likelihood of the
cluster under its parts, each part's points spread over its surface area, with a
penalty per parameter -- is kept, and its pieces that are still unexplained or
approximate are decomposed the same way (to a depth of three). A part whose model
explains at least ``approx_fit_rate`` of its points within the inlier band is used
(flagged ``approximate`` below ``min_fit_rate``); pieces below that stay unidentified.
Finally, neighbouring parts whose union one model explains as well as the two did are
merged, when that one part is also the likelier decomposition by the same score.

The paper's rule base decides a rotational model before it looks at the box (rule 3: a
cluster whose radii about its axis spread by at most 2.5 noise sigmas is a cylinder or
a cone). A single view of a box shows two or three of its faces, and under a depth
camera's noise (2-3 mm at a table's 0.7 m) the L of a block's top and near side spreads
about a cylinder's axis that little (a 150 x 50 x 30 mm block fitted as a cylinder of
radius 3 cm), a standing domino's face and edges as a cone. In robust mode every
cylinder or cone part is therefore challenged by the cluster's own box fit, when that
fit is a candidate (fit rate at least ``min_fit_rate``, supported): the likelier of the
two by the same score stands (:func:`_box_or_rotational`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from graspsim.errors import PrimitiveError
from graspsim.geometry.spacing import median_spacing
from graspsim.perception.acceptance import band_rate, data_scale, decomposition_score, inlier_band, model_distance
from graspsim.perception.classify import Shape
from graspsim.perception.cluster import Cloud
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.identify_results import PartResult
from graspsim.perception.mlesac import fit_from, rescore
from graspsim.perception.mvbb import min_volume_box
from graspsim.perception.profile import profile_segments
from graspsim.perception.split import best_split, theta_star
from graspsim.perception.support import extent_ratio
from graspsim.primitives.sdf import fit_to_object

__all__ = ["keep_going", "settled"]

_MAX_DEPTH = 3

#: A box stands for a cylinder or cone part only where at most this share fewer of the part's points
#: face as the box's faces do than as the rotational model's surface does (:func:`_facing`): near a box's
#: edges normals estimated over neighbourhoods wider than the noise turn smoothly, as a cylinder's do (E10's
#: household-tuning blocks seen on top and one side: 0.80-0.86 of the points face the box, 0.71-0.89 the
#: cylinder), while a plate standing for a curved strip faces far worse (bottles lying down: 0.47-0.59 against
#: 0.86-0.95).
FACING_MARGIN = 0.1


@dataclass(frozen=True)
class _Ctx:
    cloud: Cloud
    rng: np.random.Generator
    cfg: IdentifyConfig
    spacing: float
    band: float

    @property
    def scale(self) -> float:
        return data_scale(self.cloud.noise, self.spacing)


def _model(part: PartResult):
    return part.fits.get(part.shape.value) if part.shape is not Shape.UNIDENTIFIED else None


def _best_single(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> PartResult:
    """The part as the best-scoring single model of its fits that explains at least
    ``approx_fit_rate`` of its points within the band; else ``part`` (unidentified),
    also where that model is below the primitive floor (a flat face: a worse model
    does not stand for it)."""
    pts = ctx.cloud.points[idx]
    ranked = []
    for kind, fit in part.fits.items():
        if fit is None or part.coverage.get(kind, 1.0) < ctx.cfg.min_coverage:
            continue
        ranked.append((decomposition_score([fit], pts, ctx.band, ctx.cfg.band), kind, fit))
    rate = None
    for score, _, fit in sorted(ranked, key=lambda r: (r[0], r[1])):
        fit, rate = _widened(ctx, pts, fit, score, part.noise)
        if rate < ctx.cfg.approx_fit_rate:
            continue  # a model that cannot be used does not stand for the part: the next
        try:
            prim, T = fit_to_object(fit.kind, fit.R, fit.t, fit.dims)
        except PrimitiveError:
            break  # the best usable model is degenerate (a flat face): no primitive stands for it
        return replace(part, shape=Shape(fit.kind), dims=prim.dims, T_world_obj=T, fit_rate=fit.fit_rate,
                       rms=fit.rms, reason="", approximate=rate < ctx.cfg.min_fit_rate, band_rate=rate,
                       fits={**part.fits, fit.kind: fit})
    return part if rate is None else replace(part, band_rate=rate)


def _widened(ctx: _Ctx, pts: np.ndarray, fit, score: float, noise: float):
    """(fit, its band rate): ``fit`` refined with the data's scale as sigma when that
    scores better -- MLESAC's fit under the sensor sigma can sit off a surface the
    primitive only approximates (a rounded box's faces)."""
    wide = fit_from(fit.kind, pts, fit.R, fit.t, fit.dims, sigma=ctx.band / ctx.cfg.band, refine=ctx.cfg.refine,
                    max_extent_ratio=ctx.cfg.max_extent_ratio)
    if decomposition_score([wide], pts, ctx.band, ctx.cfg.band) < score:
        fit = rescore(wide, pts, noise)
    return fit, band_rate(fit, pts, ctx.band)


def _leaf(ctx: _Ctx, idx: np.ndarray) -> PartResult:
    """A piece: the paper's rules, else the best single model."""
    part = _box_or_rotational(ctx, idx, ctx.cloud.cluster(idx, ctx.rng, ctx.cfg))
    if part.shape is not Shape.UNIDENTIFIED:
        model = _model(part)
        rate = band_rate(model, ctx.cloud.points[idx], ctx.band) if model is not None else None
        return replace(part, band_rate=rate)
    return _best_single(ctx, idx, part)


def _axis_fit(part: PartResult):
    fits = [part.fits.get(k) for k in ("cylinder", "cone")]
    fits = [f for f in fits if f is not None]
    return max(fits, key=lambda f: f.fit_rate, default=None)


def _axial(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> list[PartResult] | None:
    feats = part.features
    axis = _axis_fit(part)
    if axis is None or not np.isfinite(feats.cylindrical_symmetry) or not np.isfinite(feats.mean_radius):
        return None
    if feats.cylindrical_symmetry > max(0.15 * feats.mean_radius, 3.0 * ctx.scale):
        return None  # not near-axisymmetric
    segs = profile_segments(ctx.cloud.points[idx], axis.t, axis.R[:, 2], spacing=ctx.spacing, scale=ctx.scale,
                            min_points=ctx.cfg.min_cluster_points)
    return None if segs is None else [_leaf(ctx, idx[s]) for s in segs]


def _peel(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> list[PartResult] | None:
    body = _axis_fit(part)
    if body is None:
        return None
    from graspsim.primitives.sdf import model_sdf

    sd = model_sdf(body.kind, body.R[None], body.t[None], body.dims[None], ctx.cloud.points[idx])[0]
    out = np.nan_to_num(sd, nan=0.0) > ctx.band
    if out.sum() < ctx.cfg.min_handle_points or len(idx) - out.sum() < ctx.cfg.min_cluster_points:
        return None
    return [_leaf(ctx, idx[~out]), _leaf(ctx, idx[out])]


def _split(ctx: _Ctx, idx: np.ndarray, force: bool = False) -> list[PartResult] | None:
    """The cluster's best MVBB split into two identified pieces, if it gains volume
    (theta* below ``max_theta``) or ``force``."""
    pts = ctx.cloud.points[idx]
    if len(idx) < 2 * ctx.cfg.min_cluster_points:
        return None
    box = min_volume_box(pts)
    split = best_split(pts, box, min_points=ctx.cfg.min_cluster_points)
    if split is None:
        return None
    theta = theta_star(box.volume, (split.boxes[0].volume, split.boxes[1].volume), 0.0)
    if theta >= max(ctx.cfg.max_theta, ctx.cfg.theta) and not force:
        return None
    return [_leaf(ctx, idx[split.mask]), _leaf(ctx, idx[~split.mask])]


def _assigned(ctx: _Ctx, idx: np.ndarray, parts: list[PartResult]) -> list[PartResult]:
    """The parts with the cluster's points re-assigned to the nearest identified part's
    surface (unidentified parts keep the points no identified part is near), and their
    band rates on those points."""
    good = [p for p in parts if p.shape is not Shape.UNIDENTIFIED]
    if len(good) < 2 or len(parts) > len(good):
        return parts
    pts = ctx.cloud.points[idx]
    d = np.stack([model_distance([_model(p)], pts) for p in good])
    owner = np.argmin(d, axis=0)
    out = []
    for j, p in enumerate(good):
        mine = owner == j
        if not mine.any():
            continue
        rate = float(np.mean(d[j, mine] <= ctx.band))
        out.append(replace(p, indices=ctx.cloud.kept[idx[mine]], band_rate=rate,
                           approximate=p.approximate or rate < ctx.cfg.approx_fit_rate))
    return out


def _score(ctx: _Ctx, idx: np.ndarray, parts: list[PartResult]) -> float:
    models = [_model(p) for p in parts if p.shape is not Shape.UNIDENTIFIED]
    return decomposition_score(models, ctx.cloud.points[idx], ctx.band, ctx.cfg.band)


def _solve(ctx: _Ctx, idx: np.ndarray, depth: int, part: PartResult | None = None) -> list[PartResult]:
    """The best decomposition of the cluster ``idx`` (local indices); ``part``: its
    identification by the paper's rules, if made already. An identified part that
    explains ``settle_rate`` of its points within the band is kept as it is."""
    if part is None:
        part = ctx.cloud.cluster(idx, ctx.rng, ctx.cfg)
    if not part.fits:  # not one surface, or too noisy for its size: nothing to fit
        return [part]
    if part.shape is not Shape.UNIDENTIFIED:
        first = _leaf_of(ctx, idx, _box_or_rotational(ctx, idx, part))
    else:
        first = _best_single(ctx, idx, part)
    if first.shape is not Shape.UNIDENTIFIED and (first.band_rate is None or first.band_rate >= ctx.cfg.settle_rate):
        return [first]
    cands = [[first]]
    for make in (_axial, _peel):
        c = make(ctx, idx, part)
        if c is not None:
            cands.append(_assigned(ctx, idx, c))
    split = None
    if not any(_settled(ctx, c) for c in cands[1:]):
        split = _split(ctx, idx)
        if split is not None:
            cands.append(split)
    best = min(cands, key=lambda c: _score(ctx, idx, c))
    if best is cands[0] and first.shape is Shape.UNIDENTIFIED and depth + 1 < _MAX_DEPTH:
        # nothing explains the cluster, not even roughly: its pieces, split where that gains no volume too (an
        # irregular object's lumps are fitted where the whole is not), rather than no part at all
        best = split or _split(ctx, idx, force=True) or best
    if len(best) == 1 or depth + 1 >= _MAX_DEPTH:
        return best
    # the pieces of the chosen decomposition that are still not explained: again
    out = []
    for p in best:
        poor = p.fits and (p.shape is Shape.UNIDENTIFIED or p.approximate)
        out += _solve(ctx, _local(ctx.cloud, p), depth + 1, p) if poor else [p]
    return out


def _settled(ctx: _Ctx, parts: list[PartResult]) -> bool:
    """Every part identified and explaining ``settle_rate`` of its points."""
    return all(p.shape is not Shape.UNIDENTIFIED and (p.band_rate or 0.0) >= ctx.cfg.settle_rate for p in parts)


def _leaf_of(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> PartResult:
    model = _model(part)
    return replace(part, band_rate=None if model is None else band_rate(model, ctx.cloud.points[idx], ctx.band))


def _local(cloud: Cloud, part: PartResult) -> np.ndarray:
    return np.searchsorted(cloud.kept, part.indices)


def _context(cloud: Cloud, rng: np.random.Generator, cfg: IdentifyConfig) -> _Ctx:
    spacing = median_spacing(cloud.points)
    return _Ctx(cloud, rng, cfg, spacing, inlier_band(cloud.noise, spacing, cfg.band))


def _facing(fit, pts: np.ndarray, normals: np.ndarray, max_angle_deg: float = 30.0) -> float:
    """Share of the points (N, 3) whose estimated normals (N, 3, either sign) lie within
    ``max_angle_deg`` of the normal of ``fit``'s surface where it is nearest to them (the
    normal test of efficient RANSAC's compatibility, Schnabel et al. 2007): distances
    alone let a thin plate stand for a curved strip seen from one side, its hidden back
    face catching the points the noise puts behind the front one."""
    try:
        prim, T = fit_to_object(fit.kind, fit.R, fit.t, fit.dims)
    except PrimitiveError:
        return 0.0
    model = prim.normals((pts - T[:3, 3]) @ T[:3, :3]) @ T[:3, :3].T
    return float(np.mean(np.abs(np.sum(model * normals, axis=1)) >= np.cos(np.radians(max_angle_deg))))


def _box_or_rotational(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> PartResult:
    """``part`` (cluster ``idx``, local indices), or a box when ``part`` is a cylinder or
    cone and a box explains the cluster as a candidate (fit rate >= ``min_fit_rate``)
    and more likely by :func:`~graspsim.perception.acceptance.decomposition_score` -- a
    proper density per unit surface, so the box does not win by reaching over empty
    space, nor the cylinder by a wide shell. The boxes tried: the cluster's own MLESAC
    box fit (ten three-point samples need two of them on a narrow side face to find a
    block's L of faces, so it is often a poor one) and the cluster's minimum-volume box
    refined -- the bounding box of a box's two or three seen faces is the box. Both
    sides of the comparison are refined with the data's scale as sigma where that
    scores better (:func:`_widened`)."""
    if part.shape not in (Shape.CYLINDER, Shape.CONE):
        return part
    own = _model(part)
    if own is None:
        return part
    pts = ctx.cloud.points[idx]
    sigma = ctx.band / ctx.cfg.band

    def score(fit) -> float:
        return decomposition_score([fit], pts, ctx.band, ctx.cfg.band)

    mvbb = min_volume_box(pts)
    seeds = [part.fits.get("box"), fit_from("box", pts, mvbb.T_world_box[:3, :3], mvbb.T_world_box[:3, 3],
                                            np.asarray(mvbb.extents, float), sigma=sigma, refine=ctx.cfg.refine,
                                            max_extent_ratio=ctx.cfg.max_extent_ratio)]
    boxes = []
    for fit in seeds:
        if fit is None:
            continue
        fit, _ = _widened(ctx, pts, fit, score(fit), part.noise)
        fit = rescore(fit, pts, part.noise)
        if fit.fit_rate >= ctx.cfg.min_fit_rate and \
                extent_ratio("box", fit.R[None], fit.t[None], fit.dims[None], pts, part.noise)[0] \
                <= ctx.cfg.max_uncovered_extent:
            boxes.append((score(fit), fit))
    if not boxes:
        return part
    best, box = min(boxes, key=lambda b: b[0])
    plain = score(own)
    own_score = min(plain, score(_widened(ctx, pts, own, plain, part.noise)[0]))
    if best >= own_score:
        return part
    nrm = ctx.cloud.normals[idx]
    if _facing(box, pts, nrm) < _facing(own, pts, nrm) - FACING_MARGIN:
        return part  # a plate behind a curved strip: its area is small, but the points do not face as its faces do
    try:
        prim, T = fit_to_object("box", box.R, box.t, box.dims)
    except PrimitiveError:
        return part
    rate = band_rate(box, pts, ctx.band)
    return replace(part, shape=Shape.BOX, dims=prim.dims, T_world_obj=T, fit_rate=box.fit_rate, rms=box.rms,
                   reason="", approximate=rate < ctx.cfg.min_fit_rate, band_rate=rate,
                   fits={**part.fits, "box": box})


def settled(cloud: Cloud, done: list, failed: list, cfg: IdentifyConfig) -> list | None:
    """The paper loop's leaves ``done`` with their band rates when nothing is left to
    decompose -- no cluster unidentified, every part explaining ``settle_rate`` of its
    points within the band -- else None."""
    if failed or not done:
        return None
    ctx = _context(cloud, np.random.default_rng(0), cfg)  # no draws: rates only
    out = [(_leaf_of(ctx, _local(cloud, p), _box_or_rotational(ctx, _local(cloud, p), p)), box)
           for p, box in done]
    return out if _settled(ctx, [p for p, _ in out]) else None


def keep_going(cloud: Cloud, done: list, failed: list, n_splits: int, rng: np.random.Generator,
               cfg: IdentifyConfig):
    """Robust continuation of the paper's loop: (identified leaves, unidentified leaves,
    splits) as :func:`~graspsim.perception.identify._hierarchy` returns them, with the
    clusters in ``failed`` decomposed further and over-split neighbours merged."""
    ctx = _context(cloud, rng, cfg)
    out, left = [], []
    for part, box in [*done, *failed]:
        idx = _local(cloud, part)
        parts = _solve(ctx, idx, 0, part)
        if len(parts) == 1 and parts[0].shape is part.shape:
            (out if part.shape is not Shape.UNIDENTIFIED else left).append((parts[0], box))
            continue
        for p in parts:
            if p.shape is Shape.UNIDENTIFIED:
                left.append((replace(p, T_world_obj=min_volume_box(cloud.points[_local(cloud, p)]).T_world_box.copy()),
                             None))
            else:
                out.append((p, None))
        n_splits += max(len(parts) - 1, 0)
    done = out
    return _merged(ctx, done), left, n_splits


def _merged(ctx: _Ctx, done: list) -> list:
    """Merge pairs of touching parts whose union one model explains as well."""
    parts = list(done)
    changed = True
    while changed and len(parts) > 1:
        changed = False
        for i in range(len(parts)):
            for j in range(i + 1, len(parts)):
                merged = _try_merge(ctx, parts[i][0], parts[j][0])
                if merged is not None:
                    parts = [p for k, p in enumerate(parts) if k not in (i, j)] + [(merged, None)]
                    changed = True
                    break
            if changed:
                break
    return parts


def _try_merge(ctx: _Ctx, a: PartResult, b: PartResult) -> PartResult | None:
    """The union of two touching parts as one part, when one model explains it within
    the band as well as the two did (within 1 %): a fresh identification of the union
    by the paper's rules (parts of one kind), or either part's own model refined on the
    union -- two halves of one body each fitted with the whole body's primitive (a
    cylinder split lengthwise) overlap, and the combined map drops every grasp of each
    as colliding with the other, while a fresh fit of the union may draw worse. The
    union is approximate only where a part was. Of those, the best-scoring, and only
    when it scores at least as well as the pair: band rates saturate for rough parts
    (E09's teddy: two blobs, each an approximate sphere, and one approximate cone over
    both explained as many points, but the cone's map had no grasp)."""
    ia, ib = _local(ctx.cloud, a), _local(ctx.cloud, b)
    pa, pb = ctx.cloud.points[ia], ctx.cloud.points[ib]
    gap = cKDTree(pa).query(pb, k=1, distance_upper_bound=3.0 * ctx.spacing)[0]
    if not np.isfinite(gap).any():
        return None  # not neighbours
    idx = np.concatenate([ia, ib])
    d = model_distance([_model(a)], pa) <= ctx.band, model_distance([_model(b)], pb) <= ctx.band
    pair = (d[0].sum() + d[1].sum()) / len(idx)
    cands = [_leaf(ctx, idx)] if a.shape is b.shape else []
    cands += [_refit(ctx, idx, p) for p in (a, b)]
    loose = a.approximate or b.approximate
    good = [u for u in cands if u is not None and u.shape is not Shape.UNIDENTIFIED and u.band_rate is not None
            and (loose or not u.approximate) and u.band_rate >= max(pair - 0.01, ctx.cfg.approx_fit_rate)]
    scored = [(_score(ctx, idx, [u]), -u.band_rate, k, u) for k, u in enumerate(good)]
    best = min(scored, key=lambda s: s[:3], default=None)
    if best is None or best[0] > _score(ctx, idx, [a, b]):
        return None  # the pair is the likelier decomposition: two parts, not one
    return best[3]


def _refit(ctx: _Ctx, idx: np.ndarray, part: PartResult) -> PartResult | None:
    """``part``'s model refined on the points ``idx`` (local indices) and the part it
    makes there (None: no model, or the refined one is no primitive)."""
    model = _model(part)
    if model is None:
        return None
    pts = ctx.cloud.points[idx]
    wide = fit_from(model.kind, pts, model.R, model.t, model.dims, sigma=ctx.band / ctx.cfg.band,
                    refine=ctx.cfg.refine, max_extent_ratio=ctx.cfg.max_extent_ratio)
    fit = rescore(wide, pts, part.noise)
    rate = band_rate(fit, pts, ctx.band)
    try:
        prim, T = fit_to_object(fit.kind, fit.R, fit.t, fit.dims)
    except PrimitiveError:
        return None
    return replace(part, dims=prim.dims, T_world_obj=T, fit_rate=fit.fit_rate, rms=fit.rms,
                   indices=ctx.cloud.kept[np.sort(idx)], fits={fit.kind: fit}, coverage={},
                   approximate=rate < ctx.cfg.min_fit_rate, band_rate=rate)
