"""One segment of a scene planned (:func:`~graspsim.planning.scene.plan_scene`): its
ranked grasps (:class:`SceneGrasp`) and its record (:class:`SegmentPlan`); settled
without planning when its identification failed or the previous frame's grasps stand
(:mod:`~graspsim.planning.scene_reuse`), else planned by the run-time planner against
the scene around it -- the segments side by side on the scene's worker processes
(:mod:`~graspsim.planning.scene_workers`; a segment's planning draws nothing at random,
so the result does not depend on where or in which order; a scene planned lazily
streams its batches, and a worker free before its batch ends starts the next batch's
segments ahead: :func:`plan_batches`), or in this process, in
segment order, when a plan could store a new FS map (later plans match against it) or
the database is a subclass with state of its own that a copy in a worker would not
share (:func:`copies_plan_alike`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from graspsim.geometry.table import TablePlane
from graspsim.maps.database import MapDatabase
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.match import MatchKind
from graspsim.maps.robust import executed_width
from graspsim.perception.identify import Identification
from graspsim.planning.planner import PlannerConfig, PlanResult, canonical_box, plan_stream
from graspsim.planning.scene_config import SPARSE_SHARE
from graspsim.planning.scene_reuse import nothing_new, reused_grasps
from graspsim.planning.scene_workers import cancelled, resident_database, stream_segments

if TYPE_CHECKING:  # the scene's settings (scene.py imports this module)
    from graspsim.planning.scene_config import SceneConfig

__all__ = ["SceneGrasp", "SegmentPlan", "builds_maps", "copies_plan_alike", "discount_sparse", "settled_plan",
           "plan_batches"]


@dataclass(frozen=True, eq=False)
class SceneGrasp:
    """segment: which segment it grasps; T_world_wrist (4, 4) in the cloud's frame;
    opening: the pad gap to open the jaws to before closing [m]; score: the robust score
    (expected success; 0: colliding with the scene at its pose); grade: the map's grade;
    clearance: distance of the gripper to the nearest observed point [m]; source: what it was
    planned from, the identified part's primitive (``"box"``, ``"cylinder"``, ...) or
    ``"features"`` (the segment's own points: ``PlannerConfig.features``); None: not known."""

    segment: int
    T_world_wrist: np.ndarray
    opening: float
    score: float
    grade: float
    clearance: float
    source: str | None = None

    def to_dict(self) -> dict:
        return {"segment": self.segment, "T_world_wrist": self.T_world_wrist.tolist(), "opening": self.opening,
                "score": self.score, "grade": self.grade, "clearance": self.clearance, "source": self.source}


@dataclass(frozen=True, eq=False)
class SegmentPlan:
    """One segment's planning: points (count), status ("planned": grasps found, "reused": the previous frame's,
    "no_grasp", "failed": identification could not run, with ``reason``, "deferred": not
    planned, another segment's grasp was good enough: ``SceneConfig.good_enough``), the primitives
    identified, grasps scored, seconds."""

    segment: int
    points: int
    status: str
    reason: str | None
    primitives: tuple[str, ...]
    scored: int
    seconds: float

    def to_dict(self) -> dict:
        return {"segment": self.segment, "points": self.points, "status": self.status, "reason": self.reason,
                "primitives": list(self.primitives), "scored": self.scored, "seconds": self.seconds}


def builds_maps(ident: Identification, db: MapDatabase, config: PlannerConfig) -> bool:
    """Whether planning identification ``ident`` could build and store an FS map (a part
    with no stored map within the scaling range, ``build_missing`` on): such a plan
    changes the database that later plans match against."""
    if not config.build_missing:
        return False
    return any(db.match(canonical_box(p.primitive(), p.T_world_obj)[0],
                        max_ratio=config.scaling.max_ratio).match is MatchKind.BUILD for p in ident.parts)


def _inner(seg: np.ndarray, cfg: SceneConfig) -> tuple[np.ndarray, np.ndarray]:
    """The box where new obstacles stop a segment's plan from being reused: its reach
    box (``scene._obstacles``) less twice the reuse tolerance."""
    m = cfg.reach - 2.0 * cfg.reuse_tol
    return seg.min(axis=0) - m, seg.max(axis=0) + m


def _plan_segment(seg: np.ndarray, k: int, ident: Identification, obstacles: np.ndarray | None, db,
                  cfg: SceneConfig, table: TablePlane, viewpoint: np.ndarray | None = None,
                  seen: np.ndarray | None = None) -> tuple[SegmentPlan, list[SceneGrasp]] | None:
    """Segment ``k`` (its thinned points ``seg`` (M, 3), identified as ``ident``) planned
    against ``obstacles`` (``seen``: which of them the camera saw, ``plan_stream``'s
    ``obstacles_seen``): its SegmentPlan and best ``keep`` grasps. It draws nothing at
    random: the same inputs give the same plan in any process, in any order. Its planning
    stops at ``enough`` grasps scoring > 0 -- in a lazily planned scene, once one of them
    (before :func:`discount_sparse`) also reaches ``good_enough`` -- or when its scoring
    budget (``per_segment`` per part) is spent. None: a plan started ahead that its caller
    gave up (:func:`~graspsim.planning.scene_workers.cancelled`)."""
    if cancelled():  # given up before it began
        return None
    t0 = time.perf_counter()
    pcfg = replace(cfg.planner, table=table, table_band=cfg.table_band, features=cfg.segment_features,
                   robust=replace(cfg.planner.robust, top=cfg.per_segment))
    batches: list[GraspabilityMap] = []
    prims = tuple(p.shape.value for p in ident.parts)
    stream = plan_stream(seg, db=db, rng=None, config=pcfg, obstacles=obstacles, obstacles_seen=seen,
                         identification=ident, viewpoint=viewpoint, scored_only=True)  # identified already: no draws
    good = scored = 0  # over the batches so far
    top = 0.0  # the best robust score so far
    aim = 0.0 if cfg.good_enough is None else cfg.good_enough  # lazily planned: one must reach it
    try:
        for item in stream:
            if cancelled():
                return None
            if isinstance(item, PlanResult):
                break
            batches.append(item.map)
            good += int(np.sum(item.map.robust > 0))
            scored += int(np.isfinite(item.map.robust).sum())
            top = max(top, float(np.nanmax(item.map.robust, initial=0.0)))
            if (good >= cfg.enough and top >= aim) or scored >= cfg.per_segment * len(ident.parts):
                break  # enough found (one reaching the aim), or the budget spent: the rest is unscored
    finally:
        stream.close()
    if not batches:
        return SegmentPlan(k, len(seg), "no_grasp", None, prims, 0, time.perf_counter() - t0), []
    gmap = GraspabilityMap.concat(batches, meta=batches[0].meta)
    gmap = gmap.select(np.isfinite(gmap.robust))  # the rows scored against the scene
    g = db.gripper
    gmap = discount_sparse(gmap, seg, g, cfg.sparse_between).top_k(cfg.keep)
    T = gmap.meta.placement.T_cloud_obj @ gmap.T_obj_wrist
    opening = g.pregrasp_opening(executed_width(gmap))
    score = np.nan_to_num(gmap.robust.astype(float), nan=0.0)
    # the part each grasp came from; part len(parts) is the segment's own features
    source = [prims[p] if p < len(prims) else "features" for p in np.asarray(gmap.part, int)]
    grasps = [SceneGrasp(k, T[i], float(opening[i]), float(score[i]), float(gmap.grade[i]),
                         float(gmap.clearance[i]), source[i]) for i in range(len(gmap))]
    return SegmentPlan(k, len(seg), "planned", None, prims, scored, time.perf_counter() - t0), grasps


def discount_sparse(gmap: GraspabilityMap, seg: np.ndarray, gripper, need: int) -> GraspabilityMap:
    """``gmap`` (a segment's scored grasps, placed in the scene) with the robust score of every
    grasp whose closing region holds fewer than ``need`` of the segment's points ``seg`` (M, 3) at
    the opening it executes (``SceneConfig.sparse_between``) multiplied by :data:`SPARSE_SHARE`;
    ``need`` 0: ``gmap`` itself."""
    if need <= 0 or not len(gmap):
        return gmap
    T = gmap.meta.placement.T_cloud_obj @ gmap.T_obj_wrist
    sparse = gripper.points_between(T, gripper.pregrasp_opening(executed_width(gmap)), seg) < need
    if not sparse.any():
        return gmap
    return replace(gmap, robust=np.where(sparse, gmap.robust * SPARSE_SHARE, gmap.robust).astype(gmap.robust.dtype))


def settled_plan(k: int, seg: np.ndarray, ident: Identification | None, why: str, old, obstacles, cfg: SceneConfig
                      ) -> tuple[SegmentPlan, list[SceneGrasp]] | None:
    """Segment ``k``'s plan and grasps when it needs no planning: its identification
    failed, or the previous frame's grasps stand (:mod:`~graspsim.planning.scene_reuse`);
    else None. In a lazily planned scene (``SceneConfig.good_enough``) remembered grasps
    that all score under it stand only while nothing near the segment is gone: their
    scores were taken against the neighbours of then, a lower bound once one of them has
    left (the object just picked), and the segment is planned again."""
    if ident is None:
        return SegmentPlan(k, len(seg), "failed", why, (), 0, 0.0), []
    if old is None or old.plan.status in ("failed", "deferred"):  # deferred: never planned
        return None
    box = _inner(seg, cfg)
    if not nothing_new(old.obstacles, obstacles, tol=cfg.reuse_tol, within=box, own=seg):
        return None
    g = reused_grasps(old, k)
    if not g:
        return None
    if (cfg.good_enough is not None and max(s.score for s in g) < cfg.good_enough
            and not nothing_new(obstacles, old.obstacles, tol=cfg.reuse_tol, within=box, own=seg)):
        return None  # under the aim, and an obstacle is gone: the remembered scores are lower bounds
    return replace(old.plan, segment=k, status="reused", seconds=0.0), g


def copies_plan_alike(db) -> bool:
    """Whether a copy of ``db`` in a scene worker plans a segment as ``db`` does, so long
    as no part needs an FS map built (:func:`builds_maps`): a plain
    :class:`~graspsim.maps.database.MapDatabase`, or a subclass that says so with a true
    class attribute ``copies_plan_alike`` (its own state -- e.g. maps it built in memory --
    serves only parts that need a map built, and those are planned in this process). Any
    other subclass may keep state a copy would not share: planned in this process."""
    return type(db) is MapDatabase or getattr(type(db), "copies_plan_alike", False) is True


def plan_batches(batches: list[list[tuple]], db, cfg: SceneConfig
                 ) -> Iterator[list[tuple[SegmentPlan, list[SceneGrasp]]]]:
    """:func:`_plan_segment` of every task of each batch, yielded batch after batch (see
    :func:`~graspsim.planning.scene_workers.stream_segments`: a worker free before its
    batch ends starts the next batch's tasks; closing the generator gives those up). A
    batch is planned on the scene's worker processes unless a plan could build (and
    store) an FS map -- then in this process, in segment order, as each plan matches
    against the maps stored before it, and no later batch starts before it -- or the
    database's copy in a worker might plan otherwise (:func:`copies_plan_alike`): in this
    process too."""
    alike = copies_plan_alike(db)
    # the longest plans first: parts (each streams its own maps), then points
    groups = [(tasks, [len(t[2].parts) * 1e6 + len(t[0]) for t in tasks],
               alike and not any(builds_maps(t[2], db, cfg.planner) for t in tasks)) for tasks in batches]
    return stream_segments(_plan_segment_there, groups, cfg.workers)


def _plan_segment_there(seg, k, ident, obstacles, db, *args):
    """:func:`_plan_segment` with the worker's own copy of the map database (its loaded maps kept)."""
    return _plan_segment(seg, k, ident, obstacles, resident_database(db), *args)
