"""Scene perception: a table with several objects seen as one cloud -> ranked grasps.

    scene cloud -> table plane (MLESAC, :mod:`~graspsim.perception.plane`) -> the points
    above it, thinned to a voxel grid -> objects by Euclidean clustering
    (:mod:`~graspsim.perception.segment`) -> every segment identified -> every segment
    (with ``SceneConfig.good_enough``: the highest first, until a grasp scores that well)
    planned by the run-time planner (stored/scaled/combined maps, the table as its
    ``TablePlane``) with the robust score computed against the WHOLE scene near it, not
    the segment's points alone -> one ranking of every segment's best grasps

The whole scene is the observed points of the other segments plus surface samples of
their identified primitives (one camera sees a neighbour's front; the primitive stands
for its back; a cluster left unidentified stands as its bounding box down to the
table), and the table as a plane. A grasp whose fingers would close on a neighbour
collides at its nominal pose, so its robust score is 0 and it ranks last.
``SceneConfig(neighbours=False)`` scores each segment against its own points only (the
ablation). :func:`graspsim.planning.planner.plan_stream` streams best-first; planning of a
segment stops once ``enough`` grasps with a positive robust score are found (planned
lazily, ``good_enough``: and one of them reaches it) or
``per_segment`` grasps per part are scored (later batches would not be scored), and
a part whose ``per_segment`` are scored yields to the next (``scored_only``: its
unscored batches are not made). That budget goes to grasps whose gripper holds no
point of the scene at their pose (``PlannerConfig.clear_first``): in a crowded pile a
lying bottle's best-graded grasps can all close on a neighbour, and the clear ones lie
further down the grade order.

Frames: the cloud's frame is called the world here (``T_world_wrist``); a cloud in the
camera's frame gives poses in the camera's frame.
"""

from __future__ import annotations

import time
from contextlib import closing
from dataclasses import dataclass, replace

import numpy as np

from graspsim.errors import InvalidParameterError, PointCloudError
from graspsim.geometry.table import TablePlane
from graspsim.perception.cluster import other_models
from graspsim.perception.identify import Identification
from graspsim.perception.mvbb import min_volume_box
from graspsim.perception.plane import PlaneFit, fit_table
from graspsim.perception.prepare import as_coordinates, check_extent, voxel_keep
from graspsim.perception.segment import cluster_radius, euclidean_clusters, gap_link
from graspsim.planning.scene_config import (
    LAZY_BATCH,
    MAX_SCENE_EXTENT,
    SCENE_BYTES_PER_POINT,
    SHADOW_ALONG,
    SHADOW_FINGER_SHARE,
    SceneConfig,
)
from graspsim.planning.scene_reuse import SegmentMemory, find_previous
from graspsim.planning.scene_segments import SceneGrasp, SegmentPlan, plan_batches, settled_plan
from graspsim.planning.scene_workers import identify_segments, start_workers
from graspsim.primitives import Box
from graspsim.primitives.base import MIN_DIM

__all__ = ["ScenePerception", "SceneGrasp", "SegmentPlan", "ScenePlan", "perceive_scene", "plan_scene",
           "shadow_step", "start_workers"]

@dataclass(frozen=True, eq=False)
class ScenePerception:
    """plane: the table's fit; labels (N,) per input point: segment id >= 0, -1 table,
    below it, too high, non-finite, thinned away or noise; points (M, 3) and
    indices (M,) into the input: the thinned points above the table; segment (M,) their
    labels; radius [m]: the clustering radius used; timing [s]."""

    plane: PlaneFit
    labels: np.ndarray
    points: np.ndarray
    indices: np.ndarray
    segment: np.ndarray
    radius: float
    timing: dict

    @property
    def n_segments(self) -> int:
        return int(self.segment.max()) + 1 if len(self.segment) and self.segment.max() >= 0 else 0

    def segment_points(self, k: int) -> np.ndarray:
        return self.points[self.segment == k]


@dataclass(frozen=True, eq=False)
class ScenePlan:
    """perception; table: the fitted plane as the planner used it; segments:
    per-segment planning; grasps: every segment's best ``keep`` grasps, best first
    (score, then grade); timing [s]: ``table``, ``segment``, ``identify`` (every
    segment), ``plan`` (maps and scores) and ``total``; memory: what the next frame
    may reuse (``plan_scene(previous=...)``)."""

    perception: ScenePerception
    table: TablePlane
    segments: tuple[SegmentPlan, ...]
    grasps: tuple[SceneGrasp, ...]
    timing: dict
    memory: tuple[SegmentMemory, ...] = ()

    @property
    def best(self) -> SceneGrasp | None:
        """The best grasp of the scene with a robust score > 0, or None."""
        return self.grasps[0] if self.grasps and self.grasps[0].score > 0 else None

    def summary(self) -> dict:
        return {"table": self.perception.plane.to_dict(), "segments": [s.to_dict() for s in self.segments],
                "radius": self.perception.radius, "grasps": len(self.grasps),
                "best": None if self.best is None else self.best.to_dict(), "timing": self.timing}


def _check_scene(points) -> tuple[np.ndarray, np.ndarray]:
    pts = as_coordinates(points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise PointCloudError(f"a scene cloud must be an (N, 3) array, got shape {pts.shape}")
    _check_memory(len(pts))
    finite = np.flatnonzero(np.all(np.isfinite(pts), axis=1))
    if len(finite) < 100:
        raise PointCloudError(f"the scene cloud has {len(finite)} finite points; a table with objects needs "
                              "at least 100 (is the camera looking at the table?)")
    check_extent(pts[finite], max_extent=MAX_SCENE_EXTENT, what="a table-top scene")
    return pts, finite


def _check_memory(n: int) -> None:
    """Refuse a cloud whose planning would need more memory than the budget
    (:func:`~graspsim.maps.preflight.memory_budget`), before any work."""
    from graspsim.errors import BudgetExceededError
    from graspsim.maps.preflight import BUDGET_ENV, memory_budget

    need, budget = n * SCENE_BYTES_PER_POINT, memory_budget()
    if need > budget:
        raise BudgetExceededError(
            f"a scene cloud of {n} points needs about {need / 2**30:.1f} GiB to plan, over the memory budget of "
            f"{budget / 2**30:.1f} GiB (${BUDGET_ENV}); crop it to the table and what stands on it, or "
            "voxel-downsample it (planning thins it to a 3 mm grid anyway)")


def perceive_scene(points: np.ndarray, rng: np.random.Generator, config: SceneConfig | None = None, *,
                   labels: np.ndarray | None = None, viewpoint=None) -> ScenePerception:
    """The table and the objects of a scene cloud (N, 3) [m] (NaN rows: no depth).
    ``labels`` (N,): given segment ids (>= 0 objects, < 0 none; e.g. the simulator's
    ground truth) replace the clustering. ``viewpoint`` (3,): the camera that saw the
    cloud (one view): surface normals point towards it, and with
    ``SceneConfig.crease_angle`` the clustering parts touching objects along the
    concave creases between them (:func:`~graspsim.perception.segment.euclidean_clusters`)."""
    from graspsim.seeding import check_rng

    check_rng(rng)
    cfg = config or SceneConfig()
    t0 = time.perf_counter()
    pts, finite = _check_scene(points)
    plane = fit_table(pts[finite], rng, sigma=cfg.plane_sigma, repetitions=cfg.plane_repetitions,
                      up=None if cfg.up is None else np.asarray(cfg.up, float), confidence=cfg.plane_confidence)
    t1 = time.perf_counter()
    h = plane.heights(pts[finite])
    above = finite[(h > cfg.table_band) & (h < cfg.max_height)]
    idx = above[voxel_keep(pts[above], cfg.voxel)] if len(above) else above
    sub = pts[idx]
    if labels is not None:
        seg, radius = _given_segments(labels, idx, len(pts), cfg.min_points), float("nan")
    else:
        radius = cfg.radius if cfg.radius is not None else cluster_radius(sub, max_radius=cfg.max_radius)
        crease = None if viewpoint is None or cfg.min_gap is not None else cfg.crease_angle  # apart: no creases
        seg = euclidean_clusters(sub, radius=radius, min_points=cfg.min_points, link=gap_link(cfg.min_gap),
                                 viewpoint=viewpoint, crease_angle=crease)
    full = np.full(len(pts), -1, np.int64)
    full[idx] = seg
    t2 = time.perf_counter()
    return ScenePerception(replace(plane, inliers=_spread(plane.inliers, finite, len(pts))), full, sub, idx, seg,
                           radius, {"table": t1 - t0, "segment": t2 - t1})


def _given_segments(labels, idx: np.ndarray, n: int, min_points: int) -> np.ndarray:
    """Segment ids 0, 1, ... (ascending given id) of the thinned points from given
    labels (n,) (< 0: none); ids with fewer than ``min_points`` thinned points: -1."""
    given = np.asarray(labels).reshape(-1)
    if given.shape != (n,):
        raise InvalidParameterError(f"labels must have one entry per point ({n}), got shape {given.shape}")
    g = given[idx].astype(np.int64)
    ids, counts = np.unique(g[g >= 0], return_counts=True)
    ids = ids[counts >= min_points]
    keep = np.isin(g, ids)
    seg = np.full(len(g), -1, np.int64)
    seg[keep] = np.searchsorted(ids, g[keep])
    return seg


def _spread(mask: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n, bool)
    out[rows] = mask
    return out


def _box_samples(points: np.ndarray, plane: PlaneFit, step: float) -> np.ndarray:
    """Surface samples (M, 3) of the smallest box around ``points`` (N, 3) and their
    footprint on the table: the room an object the planner could not identify takes."""
    foot = points - np.outer(plane.heights(points), plane.normal)
    box = min_volume_box(np.concatenate([points, foot]))
    ext = np.maximum(box.extents, 2.0 * MIN_DIM)
    s = Box(*ext).surface_samples(min(step, 0.5 * float(ext.min()))).points
    return s @ box.axes.T + box.center


def _solid_samples(seg: np.ndarray, ident: Identification | None, plane: PlaneFit, step: float) -> np.ndarray:
    """Surface samples (M, 3) [m, cloud frame] of what segment points ``seg`` stand
    for: its identified primitives, and a box around each cluster it left unidentified
    (the whole segment when identification could not run) -- the sides of a neighbour
    the camera does not see."""
    if ident is None:
        return _box_samples(seg, plane, step)
    out = [np.zeros((0, 3))]
    for part in ident.parts:
        prim = part.primitive()
        s = prim.surface_samples(min(step, 0.5 * prim.size_scale)).points
        out.append(s @ part.T_world_obj[:3, :3].T + part.T_world_obj[:3, 3])
    out += [_box_samples(seg[p.indices], plane, step) for p in ident.unidentified if p.n_points >= 4]
    return np.concatenate(out)


def _shadow_samples(seg: np.ndarray, plane: PlaneFit, viewpoint: np.ndarray, depth: float,
                    step: float, along: float | None = None) -> np.ndarray:
    """Samples (M, 3) [m, cloud frame] of the space up to ``depth`` behind segment points
    ``seg`` along the camera's rays from ``viewpoint``: the points thinned to a ``step`` grid,
    every ``along`` (None: ``step``; :func:`shadow_step`) along each ray, above the table:
    where the object the camera saw goes on, at the least depth its front tells nothing
    against."""
    if len(seg) == 0 or depth <= 0:
        return np.zeros((0, 3))
    along = step if along is None else along
    _, first = np.unique(np.floor(seg / step).astype(np.int64), axis=0, return_index=True)
    p = seg[np.sort(first)]
    u = p - viewpoint
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    t = np.arange(1, int(np.floor(depth / along + 1e-9)) + 1) * along
    out = (p[:, None, :] + t[None, :, None] * u[:, None, :]).reshape(-1, 3)
    return out[plane.heights(out) > 0.0]


def shadow_step(step: float, gripper) -> float:
    """[m] The spacing of a shadow's samples along the camera's rays (:func:`_shadow_samples`):
    :data:`SHADOW_ALONG` times the grid ``step`` across them, less where the ``gripper``'s
    finger is thinner (``SHADOW_FINGER_SHARE`` of its thinnest side: a finger that crosses the
    rays inside a shadow holds a sample), never under ``step``."""
    return max(step, min(SHADOW_ALONG * step, SHADOW_FINGER_SHARE * float(min(gripper.finger_size))))


def _obstacles(per: ScenePerception, k: int, solids: list[np.ndarray] | None, reach: float,
               felt: np.ndarray | None = None, shadows: list[np.ndarray] | None = None
               ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """What the gripper must clear besides segment ``k``, within ``reach`` of its bounding
    box: the scene's points above the table outside it (noise points included: they were
    seen) and the surface samples of the other segments' identified primitives (both
    only with ``solids``: ``SceneConfig.neighbours``), the other segments' ``shadows``
    (:func:`_shadow_samples`; ``SceneConfig.shadow_depth``), and the ``felt`` points (see
    :func:`plan_scene`); and which of them the camera saw (bool, the scene's points: the
    planner's depth image of what was seen holds these alone, ``plan_stream``'s
    ``obstacles_seen``). (None, None): nothing to clear."""
    own = per.segment == k
    lo, hi = per.points[own].min(axis=0) - reach, per.points[own].max(axis=0) + reach
    got = [] if solids is None else [per.points[~own], *(s for j, s in enumerate(solids) if j != k)]
    if shadows is not None:
        got += [s for j, s in enumerate(shadows) if j != k]
    if felt is not None and len(felt):
        got.append(felt)
    if not got:
        return None, None
    pts = np.concatenate(got)
    seen = np.zeros(len(pts), bool)
    if solids is not None:
        seen[:int(np.count_nonzero(~own))] = True
    near = np.all((pts >= lo) & (pts <= hi), axis=1)
    return pts[near], seen[near]


def _check_felt(felt) -> np.ndarray | None:
    """``plan_scene``'s ``felt`` as a finite (K, 3) float array (None or no rows: None), or
    an :class:`InvalidParameterError` naming what is valid."""
    if felt is None:
        return None
    try:
        F = np.asarray(felt, float)
    except (TypeError, ValueError):
        F = None
    if F is None or F.ndim != 2 or F.shape[1] != 3 or not np.all(np.isfinite(F)):
        raise InvalidParameterError(f"felt must be finite points (K, 3) [m, the cloud's frame], got "
                                    f"{getattr(F, 'shape', type(felt).__name__)}")
    return F if len(F) else None


def _identify_new(segs: list[np.ndarray], olds: list, rng: np.random.Generator, cfg: SceneConfig) -> list:
    """(identification or None, why) of every segment: a reused one's, else identified,
    segment k drawing from the k-th generator spawned from ``rng``."""
    rngs = rng.spawn(len(segs))
    new = [k for k, o in enumerate(olds) if o is None]
    made = dict(zip(new, identify_segments([segs[k] for k in new], [rngs[k] for k in new], cfg.planner.identify,
                                           cfg.workers)))
    return [(o.ident, o.why) if o is not None else made[k] for k, o in enumerate(olds)]


def _best(plan: tuple) -> float:
    """The best robust score of a segment's (SegmentPlan, grasps); 0 with none."""
    return max((g.score for g in plan[1]), default=0.0)


def _other_identifications(ident: Identification, config) -> list[Identification]:
    """``ident`` with its parts as the other models their clusters fitted, best first
    (:func:`~graspsim.perception.cluster.other_models`): the r-th has each part as its r-th
    other model (a part with fewer as it is); none when no part has another."""
    alts = [other_models(p, config) for p in ident.parts]
    return [replace(ident, parts=tuple(a[r] if r < len(a) else p for a, p in zip(alts, ident.parts)))
            for r in range(max(map(len, alts), default=0))]


def _fallback(done: list, segs: list, idents: list, obstacles, seen, db, cfg: SceneConfig, table,
              viewpoint) -> tuple[list, list]:
    """(``done``, ``idents``) with every identified segment that holds no grasp scoring > 0
    planned again (``SceneConfig.feature_grasps`` ``"fallback"``: a frame planned afresh --
    no ``previous`` frame: a frame planned with one reuses its identifications and plans,
    and a clutter-removal loop plans it afresh before it gives up -- whose parts give no
    grasp at all, which would end the loop with objects left): with grasps on its cloud's
    own features added, and so with each of the other models its parts' clusters fitted
    (:func:`_other_identifications`: a brick the rule base named a sphere wider than it is
    planned as the box it fits as well), all side by side. A segment keeps the plan whose
    best grasp scores highest -- the planner's own estimate of a grasp's success, whatever
    model it was planned on -- and that plan's identification (which a next frame reuses);
    on a tie the first: its own identification, then the other models best fit first. The
    others as they were."""
    again = [k for k, d in enumerate(done) if idents[k][0] is not None and _best(d) <= 0.0]
    if not again:
        return done, idents
    fcfg = replace(cfg, feature_grasps="always", good_enough=None)
    tried = [(k, ident) for k in again
             for ident in [idents[k][0], *_other_identifications(idents[k][0], cfg.planner.identify)]]
    with closing(plan_batches([[(segs[k], k, ident, obstacles[k], db, fcfg, table, viewpoint, seen[k])
                                for k, ident in tried]], db, fcfg)) as stream:
        plans = next(stream)
    out, ids = list(done), list(idents)
    for (k, ident), d in zip(tried, plans):
        if ident is idents[k][0] or _best(d) > _best(out[k]):
            out[k], ids[k] = d, (ident, idents[k][1])
    return out, ids


def plan_scene(points: np.ndarray, *, db, rng: np.random.Generator, config: SceneConfig | None = None,
               labels: np.ndarray | None = None, previous: ScenePlan | None = None,
               viewpoint: np.ndarray | None = None, felt: np.ndarray | None = None) -> ScenePlan:
    """Ranked grasps for every object of a scene cloud (N, 3) [m] (see the module
    docstring); ``db``: the :class:`~graspsim.maps.database.MapDatabase`; ``labels``:
    see :func:`perceive_scene`; ``previous``: the plan of the previous frame of the same
    scene (same frame of reference): segments that did not change keep their
    identification, and their grasps when no new obstacle came near them
    (:mod:`~graspsim.planning.scene_reuse`; status ``"reused"``); ``viewpoint`` (3,):
    where the camera that saw the cloud was (cloud frame): finger volume in the space
    behind what it saw -- an object's far side, what lies under a neighbour -- scales the
    robust score down (:mod:`~graspsim.maps.occlusion`), and where objects may touch (no
    ``min_gap``) the space up to ``SceneConfig.shadow_depth`` behind each other segment's seen
    points is an obstacle (:func:`_shadow_samples`); None: neither. ``felt``
    (K, 3) [m, cloud frame]: where the gripper met something the camera did not see (a
    grasp that started in collision with an object:
    :func:`~graspsim.maps.occlusion.felt_volume`); every segment's grasps keep clear of
    these points as of its neighbours' (a segment they come near is planned again, not
    reused); None: none."""
    from graspsim.maps.occlusion import check_viewpoint
    from graspsim.seeding import check_rng

    cfg = config or SceneConfig()
    t0 = time.perf_counter()
    viewpoint = check_viewpoint(viewpoint)  # before the work: a bad one fails now, in one line
    felt = _check_felt(felt)
    check_rng(rng)
    per = perceive_scene(points, rng, cfg, labels=labels, viewpoint=viewpoint)
    table = per.plane.table(cfg.clearance)
    t1 = time.perf_counter()
    segs = [per.segment_points(k) for k in range(per.n_segments)]
    before = previous.memory if previous is not None else ()
    olds = [find_previous(seg, before, tol=cfg.reuse_tol) for seg in segs]
    idents = _identify_new(segs, olds, rng, cfg)
    solids = [o.solids if o is not None and o.solids is not None else _solid_samples(seg, i, per.plane, cfg.solid_step)
              for seg, (i, _), o in zip(segs, idents, olds)] if cfg.neighbours else []
    t2 = time.perf_counter()
    along = shadow_step(cfg.solid_step, db.gripper)
    shadows = [_shadow_samples(seg, per.plane, viewpoint, cfg.shadow_depth, cfg.solid_step, along) for seg in segs] \
        if cfg.neighbours and cfg.shadow_depth > 0 and cfg.min_gap is None and viewpoint is not None else None
    obstacles, seen = zip(*(_obstacles(per, k, solids if cfg.neighbours else None, cfg.reach, felt, shadows)
                            for k in range(len(segs)))) if segs else ((), ())
    done = [settled_plan(k, segs[k], ident, why, olds[k], obstacles[k], cfg)
            for k, (ident, why) in enumerate(idents)]
    todo = [k for k, d in enumerate(done) if d is None]
    if cfg.good_enough is None:
        batches = [todo]
    else:  # highest first, LAZY_BATCH at a time, until a grasp scores good_enough
        top = {k: float(per.plane.heights(segs[k]).max()) for k in todo}
        todo.sort(key=lambda k: (-top[k], k))
        batches = [todo[i:i + LAZY_BATCH] for i in range(0, len(todo), LAZY_BATCH)]
    best = max((g.score for d in done if d is not None for g in d[1]), default=0.0)
    stream = plan_batches([[(segs[k], k, idents[k][0], obstacles[k], db, cfg, table, viewpoint, seen[k]) for k in batch]
                           for batch in batches], db, cfg)
    with closing(stream):  # stopped early: the next batch's plans started ahead are given up
        for b, batch in enumerate(batches):
            if cfg.good_enough is not None and best >= cfg.good_enough:
                for k in (k for rest in batches[b:] for k in rest):
                    done[k] = (SegmentPlan(k, len(segs[k]), "deferred", None,
                                           tuple(p.shape.value for p in idents[k][0].parts), 0, 0.0), [])
                break
            for k, d in zip(batch, next(stream)):
                done[k] = d
                best = max([best, *(g.score for g in d[1])])
    if best <= 0.0 and cfg.feature_grasps == "fallback" and cfg.segment_features is None and previous is None:
        done, idents = _fallback(done, segs, idents, obstacles, seen, db, cfg, table, viewpoint)
    plans, grasps, memory = [], [], []
    for k, (p, g) in enumerate(done):
        plans.append(p)
        grasps += g
        memory.append(SegmentMemory(segs[k], idents[k][0], idents[k][1], solids[k] if solids else None,
                                    obstacles[k], p, tuple(g)))
    grasps.sort(key=lambda s: (-s.score, -s.grade, s.segment))
    now = time.perf_counter()
    timing = {**per.timing, "identify": t2 - t1, "plan": now - t2, "total": now - t0}
    return ScenePlan(per, table, tuple(plans), tuple(grasps), timing, tuple(memory))
