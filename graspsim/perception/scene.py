"""Scene perception: a table with several objects seen as one cloud -> ranked grasps.

    scene cloud -> table plane (MLESAC, :mod:`~graspsim.perception.plane`) -> the points
    above it, thinned to a voxel grid -> objects by Euclidean clustering
    (:mod:`~graspsim.perception.segment`) -> every segment identified -> every segment
    planned by the run-time planner (stored/scaled/combined maps, the table as its
    ``TablePlane``) with the robust score computed against the WHOLE scene near it, not
    the segment's points alone -> one ranking of every segment's best grasps

The whole scene is the observed points of the other segments plus surface samples of
their identified primitives (one camera sees a neighbour's front; the primitive stands
for its back; a cluster left unidentified stands as its bounding box down to the
table), and the table as a plane. A grasp whose fingers would close on a neighbour
collides at its nominal pose, so its robust score is 0 and it ranks last.
``SceneConfig(neighbours=False)`` scores each segment against its own points only (the
ablation). :func:`graspsim.planner.plan_stream` streams best-first; planning of a
segment stops once ``enough`` grasps with a positive robust score are found or
``per_segment`` grasps per part are scored (later batches would not be scored), and
a part whose ``per_segment`` are scored yields to the next (``scored_only``: its
unscored batches are not made).

Frames: the cloud's frame is called the world here (``T_world_wrist``); a cloud in the
camera's frame gives poses in the camera's frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from graspsim.errors import InvalidParameterError, PointCloudError
from graspsim.maps.table import TablePlane
from graspsim.perception.identify import Identification
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.mvbb import min_volume_box
from graspsim.perception.plane import PlaneFit, fit_table
from graspsim.perception.prepare import as_coordinates, check_extent, voxel_keep
from graspsim.perception.scene_reuse import SegmentMemory, find_previous
from graspsim.perception.scene_segments import SceneGrasp, SegmentPlan, plan_segments, settled_plan
from graspsim.perception.scene_workers import identify_segments, scene_workers, start_workers
from graspsim.perception.segment import cluster_radius, euclidean_clusters, gap_link
from graspsim.planner import PlannerConfig
from graspsim.primitives import Box
from graspsim.primitives.base import MIN_DIM

__all__ = ["SceneConfig", "ScenePerception", "SceneGrasp", "SegmentPlan", "ScenePlan", "perceive_scene",
           "plan_scene", "start_workers", "budget_fields", "MAX_SCENE_EXTENT", "SCENE_FIT_POINTS",
           "SCENE_COLLISION_TOLERANCE"]

#: Widest plausible table-top scene [m]; wider clouds are taken for millimetres or centimetres.
MAX_SCENE_EXTENT = 10.0


#: Memory planning a scene takes per cloud point [bytes], with a margin: ``graspsim
#: plan-scene``'s peak resident memory grew by about 110 bytes a point from an E10 packed
#: frame (0.14 M points) to the same frame tiled ten times (1.4 M).
SCENE_BYTES_PER_POINT = 160

#: Points a scene segment is identified on at most (``IdentifyConfig.fit_points`` of the
#: scene's default planner): segments are 3 mm grids already, the largest thinned further.
SCENE_FIT_POINTS = 1000
#: [m] the scene planner's run-time collision tolerance (:attr:`PlannerConfig.collision_tolerance
#: <graspsim.planner.PlannerConfig.collision_tolerance>`): a grasp adapted to a segment's
#: identified primitive is rejected when it comes this close to touching it. The primitive
#: is fitted to a depth camera's points -- the default sensor's noise is 1.8-2.8 mm at the
#: camera's 0.6-0.8 m, its depth step 1 mm -- so it is not known to the FS maps' 0.25 mm;
#: checking to 1 mm takes about a sixteenth of their finest collision samples.
SCENE_COLLISION_TOLERANCE = 0.001


def _scene_planner() -> PlannerConfig:
    return PlannerConfig(identify=IdentifyConfig(fit_points=SCENE_FIT_POINTS),
                         collision_tolerance=SCENE_COLLISION_TOLERANCE)


@dataclass(frozen=True)
class SceneConfig:
    """planner: the per-segment planner settings (its ``table`` is replaced by the
    fitted plane; by default robust identification on at most :data:`SCENE_FIT_POINTS`
    points of a segment, ``IdentifyConfig(fit_points=None)`` for all of them).
    plane_sigma [m], plane_repetitions, plane_confidence: the table fit (its planes are
    scored until the RANSAC bound at this confidence is met; None: all of them, see
    :func:`~graspsim.perception.plane.fit_table`); table_band [m]:
    points less than this above the table belong to it; max_height [m]: points higher
    above it are ignored; voxel [m]: the grid the points above the table are thinned
    to; radius [m]: the clustering radius (None: from the spacing, at most max_radius);
    min_gap [m]: the least gap the user knows parts any two objects (objects placed
    apart; None: they may touch): clusters closer than
    :data:`~graspsim.perception.segment.GAP_LINK` x min_gap are one object; crease_angle [deg]:
    where objects may touch (no ``min_gap``) and the camera's viewpoint is known, the
    points along concave creases sharper than this are taken out before clustering, so
    touching objects come apart (None: off; :mod:`~graspsim.perception.segment`); min_points: smallest
    object (points after thinning); neighbours: score grasps
    against the whole scene (False: the segment's points only); reach [m]: scene points
    farther than this from a segment's bounding box cannot touch the gripper and are
    left out of its check; solid_step [m]: spacing of the surface samples of the
    neighbours' identified primitives added to the check (their unseen sides);
    per_segment: grasps scored per part of a segment at most; enough: planning of a segment
    stops at this many grasps with a robust score > 0; keep: grasps per segment in the
    scene ranking; clearance [m]: the gripper's clearance above the table; reuse_tol
    [m]: how far points may move between frames for a segment to count as unchanged
    (``plan_scene(previous=...)``); up: the
    table's upward direction if known (cloud frame); workers: processes the segments are
    identified on (None: one per core; 1: in this process; see
    :mod:`~graspsim.perception.scene_workers` -- the result does not depend on it)."""

    planner: PlannerConfig = field(default_factory=_scene_planner)
    plane_sigma: float = 0.002
    plane_repetitions: int = 200
    plane_confidence: float | None = 0.999
    table_band: float = 0.006
    max_height: float = 0.5
    voxel: float = 0.003
    radius: float | None = None
    max_radius: float = 0.007
    min_gap: float | None = None
    crease_angle: float | None = 15.0
    min_points: int = 40
    neighbours: bool = True
    reach: float = 0.15
    solid_step: float = 0.004
    per_segment: int = 200
    enough: int = 32
    keep: int = 10
    clearance: float = 0.002
    reuse_tol: float = 0.005
    up: tuple[float, float, float] | None = (0.0, 0.0, 1.0)
    workers: int | None = None

    def __post_init__(self) -> None:
        for k in ("plane_sigma", "table_band", "max_height", "voxel", "max_radius", "reach", "solid_step",
                  "reuse_tol"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise InvalidParameterError(f"SceneConfig.{k} must be > 0 m, got {v!r}")
        if self.crease_angle is not None and not (isinstance(self.crease_angle, (int, float))
                                                  and 0 < self.crease_angle < 180):
            raise InvalidParameterError(f"SceneConfig.crease_angle must be in (0, 180) deg or None, "
                                        f"got {self.crease_angle!r}")
        if self.radius is not None and not (np.isfinite(self.radius) and self.radius > 0):
            raise InvalidParameterError(f"SceneConfig.radius must be > 0 m or None, got {self.radius!r}")
        try:
            gap_link(self.min_gap)
        except InvalidParameterError as err:
            raise InvalidParameterError(f"SceneConfig.{err}") from None
        for k in ("plane_repetitions", "min_points", "per_segment", "enough", "keep"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise InvalidParameterError(f"SceneConfig.{k} must be an integer >= 1, got {v!r}")
        scene_workers(self.workers)  # validates it
        if self.plane_confidence is not None and not 0 < self.plane_confidence < 1:
            raise InvalidParameterError(f"SceneConfig.plane_confidence must be in (0, 1) or None, "
                                        f"got {self.plane_confidence!r}")
        if not isinstance(self.planner, PlannerConfig) or self.planner.rank != "robust":
            raise InvalidParameterError("SceneConfig.planner must be a PlannerConfig ranking by the robust score "
                                        f"(the scene check is part of it), got {self.planner!r}")

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "planner"}

    @property
    def budget(self) -> str:
        """The planning budget as its label ``"ENOUGH:PER_SEGMENT"`` (read back by :func:`budget_fields`)."""
        return f"{self.enough}:{self.per_segment}"


def budget_fields(label: str) -> dict[str, int]:
    """A segment's planning budget ``"ENOUGH:PER_SEGMENT"`` as the :class:`SceneConfig`
    fields it sets (``enough``, ``per_segment``); "" for none (the defaults, E10's).
    Smaller budgets plan a new frame with less CPU and choose from fewer grasps
    (``experiments/study_scene_budget.py`` measures both)."""
    if label == "":
        return {}
    try:
        enough, per = (int(v) for v in str(label).split(":"))
    except ValueError:
        raise InvalidParameterError(f"a planning budget is ENOUGH:PER_SEGMENT, two whole numbers (e.g. 8:100), "
                                    f"got {label!r}") from None
    if enough < 1 or per < 1:
        raise InvalidParameterError(f"a planning budget's numbers must be >= 1, got {label!r}")
    return {"enough": enough, "per_segment": per}


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


def _obstacles(per: ScenePerception, k: int, solids: list[np.ndarray], reach: float) -> np.ndarray:
    """What the gripper must clear besides segment ``k``: the scene's points above the
    table outside it (noise points included: they were seen) and the surface samples
    of the other segments' identified primitives, within ``reach`` of its bounding box."""
    own = per.segment == k
    lo, hi = per.points[own].min(axis=0) - reach, per.points[own].max(axis=0) + reach
    pts = np.concatenate([per.points[~own], *(s for j, s in enumerate(solids) if j != k)])
    return pts[np.all((pts >= lo) & (pts <= hi), axis=1)]


def _identify_new(segs: list[np.ndarray], olds: list, rng: np.random.Generator, cfg: SceneConfig) -> list:
    """(identification or None, why) of every segment: a reused one's, else identified,
    segment k drawing from the k-th generator spawned from ``rng``."""
    rngs = rng.spawn(len(segs))
    new = [k for k, o in enumerate(olds) if o is None]
    made = dict(zip(new, identify_segments([segs[k] for k in new], [rngs[k] for k in new], cfg.planner.identify,
                                           cfg.workers)))
    return [(o.ident, o.why) if o is not None else made[k] for k, o in enumerate(olds)]


def plan_scene(points: np.ndarray, *, db, rng: np.random.Generator, config: SceneConfig | None = None,
               labels: np.ndarray | None = None, previous: ScenePlan | None = None,
               viewpoint: np.ndarray | None = None) -> ScenePlan:
    """Ranked grasps for every object of a scene cloud (N, 3) [m] (see the module
    docstring); ``db``: the :class:`~graspsim.maps.database.MapDatabase`; ``labels``:
    see :func:`perceive_scene`; ``previous``: the plan of the previous frame of the same
    scene (same frame of reference): segments that did not change keep their
    identification, and their grasps when no new obstacle came near them
    (:mod:`~graspsim.perception.scene_reuse`; status ``"reused"``); ``viewpoint`` (3,):
    where the camera that saw the cloud was (cloud frame): finger volume in the space
    behind what it saw -- an object's far side, what lies under a neighbour -- scales the
    robust score down (:mod:`~graspsim.maps.occlusion`); None: no such term."""
    cfg = config or SceneConfig()
    t0 = time.perf_counter()
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
    obstacles = [_obstacles(per, k, solids, cfg.reach) if cfg.neighbours else None for k in range(len(segs))]
    done = [settled_plan(k, segs[k], ident, why, olds[k], obstacles[k], cfg)
            for k, (ident, why) in enumerate(idents)]
    todo = [k for k, d in enumerate(done) if d is None]
    for k, d in zip(todo, plan_segments([(segs[k], k, idents[k][0], obstacles[k], db, cfg, table, viewpoint)
                                          for k in todo], db, cfg)):
        done[k] = d
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
