"""The run-time planner (paper 2.2-2.5): point cloud -> adapted graspability map.

    cloud -> hierarchical MVBB + MLESAC identification -> for every part: the FS map of
    a known primitive as is, or the nearest FS map scaled to a familiar one -> one part:
    that map; several parts: the combined map of the compound -> adapted map

:func:`plan_stream` yields grasps as soon as they exist (best-first within each part),
so a caller can act on the first grasps before the whole map is built; :func:`plan`
returns the finished map. With ``PlannerConfig.rank="robust"`` (the default) every
batch's best-graded grasps get robust scores as they stream (clearance to the observed
cloud, feasibility under wrist pose error; :mod:`graspsim.maps.robust`), up to
``PlannerConfig.robust.top`` per part, and batches and the finished map are ordered by
them; ``rank="paper"`` keeps the paper's grade order and scores nothing. Every map
records ``extra["T_cloud_obj"]`` (4x4): the object frame in the cloud's frame, so poses
can be taken back to the sensor. What it returns (:class:`PlanResult`, :class:`GraspBatch`,
...) is defined in :mod:`graspsim.planning.plan_results`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from graspsim.errors import InvalidParameterError, NoFeasibleGraspError
from graspsim.geometry.spacing import median_spacing
from graspsim.geometry.table import TablePlane, table_frame
from graspsim.maps.combine import combine_part
from graspsim.maps.database import MapDatabase
from graspsim.maps.feature_grasps import FeatureConfig
from graspsim.maps.generate import object_description
from graspsim.maps.graspmap import GraspabilityMap, MapMeta, Placement
from graspsim.maps.match import MatchKind
from graspsim.maps.occlusion import ViewDepth
from graspsim.maps.robust import RANKS, RobustConfig, cloud_in_object, score_map, view_of
from graspsim.maps.scaling import ScalingConfig, scale_stream
from graspsim.maps.table_clearance import (
    LowProfile,
    clears_table,
    heights_above,
    lift_clear,
    low_part,
    stream_order,
    table_height,
)
from graspsim.perception import Identification, IdentificationStatus, IdentifyConfig, identify
from graspsim.planning.box_merge import merge_boxes
from graspsim.planning.observed import ObservedChecks, first_clear
from graspsim.planning.plan_results import GraspBatch, PartPlan, PlanResult, PlanStatus
from graspsim.planning.stages import StageClock
from graspsim.planning.table_completion import complete_to_table, segment_depth
from graspsim.primitives import Compound, Primitive, make_primitive
from graspsim.primitives.compound import object_frame
from graspsim.transforms import invert_transform

__all__ = ["PlanStatus", "PlannerConfig", "SCENE_TABLE_SKIP", "CLEAR_FIRST_SPAN", "PartPlan", "PlanResult",
           "GraspBatch", "plan", "plan_stream", "plan_shape", "plan_shape_stream"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PlannerConfig:
    """identify: perception settings (paper case study: 10 repetitions, theta 0.5).
    scaling: the map scaling settings (Combined by default).
    partial: when clustering fails, still build the map of the identified parts.
    build_missing: when no stored map of the primitive lies within the scaling range,
        build (and store) an FS map of it, as the paper suggests; else skip the part.
    table: the plane the object stands on (cloud frame); poses that would take the
        gripper below it are dropped from every batch. None (default, as the paper):
        the map ignores the table.
    contact_tolerance: robust identification: a grasp is kept only where the cloud bears
        it out (:mod:`~graspsim.maps.agreement`): at least one contact where the cloud
        shows the finger's touch -- a cloud point within this distance [m] of the
        contact or of its closing path further in -- and the cloud's normal at every
        touch it shows within the friction cone about the closing line; a contact
        whose path meets no observed point is no evidence in a single view (its far
        side), and both must be borne out in a cloud seen all round (no viewpoint;
        ``both_contacts_all_round``), within at least 3 of the cloud's median point
        spacings (:class:`~graspsim.planning.observed.ObservedChecks`).
    both_contacts_all_round: robust identification, a cloud planned without a viewpoint
        (seen all round): both contacts of a grasp must be borne out, as no part of the
        object is hidden from such a cloud; False: one, as of a single view. Scene
        planning sets False: a segment's points are not all of its object even without
        a viewpoint (thinned, cut at creases and at its neighbours).
    rank: ``"robust"`` (default): score the best-graded grasps for robustness
        (``robust``) and order by the robust score; ``"paper"``: the paper's grade.
    robust: the robustness settings (pose error, perturbations, grasps scored per part).
    collision_tolerance: the run-time collision check of adapted grasps -- a stored map
        scaled to the identified primitive, a part's grasps against the other parts of
        its compound -- counts poses within this distance [m] of touching as colliding;
        None (default, the paper's check): the tolerance the FS maps were generated with
        (``MapDatabase.config``). A larger one is more conservative -- a grasp that comes
        that close is dropped, or kept at another contact depth that clears it -- and
        costs less: the check's finest collision samples number about 1 / tolerance^2
        per unit area (scene planning uses 1 mm,
        :data:`~graspsim.planning.scene.SCENE_COLLISION_TOLERANCE`).
    clear_observed: robust identification: no grasp is offered whose gripper holds an
        observed point (the cloud and ``obstacles``) at its nominal pose at the opening
        it is executed with; a grasp is dropped exactly when no opening of
        ``robust.openings`` clears (:mod:`~graspsim.planning.observed`; the count in
        ``extra["observed"]``). Paper mode never drops.
    features: robust identification: where the parts give fewer than
        ``features.min_grasps`` grasps with a robust score > 0 (a bowl as one sphere wider
        than the gripper), grasps on the cloud's own features (a rim, a bar;
        :mod:`~graspsim.maps.feature_grasps`) are added as part ``len(parts)``, through the same
        checks. None: never. Paper mode never adds.
    seen_depth: robust identification of a single view (a viewpoint): no grasp is offered
        that closes across a part's extent the view did not measure -- a box part's dimension
        with only the faces across it seen, as a carton seen from the front, fitted as a plate
        a few mm thick; a curved part's depth along the line of sight, its back the fit's
        extrapolation of the seen side
        (:meth:`~graspsim.planning.observed.ObservedChecks.unseen_depth`; the count in
        ``extra["observed"]``). False: such grasps offered. Paper mode and clouds without a
        viewpoint: never applied. A grasp across the unmeasured depth is still offered where
        its fingers stay in space the view saw (a domino standing on its edge, the camera
        seeing past it: :data:`~graspsim.planning.observed.SEEN_FINGER_SHARE`).
    hidden_faces: robust identification of a single view: a grasp closing across a box
        part's axis whose two faces the camera could not see (turned more than
        :data:`~graspsim.planning.observed.HIDDEN_FACE_ANGLE` from it: a block or carton
        lying with its long sides edge-on to the camera), where the view measured the
        part's extent along every axis (its top spans the width, its near end the height),
        needs no contact borne out by the cloud -- none can be -- only none contradicted
        (:meth:`~graspsim.planning.observed.ObservedChecks.borne_out`). False: such grasps
        dropped, as every grasp with no contact borne out (every grasp of such a block
        that clears the table, before). Paper mode and clouds without a viewpoint: never.
    low_profile: with a ``table``, a pose that would take the gripper under it is lifted
        clear along its approach, its contacts held nearer the fingertip
        (:class:`~graspsim.maps.table_clearance.LowProfile`,
        :func:`~graspsim.maps.table_clearance.lift_clear`): the grasps of objects lower than
        the pad's planned region (a domino, a lid, a flat tool lying down), which the stored
        maps' tip margin (``GripperSpec.depth_lo``) leaves with none. Only parts that low are
        lifted (:func:`~graspsim.maps.table_clearance.low_part`: the part's top less than the
        table clearance + the tip margin + the maps' surface step above the table, 12 mm for
        the default gripper); a taller object's grasps stay as they were. They go through the
        observed-point checks and robust score, but not the cloud-agreement filter (a low
        part's side contacts lie within its tolerance of the top face, and a scene's table
        band removes the side points that would bear them out); counts in the table record:
        ``low_parts``, ``lifted``. None: never (every such pose dropped, as before). Paper
        identification mode never lifts.
    complete_to_table: robust identification of a single view with a ``table`` of known
        height: a box part whose hidden far face hangs above the table, on a segment that
        touches it, with the space between in the camera's shadow, is completed down to the
        table plane (the object cannot float; a carton lying on its side fitted as a 2 cm
        plate, a domino fitted 2 mm thick) and a grasp may close across that extent; a segment
        whose foot a neighbour hides is completed too where none of the neighbours' points
        (``obstacles``) lies in the added volume
        (:func:`~graspsim.planning.table_completion.complete_to_table`; the count in
        ``extra["table"]["completed"]``). False (default; single-object planning): parts as
        identified. Scene planning turns it on.
    hidden_depth: robust identification of a single view: a box part's extent along an axis
        the view did not measure (only the faces across it seen: a domino standing face-on
        to the camera) is at least what the view can tell from its seen face -- the contact
        tolerance plus two noise sigmas
        (:attr:`~graspsim.planning.observed.ObservedChecks.least_hidden_depth`); the fit
        makes it what the noise allows (a 6 mm domino 2.3 to 3.7 mm), which puts the far
        contact among the seen face's own points, so every grasp across it is taken as
        contradicted by them. It is also at least as deep as the segment's own points reach
        behind the part, where the volume that adds lies in the camera's shadow (a standing
        carton fitted as a plate on its front face, its top fitted apart:
        :func:`~graspsim.planning.table_completion.segment_depth`; a least depth: the faces
        along it count as measured for ``hidden_faces``, a grasp across it is still judged by
        ``seen_depth``; the count in ``extra["table"]["segment_depth"]``). Its far face moves
        away from the camera, not through the table. With the robust score's unseen margin
        on, an object with such a part is taken to be as deep as the part's seen face is
        narrow, and that is its margin where it is wider (:func:`_face_depth`). False
        (default; single-object planning): parts as identified. Scene planning turns it on.
    merge_boxes: robust identification of a single view: two box parts whose axes agree,
        the volume of their union's box neither fills in the camera's shadow, are merged
        into that box (a carton the fit cut into parallel slabs, whose
        combined maps hold no grasp across the whole carton:
        :func:`~graspsim.planning.box_merge.merge_boxes`; the count in
        ``extra["identification"]["merged"]``), after ``complete_to_table``. False (default;
        single-object planning): parts as identified. Scene planning turns it on.
    table_skip: [m] with a ``table``: a stored grasp whose scaled pose, as predicted from its
        contacts before the exact chord, puts the gripper more than this under the table's
        clearance is not scaled (the table filter would drop it: the exact pose keeps the
        predicted orientation and moves by millimetres); not for a low part, whose poses
        under the table are lifted clear (``low_profile``). None (default): every stored grasp
        is scaled. Scene planning sets :data:`~graspsim.planning.planner.SCENE_TABLE_SKIP`.
    clear_first: robust ranking: a batch's robust-scoring budget (``robust.top`` per part) goes
        to its best-graded grasps whose gripper holds no observed point -- the object's, and the
        ``obstacles`` (a scene's neighbours) -- at the nominal pose at some opening the score may
        choose (:func:`~graspsim.planning.observed.first_clear`: one pass of the robust score's
        kernel at no pose error); the grasps passed over, which the robust score would give 0,
        are left out of the batch (counts in ``extra["clear_first"]``). In a crowded pile every
        one of a lying bottle's best-graded grasps can close on a neighbour: the budget went to
        them and the object was left with no grasp, while grasps lower in the grade order
        cleared. A part's grasps are checked down to :data:`CLEAR_FIRST_SPAN` times its budget
        (the parts that went that far: ``span_reached``). False (default): the budget to the
        best-graded grasps as they come. Scene planning turns it on.
    table_band: [m] with ``complete_to_table``: the height above the table below which the
        cloud's points were cut away as the table's (a scene's ``SceneConfig.table_band``,
        which sets it); the completed volume's hidden space is judged above it.
    seen_between: robust identification: the budget of robust scores goes only to grasps whose
        closing region (between the pads at the pre-grasp opening, across the finger width,
        along the pad: :meth:`~graspsim.grippers.spec.GripperSpec.points_between`) holds at
        least this many of the plan's own observed points (not its obstacles'); the others are
        not offered. A grasp closing where the camera saw nothing of the object closes on the
        parts' extrapolation alone: in clutter, an organic object's fitted box or cylinder
        went on where the object did not, and the pads met nothing
        (:data:`~graspsim.planning.observed.SEEN_BETWEEN`, the value the scene planner sets).
        0 (default): off. Paper mode never applies it.
    restarts: robust identification made by the planner (not given to it): when the map of
        a cloud's identification holds no accepted grasp, the cloud is identified again, the
        generator drawn on (so the same seed gives the same answer), up to this many more
        times; the first map with an accepted grasp stands, else the last (the attempts made:
        ``extra["identification"]["attempts"]``). Identification is a randomised search over
        discrete decompositions: a cloud near a decision's edge comes out otherwise when its
        points move by micrometres, and some of the decompositions it can come out as -- a
        duck's body as two short cylinders whose ends its head and tail cover -- hold no
        accepted grasp where the others do (``experiments/study_identification_stability.py``).
        0: one attempt. Paper mode never restarts.
    """

    identify: IdentifyConfig = field(default_factory=IdentifyConfig)
    scaling: ScalingConfig = field(default_factory=ScalingConfig)
    partial: bool = True
    build_missing: bool = True
    table: TablePlane | None = None
    contact_tolerance: float = 0.004
    rank: str = "robust"
    robust: RobustConfig = field(default_factory=RobustConfig)
    collision_tolerance: float | None = None
    clear_observed: bool = True
    features: FeatureConfig | None = field(default_factory=FeatureConfig)
    seen_depth: bool = True
    hidden_faces: bool = True
    low_profile: LowProfile | None = field(default_factory=LowProfile)
    both_contacts_all_round: bool = True
    complete_to_table: bool = False
    table_band: float = 0.006
    hidden_depth: bool = False
    merge_boxes: bool = False
    table_skip: float | None = None
    clear_first: bool = False
    seen_between: int = 0
    restarts: int = 2

    def __post_init__(self) -> None:
        if self.low_profile is not None and not isinstance(self.low_profile, LowProfile):
            raise InvalidParameterError(f"PlannerConfig.low_profile must be a LowProfile or None (off), "
                                        f"got {self.low_profile!r}")
        tol = self.collision_tolerance
        if tol is not None and (isinstance(tol, bool) or not isinstance(tol, (int, float))
                                or not (np.isfinite(tol) and tol > 0)):
            raise InvalidParameterError(f"PlannerConfig.collision_tolerance must be > 0 m or None (the maps' "
                                        f"own), got {tol!r}")
        if self.rank not in RANKS:
            raise InvalidParameterError(f"PlannerConfig.rank must be one of {list(RANKS)}, got {self.rank!r}")
        skip = self.table_skip
        if skip is not None and (isinstance(skip, bool) or not isinstance(skip, (int, float))
                                 or not (np.isfinite(skip) and skip >= 0)):
            raise InvalidParameterError(f"PlannerConfig.table_skip must be >= 0 m or None (off), got {skip!r}")
        if isinstance(self.seen_between, bool) or not isinstance(self.seen_between, int) or self.seen_between < 0:
            raise InvalidParameterError(f"PlannerConfig.seen_between must be an integer >= 0 (0: off), "
                                        f"got {self.seen_between!r}")
        if isinstance(self.restarts, bool) or not isinstance(self.restarts, int) or not 0 <= self.restarts <= 10:
            raise InvalidParameterError(f"PlannerConfig.restarts must be an integer in [0, 10], got {self.restarts!r}")
        if not isinstance(self.robust, RobustConfig):
            raise InvalidParameterError(f"PlannerConfig.robust must be a RobustConfig, got {self.robust!r}")


def check_config(db: MapDatabase, cfg: PlannerConfig):
    """The :class:`~graspsim.maps.generate.MapConfig` the run-time collision checks of
    adapted grasps use: the database's, at ``cfg.collision_tolerance`` when it is set."""
    if cfg.collision_tolerance is None:
        return db.config
    return replace(db.config, collision_tolerance=float(cfg.collision_tolerance))


def canonical_box(prim: Primitive, T: np.ndarray) -> tuple[Primitive, np.ndarray]:
    """A box with its edges in ascending order (x <= y <= z, z the longest as docs/design.md
    §3 says), re-expressing its frame by the matching proper axis permutation."""
    if prim.kind != "box":
        return prim, T
    d = np.array([prim.x, prim.y, prim.z])
    order = np.argsort(d, kind="stable")
    if np.array_equal(order, [0, 1, 2]):
        return prim, T
    P = np.eye(3)[:, order]  # new axis k = old axis order[k]
    if np.linalg.det(P) < 0:
        P[:, 0] *= -1.0
    T2 = T.copy()
    T2[:3, :3] = T[:3, :3] @ P
    return prim.with_dims(x=d[order[0]], y=d[order[1]], z=d[order[2]]), T2


def _batches(gmap: GraspabilityMap, first: int, growth: float, prefer=None) -> Iterator[GraspabilityMap]:
    """A best-first map in growing slices (for streaming a stored map); the rows
    ``prefer`` (as in :func:`graspsim.maps.scaling.scale_stream`) accepts first."""
    pick = None if prefer is None else (
        lambda pos: prefer(gmap.wrist_quat[pos], gmap.wrist_position[pos], gmap.width[pos]))
    for rows in stream_order(len(gmap), first, growth, pick):
        yield gmap.select(rows)


#: ``PlannerConfig.clear_first`` checks a part's grasps, best-graded first, down to this many times its
#: robust-scoring budget (``robust.top``; 2000 for the scene planner's 200) and scores only those that clear:
#: on the frames of two E10 household-tuning pile scenes that stopped on no_grasp, the first grasp clear of
#: the neighbours of a segment whose 200 best-graded grasps all held a point lay at ranks 71 to 1134 (9
#: segment frames; one more segment at 5843 in two frames, which the span leaves without a grasp), while
#: a segment with none clear (a bottle lying in a pile's middle) streamed 7000 to 10000 grasps to the end
#: of its maps: unbounded, the check cost one frame 1.2 s of CPU (14 000 rows; 0.6 s with the span).
CLEAR_FIRST_SPAN = 10

# only predicted poses this far above the table's clearance stream first: the
# prediction of a scaled pose (before its exact chord) is off by a few millimetres
_TABLE_TOLERANCE = 0.005
#: [m] scene planning's ``PlannerConfig.table_skip``: a stored grasp predicted (before its
#: exact chord) to put the gripper more than 3 cm under the table's clearance is not
#: scaled. Six times the stream order's allowance for the prediction's error
#: (``_TABLE_TOLERANCE``); on 70 household-tuning E10 frames no ranked grasp changed
#: (1 cm changed two frames' rankings), and 59 % of the stored grasps streamed were not scaled.
SCENE_TABLE_SKIP = 0.03


class _LastHeights:
    """:func:`~graspsim.maps.table_clearance.heights_above` of predicted poses, the last
    call's kept: the stream order's preference and the table skip ask about the same
    poses one after the other (:func:`~graspsim.maps.scaling.scale_stream`), and the
    second gets the first's heights (the same arrays: the same values)."""

    def __init__(self, gripper, T_table_part: np.ndarray) -> None:
        self.gripper, self.T = gripper, T_table_part
        self.last: tuple = ()

    def __call__(self, q: np.ndarray, p: np.ndarray, w: np.ndarray) -> np.ndarray:
        if self.last and self.last[0] is q and self.last[1] is p and self.last[2] is w:
            return self.last[3]
        h = heights_above(self.gripper, self.T, q, p, w)
        self.last = (q, p, w, h)
        return h


def _part_stream(prim: Primitive, db: MapDatabase, cfg: PlannerConfig, checks,
                 T_table_part: np.ndarray | None = None, low: bool = False
                 ) -> tuple[MatchKind, dict, Iterator, dict | None]:
    """(match, source object, iterator of map batches in the part's frame, the stored
    map used -- :attr:`PartPlan.stored <graspsim.plan_results.PartPlan.stored>`; a scaled
    map's grasps checked for collisions at ``checks``, :func:`check_config`); with the
    table's frame ``T_table_part`` in the part's frame, the grasps likely to clear it
    stream first (the table filter would empty the first batches otherwise), and with
    ``PlannerConfig.table_skip`` those predicted far under it not scaled (not for a
    ``low`` part, whose poses under the table are lifted clear)."""
    m = db.match(prim, max_ratio=cfg.scaling.max_ratio)
    prefer = skip = None
    if T_table_part is not None:
        least = cfg.table.clearance + _TABLE_TOLERANCE
        height = _LastHeights(db.gripper, T_table_part)
        prefer = lambda q, p, w: height(q, p, w) >= least  # noqa: E731
        if cfg.table_skip is not None and not low:
            under = cfg.table.clearance - cfg.table_skip
            skip = lambda q, p, w: height(q, p, w) < under  # noqa: E731
    stream = lambda g: _batches(g, cfg.scaling.first_batch, cfg.scaling.growth, prefer)  # noqa: E731
    used = None if m.entry is None else {"key": m.entry.get("key"), "ratio": m.ratio, "max_diff": m.max_diff}
    if m.match is MatchKind.KNOWN:  # the stored map as is (paper 2.2)
        fs = db.load_entry(m.entry, accepted_only=True)
        return m.match, fs.meta.object, stream(fs), used
    if m.match is MatchKind.FAMILIAR:
        fs = db.load_entry(m.entry, accepted_only=True)
        return m.match, fs.meta.object, scale_stream(fs, prim, scaling=cfg.scaling, gripper=db.gripper,
                                                        quality=db.quality, config=checks, prefer=prefer,
                                                        skip=skip), used
    if not cfg.build_missing:
        return MatchKind.BUILD, {}, iter(()), None
    # no map of this primitive within the scaling range: add one to the database
    try:
        fs = db.get(prim)  # sorted best first: the accepted grasps are a prefix
    except NoFeasibleGraspError:  # no chord of it fits the gripper (a part fitted a mm thick): it gives no grasps,
        return MatchKind.BUILD, {}, iter(()), None  # and the object's other parts (and features) are still planned
    fs = fs.select(np.arange(int(fs.accepted.sum())))
    return MatchKind.BUILD, fs.meta.object, stream(fs), {"key": db.key(prim), "ratio": 1.0, "max_diff": 0.0}


def plan_stream(points: np.ndarray, *, db: MapDatabase, rng: np.random.Generator,
                config: PlannerConfig | None = None, source: str = "array",
                obstacles: np.ndarray | None = None, identification: Identification | None = None,
                viewpoint: np.ndarray | None = None, scored_only: bool = False,
                obstacles_seen: np.ndarray | None = None) -> Iterator[GraspBatch | PlanResult]:
    """Yield :class:`GraspBatch` es as grasps are found, then the :class:`PlanResult`.
    obstacles: (M, 3) further points [m, cloud frame] the robust score keeps the
    gripper clear of besides the object's own (a scene's neighbours); None: none.
    obstacles_seen: (M,) bool, which obstacles the camera saw -- the others inferred (a
    scene's samples of its neighbours' hidden sides and shadows): the depth image of what
    was seen (the occlusion term, the single-view rules) holds ``points`` and these alone;
    None: every obstacle was seen.
    identification: the cloud's, when the caller has identified it already (``points``
    must be the cloud it was made from); None: identified here. viewpoint: (3,) where a
    single-view cloud was seen from [m, cloud frame] (the robust score's occlusion term);
    None: unknown or seen all round. scored_only: with ``rank="robust"``, once a part's
    robust-scoring budget (``robust.top``) is spent, the rest of that part's maps are
    skipped instead of streamed unscored (for a caller that keeps only scored grasps,
    as a scene does: the same scored grasps, sooner; the final map then lacks the
    skipped ones)."""
    from graspsim.maps.occlusion import check_viewpoint
    from graspsim.seeding import check_rng

    cfg = config or PlannerConfig()
    t0 = time.perf_counter()
    if identification is None or rng is not None:  # given the identification, nothing is drawn
        check_rng(rng)
    viewpoint = check_viewpoint(viewpoint)  # a bad one fails now, not after the identification
    points = np.asarray(points, float)
    obstacles, obstacles_seen = _check_obstacles(obstacles, obstacles_seen)
    restarts = cfg.restarts if identification is None and cfg.identify.is_robust else 0
    for attempt in range(restarts + 1):
        result = None
        for item in _plan_identified(points, identification, rng, db, cfg, source, obstacles, viewpoint, scored_only,
                                     t0, attempt, obstacles_seen):
            if isinstance(item, PlanResult):
                result = item
            else:
                yield item
        if attempt == restarts or result.map.accepted.any():
            yield result if not attempt else replace(result, attempts=attempt + 1)
            return


def _check_obstacles(obstacles, seen) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``plan_stream``'s ``obstacles`` as (M, 3) floats (None: none) and ``obstacles_seen`` as
    (M,) bool (None: all seen), or an :class:`InvalidParameterError` naming what is valid."""
    if obstacles is None:
        if seen is not None:
            raise InvalidParameterError("obstacles_seen needs obstacles: give both, or neither")
        return None, None
    O = np.asarray(obstacles, float).reshape(-1, 3)
    if seen is None:
        return O, None
    S = np.asarray(seen)
    if S.dtype != bool or S.shape != (len(O),):
        raise InvalidParameterError(f"obstacles_seen must be ({len(O)},) bool, one per obstacle point, got "
                                    f"{S.dtype} {S.shape}")
    return O, S


def _plan_identified(points, identification, rng, db: MapDatabase, cfg: PlannerConfig, source: str, obstacles,
                     viewpoint, scored_only: bool, t0: float, attempt: int,
                     obstacles_seen: np.ndarray | None = None) -> Iterator[GraspBatch | PlanResult]:
    """:func:`plan_stream`'s one attempt (``attempt``: the restarts before it)."""
    ident = identification if identification is not None else identify(points, rng=rng, config=cfg.identify)
    timing = {"identify": time.perf_counter() - t0}
    cpu0 = time.thread_time()
    prims, T_cloud = [], []
    for part in ident.parts:
        p, T = canonical_box(part.primitive(), part.T_world_obj)
        prims.append(p)
        T_cloud.append(T)
    status = PlanStatus.COMPLETE if ident.status is IdentificationStatus.IDENTIFIED else PlanStatus.PARTIAL
    if not prims or (status is PlanStatus.PARTIAL and not cfg.partial):
        status = PlanStatus.FAILED
        prims, T_cloud = [], []
    if not prims:
        yield PlanResult(status, GraspabilityMap.empty(_empty_meta(db, ident)), (), ident, np.eye(4),
                         {**timing, "total": time.perf_counter() - t0, "first": None, "tenth": None,
                          "first_robust": None, "robust": 0.0})
        return
    info = {"status": ident.status.value, "n_points": ident.n_points, "n_splits": ident.n_splits,
            "downsampling": None if ident.downsampling is None else ident.downsampling.to_dict(),
            "mode": ident.mode, "uncovered": ident.uncovered,
            "approximate": [i for i, p in enumerate(ident.parts) if p.approximate],
            "fit": ident.fit_quality(points, cfg.identify.band, viewpoint).to_dict(),
            **({"attempts": attempt + 1} if attempt else {})}
    yield from _plan_parts(prims, T_cloud, status, ident, info, points, db, cfg, source, t0, timing, cpu0,
                           obstacles, viewpoint, scored_only, obstacles_seen)


def plan_shape_stream(shape, T_world_obj: np.ndarray | None = None, *, db: MapDatabase,
                      config: PlannerConfig | None = None, source: str = "model", scored_only: bool = False
                      ) -> Iterator[GraspBatch | PlanResult]:
    """:func:`plan_stream` for an object whose primitives are known -- a
    :class:`~graspsim.primitives.Primitive` or :class:`~graspsim.primitives.Compound` at
    pose ``T_world_obj`` (4, 4; identity if None) in the frame the map's
    ``T_cloud_obj`` will refer to -- instead of identified from a cloud: retrieval,
    scaling and combination as for identified parts (``config.identify`` is unused;
    ``scored_only`` as there). The result's ``identification`` is None."""
    cfg = config or PlannerConfig()
    t0 = time.perf_counter()
    T = np.eye(4) if T_world_obj is None else np.asarray(T_world_obj, float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InvalidParameterError(f"T_world_obj must be a finite 4x4 transform, got shape {T.shape}")
    if isinstance(shape, Compound):
        pairs = [(p, T @ pose) for p, pose in zip(shape.parts, shape.poses)]
    elif isinstance(shape, Primitive):
        pairs = [(shape, T)]
    else:
        raise InvalidParameterError(f"plan_shape needs a Primitive or a Compound, got {type(shape).__name__}")
    prims, T_cloud = zip(*(canonical_box(p, Tp) for p, Tp in pairs))
    yield from _plan_parts(list(prims), list(T_cloud), PlanStatus.COMPLETE, None, None, np.zeros((0, 3)),
                           db, cfg, source, t0, {"identify": 0.0}, time.thread_time(), scored_only=scored_only)


def _completed(prims: list, T_cloud: list, points: np.ndarray, view: ViewDepth,
               table: TablePlane, viewpoint: np.ndarray, band: float,
               neighbours: np.ndarray | None = None) -> tuple[list, list, list]:
    """``PlannerConfig.complete_to_table``: the parts (canonical boxes again), their poses
    and per part the axis the table now bounds ((1, 3); None: left as identified); ``view``:
    the depth image of the segment's points and the obstacles'; ``neighbours``: the
    obstacles' alone (a segment whose foot a neighbour hides is completed where none of them
    is in the way; None: only segments touching the table)."""
    out_p, out_T, bounded = [], [], []
    for prim, T in zip(prims, T_cloud):
        p, Tp, how = complete_to_table(prim, T, points, table, viewpoint, view, band=band, neighbours=neighbours)
        if how.axis is not None:
            p, Tp = canonical_box(p, Tp)
        out_p.append(p)
        out_T.append(Tp)
        bounded.append(None if how.axis is None else how.axis[None])
    return out_p, out_T, bounded


def _deepened(prims: list, T_cloud: list, bounded: list, observed: ObservedChecks, table: TablePlane | None,
              viewpoint: np.ndarray, points: np.ndarray, view: ViewDepth, band: float
              ) -> tuple[list, list, list]:
    """``PlannerConfig.hidden_depth``: the parts with each box's unmeasured extent (no face
    along it seen: :meth:`~graspsim.planning.observed.ObservedChecks.unmeasured_axes`) at
    least :attr:`~graspsim.planning.observed.ObservedChecks.least_hidden_depth`, and as deep
    as the segment's own ``points`` reach along it where the volume that adds lies in the
    camera's shadow (``view``; :func:`~graspsim.planning.table_completion.segment_depth`),
    its far face moved away from the camera (its seen face kept), not through the table; an
    axis the table bounds (``bounded``) is left as it is. Returns the parts, their poses and
    per part the axes the segment's points deepened ((k, 3); None: none): a least depth, not
    the depth (a carton's seen gable reaches back only to its ridge, half the carton), so
    such an axis counts as measured for the extents of the faces along it
    (:meth:`~graspsim.planning.observed.ObservedChecks.borne_out`), not for a grasp
    closing across it (:meth:`~graspsim.planning.observed.ObservedChecks.unseen_depth`)."""
    least = observed.least_hidden_depth
    out_p, out_T, out_b = [], [], []
    for prim, T, axes in zip(prims, T_cloud, bounded):
        thin = _open_axes(prim, T, axes, observed)
        floors = None
        if not thin:
            out_p.append(prim)
            out_T.append(T)
            out_b.append(floors)
            continue
        T = np.asarray(T, float).copy()
        dims = np.array([prim.x, prim.y, prim.z])
        changed = False
        for j in thin:
            d = T[:3, j] * (1.0 if float((T[:3, 3] - viewpoint) @ T[:3, j]) >= 0.0 else -1.0)  # away from the camera
            reach = segment_depth(make_primitive("box", x=float(dims[0]), y=float(dims[1]), z=float(dims[2])),
                                  T, j, d, points, view, table, band)
            add = max(least - dims[j], reach)
            if table is not None and table.height is not None:  # not through the table
                n = np.asarray(table.normal, float)
                down = -float(d @ n)
                if down > 1e-6:
                    half = 0.5 * dims
                    far = T[:3, 3] + d * half[j]
                    spread = sum(abs(float(T[:3, k] @ n)) * half[k] for k in range(3) if k != j)
                    add = min(add, max(0.0, (float(far @ n) - spread - table.height) / down))
            if add <= 0.0:
                continue
            if reach > 0.0 and add >= reach:  # the segment's own points reach this deep: a least depth
                floors = T[:3, j][None].copy() if floors is None else np.vstack([floors, T[:3, j]])
            dims[j] += add
            T[:3, 3] += 0.5 * add * d
            changed = True
        if changed:
            prim, T = canonical_box(make_primitive("box", x=float(dims[0]), y=float(dims[1]), z=float(dims[2])), T)
        out_p.append(prim)
        out_T.append(T)
        out_b.append(floors)
    return out_p, out_T, out_b


#: [m] The most :func:`_face_depth` takes an object seen on one face to reach behind it: the widest
#: unseen margin a scene takes (``planning.scene_config.MAX_UNSEEN_MARGIN``).
MAX_FACE_DEPTH = 0.1


def _face_depth(prims: list, T_cloud: list, bounded: list, observed: ObservedChecks) -> float:
    """[m] How deep an object may reach behind a box part that a single view saw on one
    face only (an axis no face along it was seen: :meth:`ObservedChecks.unmeasured_axes`,
    the parts as fitted; an axis the table bounds, ``bounded``, left out: :func:`_deepened`'s axes):
    the narrower of that face's two extents (the widest such over the parts; at most
    :data:`MAX_FACE_DEPTH`); 0 when every box part's axes were measured. The fit makes such
    a part a plate a few mm deep (its depth then the view's least, ``hidden_depth``); the
    object behind the face is taken to be as deep as the face is narrow. With the scene
    planner's unseen margin on, it is the object's margin where it is wider
    (``RobustConfig.unseen_margin``), bounded as the margin always is by the shadow the
    object casts and the thickness of its known shape (:func:`graspsim.maps.robust.score_rows`):
    a milk carton standing face-on to the camera, fitted as a plate on its front and its
    gable apart, had grasps from the side closing up and down across its top whose lower
    finger went 23 to 33 mm past every known point of it, into its 52 mm depth, and kept
    their whole score at the 20 mm margin."""
    deep = 0.0
    for prim, T, table_axes in zip(prims, T_cloud, bounded):
        for j in _open_axes(prim, T, table_axes, observed):
            deep = max(deep, float(np.min(np.delete(np.array([prim.x, prim.y, prim.z]), j))))
    return min(deep, MAX_FACE_DEPTH)


def _open_axes(prim, T, table_axes: np.ndarray | None, observed: ObservedChecks) -> list[int]:
    """The axes (indices in the part's frame) of part ``prim`` (posed at ``T``, cloud frame)
    that a single view did not measure (a box's only: :meth:`ObservedChecks.unmeasured_axes`)
    and the table does not bound (``table_axes``, (k, 3) or None): what :func:`_deepened`
    deepens and :func:`_face_depth` reads."""
    thin = observed.unmeasured_axes(prim, T) if prim.kind == "box" else None
    if thin is None:
        return []
    R = np.asarray(T, float)[:3, :3]
    return [int(np.argmax(np.abs(R.T @ u))) for u in thin
            if table_axes is None or not np.any(np.abs(table_axes @ u) > 0.99)]


def _axes(*sets) -> np.ndarray | None:
    """The axes ((k, 3) each, or None) of ``sets`` stacked; None when there are none."""
    got = [a for a in sets if a is not None]
    return np.vstack(got) if got else None


def _plan_parts(prims: list, T_cloud: list, status: PlanStatus, ident: Identification | None,
                ident_info: dict | None, points: np.ndarray, db: MapDatabase, cfg: PlannerConfig,
                source: str, t0: float, timing: dict, cpu0: float, obstacles: np.ndarray | None = None,
                viewpoint: np.ndarray | None = None, scored_only: bool = False,
                obstacles_seen: np.ndarray | None = None) -> Iterator[GraspBatch | PlanResult]:
    """Retrieval, scaling and combination of parts ``prims`` posed at ``T_cloud`` (the
    part frames in the cloud's frame); ``cpu0``: the calling thread's CPU clock when
    identification ended; ``scored_only``, ``obstacles_seen``: see :func:`plan_stream`."""
    # the observed-point checks (robust mode); their object frame is set once the parts are final
    observed = ObservedChecks.of_plan(ident, points, None, np.eye(4), viewpoint, db, cfg)
    seen = points if obstacles is None else np.concatenate([points, np.asarray(obstacles, float).reshape(-1, 3)])
    # what the camera saw: the object's points and the obstacles it saw (not a scene's samples of its
    # neighbours' hidden sides and shadows, which lie in space the camera did not see)
    camera = seen if obstacles_seen is None else np.concatenate([points, obstacles[obstacles_seen]])
    bounded: list = [None] * len(prims)  # per part: its axes the table bounds ((k, 3))
    single_view_rules = cfg.complete_to_table or cfg.merge_boxes or cfg.hidden_depth
    # its depth image (cloud frame), for those rules: one serves them all; its pixel follows the spacing
    # of the camera's points on the object
    seen_view = ViewDepth(camera, viewpoint, spacing=median_spacing(points)) \
        if single_view_rules and viewpoint is not None and observed is not None else None
    if (cfg.complete_to_table and cfg.table is not None and cfg.table.height is not None and viewpoint is not None
            and observed is not None):
        prims, T_cloud, bounded = _completed(prims, T_cloud, points, seen_view, cfg.table, viewpoint, cfg.table_band,
                                             None if obstacles is None else np.asarray(obstacles, float).reshape(-1, 3))
    n_completed = sum(b is not None for b in bounded)
    if cfg.merge_boxes and observed is not None and viewpoint is not None and len(prims) > 1:  # one box
        prims, T_cloud, groups = merge_boxes(prims, T_cloud, seen_view, cfg.table, cfg.table_band)
        if len(groups) < len(bounded):
            prims, T_cloud = (list(x) for x in zip(*(canonical_box(p, T) for p, T in zip(prims, T_cloud))))
            ident_info = {**(ident_info or {}), "merged": len(bounded) - len(groups)}
            bounded = [None if all(bounded[i] is None for i in g)
                       else np.vstack([bounded[i] for i in g if bounded[i] is not None]) for g in groups]
    floors: list = [None] * len(prims)  # per part: its axes the segment's points deepened (a least depth)
    if cfg.hidden_depth and observed is not None and viewpoint is not None:
        face = _face_depth(prims, T_cloud, bounded, observed)  # as fitted: _deepened's own axes
        prims, T_cloud, floors = _deepened(prims, T_cloud, bounded, observed, cfg.table, viewpoint, points,
                                            seen_view, cfg.table_band)
        if cfg.robust.unseen_margin > 0 and face > cfg.robust.unseen_margin:  # this object's margin, its checks' too
            cfg = replace(cfg, robust=replace(cfg.robust, unseen_margin=face))
            observed.cfg = cfg
    T_cloud_obj, compound = object_frame(prims, T_cloud)
    T_obj_part = [invert_transform(T_cloud_obj) @ T for T in T_cloud]
    obj_meta = _object_meta(prims[0] if compound is None else compound, db)
    T_table_obj, table = _table_in_object(cfg, points, prims[0] if compound is None else compound, T_cloud_obj)
    extra = {**Placement(T_cloud_obj, table).to_extra(), "source": source, "status": status.value,
             "identification": ident_info,
             "viewpoint": None if viewpoint is None else np.asarray(viewpoint, float).tolist()}
    n_below = n_hi = n_lifted = n_low = 0
    lift = cfg.low_profile if T_table_obj is not None and (ident is None or ident.mode != "paper") else None
    batches: list[GraspabilityMap] = []
    parts: list[PartPlan] = []
    first = tenth = first_robust = first_robust_cpu = None
    cloud_obj = cloud_in_object(seen, T_cloud_obj)
    view_obj, view = None if viewpoint is None else cloud_in_object(viewpoint, T_cloud_obj)[0], None
    if observed is not None:  # the same points: the depth image of what was seen serves its checks
        observed.cloud_obj, observed.T_cloud_obj, observed.view = cloud_obj, T_cloud_obj, seen_view
        observed.camera = None if camera is seen else camera
    stage = StageClock("adapt", "agreement", "combine", "table", "robust", "observed", "features", "clear_first")
    n_checked = n_cut = n_span = 0  # clear_first: rows checked, rows passed over, parts checked to the span
    skip_spent = scored_only and cfg.rank == "robust"
    checks = check_config(db, cfg)
    t1 = time.perf_counter()
    for i, prim in enumerate(prims):
        stage.start()
        lift_part = lift if lift is not None and low_part(prim, T_table_obj @ T_obj_part[i], db.gripper,
                                                          cfg.table.clearance, db.config.surface_step) else None
        match, src, stream, used = _part_stream(prim, db, cfg, checks,
                                                None if T_table_obj is None else T_table_obj @ T_obj_part[i],
                                                low=lift_part is not None)
        stage.lap("adapt")
        parts.append(PartPlan(prim, match, src, T_cloud[i], T_obj_part[i], used))
        budget = cfg.robust.top if cfg.rank == "robust" else 0
        span, part_checked = CLEAR_FIRST_SPAN * budget, 0  # clear_first: a part's grasps checked at most, so far
        # the part map's frame in the cloud's (a part's own frame until it is combined)
        T_cloud_map = T_cloud_obj if compound is None else T_cloud_obj @ compound.poses[i]
        seen_lifted: set[bytes] = set()  # a line and roll lifted in one batch is not lifted again in a later one
        n_low += lift_part is not None
        for part_map in stage.iterate(() if skip_spent and budget <= 0 else stream, "adapt"):
            low = None
            if lift_part is not None:  # a low part: its poses under the table lifted clear first (part frame)
                T_table_part = T_table_obj @ T_obj_part[i]
                clear = clears_table(part_map, T_table_part, db.gripper, cfg.table.clearance)
                n_below += int(len(clear) - clear.sum())
                low = _lifted(part_map.select(~clear), T_table_part, db.gripper, cfg.table.clearance, lift_part,
                              seen_lifted)
                n_lifted += len(low)
                part_map = part_map.select(clear)
            if observed is not None:  # before combining: it keeps each grasp's contacts, and costs more
                # (not the lifted poses: their contacts lie within the contact tolerance of a low part's
                # top face, whose points' normals would count against every side contact, and a scene's
                # table band removes the side points that bear them out)
                part_map = observed.borne_out(part_map, T_cloud_map, prim, T_cloud[i],
                                              bounded=_axes(bounded[i], floors[i]))
                part_map = observed.unseen_depth(part_map, prim, T_cloud[i], T_cloud_map, bounded=bounded[i])
            stage.lap("agreement")
            if compound is not None:
                part_map, low = (m if m is None or not len(m) else combine_part(
                    m, i, compound, gripper=db.gripper, quality=db.quality, d_ref=obj_meta.quality["d_ref"],
                    config=checks, meta=obj_meta) for m in (part_map, low))
            stage.lap("combine")
            if T_table_obj is not None:
                clear = clears_table(part_map, T_table_obj, db.gripper, cfg.table.clearance)
                n_below += int(len(clear) - clear.sum())
                part_map = part_map.select(clear)
                if low is not None and len(low):  # lifted clear of the table already
                    part_map = GraspabilityMap.concat([part_map, low], meta=part_map.meta)
            stage.lap("table")
            batch = replace(part_map, meta=replace(obj_meta, extra=extra), part=np.full(len(part_map), i, np.int16))
            batch = batch if observed is None else observed.clear(batch)  # none holding observed points
            stage.lap("observed")
            if not len(batch):
                continue
            if budget > 0:  # robustness of the batch's best-graded grasps, then its order
                stage.start()
                rows = np.argsort(-batch.grade, kind="stable")[:budget]
                closes = None if observed is None or not cfg.seen_between else (
                    lambda r, b=batch: observed.closes_on_seen(b, r))  # seen_between: on the object's points
                passed = rows[:0]
                if cfg.clear_first:  # the budget to the best-graded grasps that can score: none holding a point
                    order = np.argsort(-batch.grade, kind="stable")[:span - part_checked]
                    rows, checked = first_clear(batch, order, budget, cloud_obj, cfg.robust, db.gripper, also=closes)
                    passed = np.setdiff1d(order[:checked], rows)  # each would score 0 or close on nothing: not offered
                    n_checked, n_cut, part_checked = n_checked + checked, n_cut + len(passed), part_checked + checked
                    if part_checked >= span:  # as far down the part's grade order as the check goes
                        n_span += 1
                        budget = len(rows)  # spent once these are scored
                elif closes is not None:
                    ok = closes(rows)
                    passed, rows = rows[~ok], rows[ok]
                if len(passed):
                    keep = np.ones(len(batch), bool)
                    keep[passed] = False
                    rows = (np.cumsum(keep) - 1)[rows]  # their rows once the passed ones are gone
                    batch = batch.select(keep)
                if cfg.clear_first or closes is not None:
                    stage.lap("clear_first")
                if not len(rows):  # the whole batch held points or closed on nothing
                    if skip_spent and budget <= 0:
                        break
                    continue
                if view is None:  # the cloud's depth image from the viewpoint: one for every batch (in the object
                    # frame: the seen points' spacing, measured for seen_view, serves it)
                    view = view_of(cloud_obj if camera is seen else cloud_in_object(camera, T_cloud_obj), view_obj,
                                   cfg.robust, None if seen_view is None else seen_view.spacing)
                batch = score_map(batch, cloud_obj, cfg.robust, rows=rows, gripper=db.gripper,
                                  viewpoint=view_obj, view=view, own=len(points)).ranked()
                budget -= len(rows)
                stage.lap("robust")
                if first_robust is None and bool(np.any(batch.robust > 0)):
                    first_robust = time.perf_counter() - t0
                    first_robust_cpu = time.thread_time() - cpu0
            else:  # unscored (the budget spent, or paper ranking): best-graded first, as every batch streams
                batch = batch.ranked(cfg.rank)  # (stable: the final map's order is unchanged)
            now = time.perf_counter() - t0
            hi = int((batch.grade > 0.95).sum())
            if hi and first is None:
                first = now
            n_hi += hi
            if n_hi >= 10 and tenth is None:
                tenth = now
            batches.append(batch)
            yield GraspBatch(batch, now)
            if skip_spent and budget <= 0:
                break  # this part's budget is spent: its later batches would stream unscored
        if hasattr(stream, "close"):
            stream.close()  # a part left early: its maps' generator ends now
    if observed is not None:  # too few grasps from the parts: the cloud's own features
        extra = yield from observed.stream_features(batches, replace(obj_meta, extra=extra), len(parts),
                                                    T_table_obj, view_obj, view, skip_spent, stage, t0)
    timing["maps"] = time.perf_counter() - t1
    if table is not None and lift is not None:
        table = {**table, "low_profile": lift.to_dict(), "low_parts": n_low, "lifted": n_lifted}
    if table is not None and cfg.complete_to_table:
        table = {**table, "completed": n_completed}
    if cfg.clear_first and cfg.rank == "robust":
        extra = {**extra, "clear_first": {"checked": n_checked, "passed_over": n_cut, "span_reached": n_span}}
    if table is not None and cfg.hidden_depth:
        table = {**table, "segment_depth": sum(0 if b is None else len(b) for b in floors)}
    full = _finished(batches, parts, extra, table, n_below, obj_meta, compound is not None, cfg, T_cloud_obj)
    timing.update(total=time.perf_counter() - t0, first=first, tenth=tenth, first_robust=first_robust,
                  first_robust_cpu=first_robust_cpu, **stage.seconds)
    yield PlanResult(status, full.with_meta(timing=timing), tuple(parts), ident, T_cloud_obj, timing)


def _lifted(below: GraspabilityMap, T_table_obj: np.ndarray, gripper, clearance: float, low: LowProfile,
            seen: set[bytes]) -> GraspabilityMap:
    """The poses of ``below`` (none clearing the table) lifted clear of it
    (:func:`~graspsim.maps.table_clearance.lift_clear`), but for a closing line and roll
    already lifted (``seen``: their keys, updated)."""
    rows, pos = lift_clear(below, T_table_obj, gripper, clearance, low)
    key = np.column_stack([below.contacts[rows].reshape(len(rows), 6), below.wrist_quat[rows]]).astype(np.float32)
    new = np.array([k.tobytes() not in seen for k in key], bool)
    seen.update(k.tobytes() for k in key[new])
    return replace(below.select(rows[new]), wrist_position=pos[new])


def _finished(batches: list, parts: list, extra: dict, table: dict | None, n_below: int, obj_meta: MapMeta,
              combined: bool, cfg: PlannerConfig, T_cloud_obj: np.ndarray) -> GraspabilityMap:
    """The finished adapted map: every batch streamed, in the ranking's order, with the
    parts' record, the table's (the poses it dropped) and the robust scores' provenance."""
    final = {**extra, "parts": [p.to_dict() for p in parts]}
    if table is not None:  # a new dict: the batches already yielded keep theirs
        final.update(Placement(T_cloud_obj, {**table, "dropped": n_below}).to_extra())
    meta = replace(obj_meta, method="adapted/" + ("combined" if combined else "single"), extra=final)
    full = GraspabilityMap.concat(batches, meta=meta) if batches else GraspabilityMap.empty(meta)
    if cfg.rank == "robust" and batches:  # no batch scored (a budget of 0): the settings, none scored
        prov = next((b.meta.extra["robust"] for b in batches if "robust" in b.meta.extra), cfg.robust.to_dict())
        scored = 0 if full.robust is None else int(np.isfinite(full.robust).sum())
        full = full.with_meta(extra={**final, "robust": {**prov, "scored": scored}})
    return full.ranked(cfg.rank)


def _table_in_object(cfg: PlannerConfig, points: np.ndarray, shape, T_cloud_obj: np.ndarray):
    """The table's frame in the object's and its record (height given, or found from the
    cloud: :func:`table_height`), or (None, None) without a table."""
    if cfg.table is None:
        return None, None
    height = table_height(cfg.table, points, shape, T_cloud_obj)
    return table_frame(cfg.table.normal, height) @ T_cloud_obj, {**cfg.table.to_dict(), "height": height}


def plan(points: np.ndarray, *, db: MapDatabase, rng: np.random.Generator,
         config: PlannerConfig | None = None, source: str = "array",
         obstacles: np.ndarray | None = None, viewpoint: np.ndarray | None = None) -> PlanResult:
    """The adapted map of an object cloud (N, 3) [m] (see :func:`plan_stream`)."""
    return _last(plan_stream(points, db=db, rng=rng, config=config, source=source, obstacles=obstacles,
                             viewpoint=viewpoint))


def plan_shape(shape, T_world_obj: np.ndarray | None = None, *, db: MapDatabase,
               config: PlannerConfig | None = None, source: str = "model") -> PlanResult:
    """The adapted map of a known primitive or compound (see :func:`plan_shape_stream`)."""
    return _last(plan_shape_stream(shape, T_world_obj, db=db, config=config, source=source))


def _last(stream) -> PlanResult:
    result = None
    for item in stream:
        result = item
    if not isinstance(result, PlanResult):  # pragma: no cover - the stream always ends so
        raise InvalidParameterError("planner produced no result")
    return result


def _object_meta(shape, db: MapDatabase) -> MapMeta:
    from graspsim._version import __version__

    q = db.quality
    return MapMeta(object=object_description(shape, None, db.config.density), gripper=db.gripper.to_dict(),
                   quality={**q.to_dict(), "d_ref": q.reference_distance(shape.circumradius)},
                   resolution={**db.config.to_dict()}, method="adapted", version=__version__)


def _empty_meta(db: MapDatabase, ident: Identification) -> MapMeta:
    from graspsim._version import __version__

    return MapMeta(object={"primitive": "unidentified"}, gripper=db.gripper.to_dict(),
                   quality=db.quality.to_dict(), resolution=db.config.to_dict(), method="adapted",
                   version=__version__, extra={"status": "failed", **Placement(np.eye(4)).to_extra(),
                                               "identification": ident.to_dict()})

