"""A table-top scene's planning settings (:class:`SceneConfig`), its planning budget label
(:func:`budget_fields`) and the scene planner's fixed constants; the planning itself is
:mod:`graspsim.planning.scene`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graspsim.checks import POSITIVE, check_fields, integer
from graspsim.errors import InvalidParameterError
from graspsim.maps.feature_grasps import FeatureConfig
from graspsim.maps.robust import LIFT_CEILING, UNSEEN_MARGIN, RobustConfig
from graspsim.perception.identify_config import IdentifyConfig
from graspsim.perception.segment import gap_link
from graspsim.planning.observed import SEEN_BETWEEN
from graspsim.planning.planner import SCENE_TABLE_SKIP, PlannerConfig
from graspsim.planning.scene_workers import scene_workers

__all__ = ["SceneConfig", "budget_fields", "with_unseen_margin", "with_seen_between", "with_sparse_between",
           "with_feature_grasps", "with_shadow_depth", "MAX_SHADOW_DEPTH", "SHADOW_DEPTH", "SHADOW_ALONG",
           "SHADOW_FINGER_SHARE",
           "with_pose_error", "FEATURE_GRASPS", "SPARSE_BETWEEN", "SPARSE_SHARE",
           "MAX_POSE_ERROR", "MAX_UNSEEN_MARGIN", "MAX_SCENE_EXTENT",
           "SCENE_BYTES_PER_POINT", "SCENE_FIT_POINTS", "SCENE_COLLISION_TOLERANCE", "SCENE_MAX_NOISE_RATIO"]

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
#: <graspsim.planning.planner.PlannerConfig.collision_tolerance>`): a grasp adapted to a segment's
#: identified primitive is rejected when it comes this close to touching it. The primitive
#: is fitted to a depth camera's points -- the default sensor's noise is 1.8-2.8 mm at the
#: camera's 0.6-0.8 m, its depth step 1 mm -- so it is not known to the FS maps' 0.25 mm;
#: checking to 1 mm takes about a sixteenth of their finest collision samples.
SCENE_COLLISION_TOLERANCE = 0.001


#: The largest noise a scene segment may have for its size (``IdentifyConfig.max_noise_ratio``: a
#: fraction of its bounding-box diagonal; the default's 3 % suits the paper's clouds). A depth
#: camera's noise at a table's 0.6-0.8 m (1.8-2.8 mm for the default sensor) is 3 % of a 6-9 cm
#: object: a Lego brick (its studs' roughness on top, 2.2 mm estimated over a 5.2 cm segment) was
#: never identified, so never grasped (the Lego brick left with no grasp in household-tuning
#: piles). 5 %: objects from about 4.5 cm.
SCENE_MAX_NOISE_RATIO = 0.05


def _scene_planner() -> PlannerConfig:
    # no cloud filter; grasps fitted to the cloud's own features (PlannerConfig.features) where the parts give too
    # few, in the scenes SceneConfig.feature_grasps says (by default where objects are known to stand apart);
    # one contact borne out even without a viewpoint: a segment is not all of its object (thinned, cut at creases);
    # resting boxes completed down to the table (their hidden depth, a guess of a few mm, bounded by it);
    # a box's unmeasured depth at least what the view can tell from its seen face;
    # box parts that are one box (a carton cut into parallel slabs) merged;
    # with a viewpoint, the robust score keeps the fingers UNSEEN_MARGIN off the object's own unseen back;
    # stored grasps predicted far under the table not scaled (the table filter drops them);
    # a low-profile grasp's pose error counts the way up too (its pads lifted off a thin part);
    # the scoring budget to grasps that hold no point of the scene at their pose (in a pile every best-graded
    # grasp of a lying bottle can close on a neighbour), and to grasps that close on points of the object itself
    return PlannerConfig(robust=RobustConfig(unseen_margin=UNSEEN_MARGIN, lift_ceiling=LIFT_CEILING),
                         identify=IdentifyConfig(fit_points=SCENE_FIT_POINTS, max_noise_ratio=SCENE_MAX_NOISE_RATIO),
                         collision_tolerance=SCENE_COLLISION_TOLERANCE, clear_observed=False, features=FeatureConfig(),
                         both_contacts_all_round=False, complete_to_table=True,
                         hidden_depth=True, merge_boxes=True, table_skip=SCENE_TABLE_SKIP, clear_first=True,
                         seen_between=SEEN_BETWEEN)


#: Segments planned together while a scene is planned lazily (``SceneConfig.good_enough``):
#: a constant, not the worker count, so which segments are planned does not depend on it.
LAZY_BATCH = 2

#: Where a scene segment's planning adds grasps on its cloud's own features (``PlannerConfig.features``,
#: when its parts give too few): ``"apart"`` only in scenes whose objects are known to stand apart
#: (``SceneConfig.min_gap`` given: a packed table), where a segment is one whole object; ``"fallback"``
#: (the default) as ``"apart"``, and in any other scene for a frame planned afresh (``plan_scene`` with no
#: ``previous`` frame) whose parts give no grasp at all (every segment without a grasp is planned again
#: with them, and as each other model its clusters fitted, keeping the plan whose best grasp scores
#: highest: a pile that would otherwise end with objects left and nothing planned); ``"always"``;
#: ``"never"``. From E10's tuning sets
#: (docs/results.md, "Feature grasps in scenes", "Feature grasps as a pile's fallback"): on packed
#: tables they removed more objects (a rounded blob seen from one side is fitted as a plate too wide to
#: grasp; a bowl as a sphere); in piles, where a segment can be two touching objects or a part of one,
#: their grasps closed on nothing or dropped more often and the ten-object piles lost objects and
#: planning time -- but as the last resort of a frame with no other grasp they removed most of the
#: objects that would have been left.
FEATURE_GRASPS = ("apart", "fallback", "always", "never")

#: A scene grasp whose closing region holds fewer than this many of its own segment's points
#: (``SceneConfig.sparse_between``; the count ``PlannerConfig.seen_between`` floors, at the opening
#: executed: :meth:`~graspsim.grippers.spec.GripperSpec.points_between`) keeps :data:`SPARSE_SHARE` of its
#: robust score: better-seen grasps are tried first, and it stays a fallback for an object that has no
#: other. Such a grasp closes where the camera saw little of the object, on a fitted part's
#: extrapolation -- a thin plate's edge, a box fitted past a blob's flank -- and the robust score, which
#: knows the fit, not how much of it was seen, does not tell it apart: on E10's tuning sets (both, pile
#: and packed, 5 objects, no execution error) it lifted its target clearly less often than the grasps
#: with 30 or more, the jaws mostly closing on nothing (``experiments/study_seen_between.py``;
#: docs/results.md, *Grasps that close on what was seen*).
SPARSE_BETWEEN = 30
#: The share of its robust score a sparse grasp keeps (:data:`SPARSE_BETWEEN`): about the ratio of the
#: two groups' lift rates in that study, pile and packed pooled (the packed tables' alone is lower).
SPARSE_SHARE = 0.8


#: [m] The deepest shadow a scene's planning keeps clear behind a neighbour's seen points
#: (:attr:`SceneConfig.shadow_depth`): past a table-top object's depth.
MAX_SHADOW_DEPTH = 0.1

#: [m] The shadow depth scene planning keeps clear behind a neighbour's seen points where
#: objects may touch (:attr:`SceneConfig.shadow_depth`'s default). In piles a finger that met
#: a neighbour had gone 37-70 mm behind the surface the camera saw of it, into its hidden
#: body (``experiments/study_start_collisions.py``, household-tuning ten-object piles). Chosen
#: on E10's tuning sets (5 seeds x 20 scenes of 5 objects, no execution error, against the same
#: scenes without it): random-tuning piles GSR 95.5 -> 98.2 %, DR 97.8 -> 99.0 %
#: (``start_collision_neighbour`` 6 -> 1, ``no_contact`` 6 -> 1); household-tuning piles GSR
#: 97.8 % both, DR 97.6 -> 98.2 %. On packed tables, whose objects stand apart, it changed
#: little (GSR +0.2 points on both sets, DR 0 and -0.2) and cost planning time, so a known gap
#: turns it off. docs/scenes.md.
SHADOW_DEPTH = 0.03

#: A shadow's samples lie this many times farther apart along the camera's rays than across
#: them (:func:`~graspsim.planning.scene.shadow_step`; the grid across is ``solid_step``), and
#: at most :data:`SHADOW_FINGER_SHARE` of the gripper's thinnest finger side apart, so that a
#: finger crossing the rays within a shadow still holds a sample: 8 mm for the Festo's 10 mm
#: finger at the 4 mm grid. A segment's obstacles held several times more shadow samples than
#: camera points, and every check of a grasp against them paid for it.
SHADOW_ALONG = 2.0
SHADOW_FINGER_SHARE = 0.8


@dataclass(frozen=True)
class SceneConfig:
    """planner: the per-segment planner settings (its ``table`` is replaced by the
    fitted plane; by default robust identification on at most :data:`SCENE_FIT_POINTS`
    points of a segment, ``IdentifyConfig(fit_points=None)`` for all of them; neither
    ``clear_observed``; grasps on the cloud's own features, ``features``, where ``feature_grasps`` says).
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
    per_segment: grasps scored per part of a segment at most (and as many for the grasps on
    its cloud's own features, with ``PlannerConfig.features`` on); enough: planning of a segment
    stops at this many grasps with a robust score > 0 (in a lazily planned scene, once one of
    them also reaches ``good_enough``, or when its budget is spent); keep: grasps per segment in the
    scene ranking; clearance [m]: the gripper's clearance above the table; reuse_tol
    [m]: how far points may move between frames for a segment to count as unchanged
    (``plan_scene(previous=...)``); up: the
    table's upward direction if known (cloud frame); workers: processes the segments are
    identified on (None: one per core; 1: in this process; see
    :mod:`~graspsim.planning.scene_workers` -- the result does not depend on it);
    good_enough: None plans every segment that needs it (every object's grasps ranked:
    ``plan-scene``, the clutter environment's candidates); a score in (0, 1]: the segments
    are planned highest first, :data:`LAZY_BATCH` at a time, until the scene holds a grasp
    whose robust score reaches it, and the rest are left ``"deferred"`` (no grasps; the
    next frame plans them when it needs them) -- a clutter-removal loop executes one grasp
    a look (:attr:`graspsim.tabletop.clutter.ClutterConfig.good_enough`); each segment is
    planned until a grasp reaches it (see ``enough``), and an unchanged segment whose
    remembered grasps are under it is planned again once a neighbour near it is gone
    (:func:`~graspsim.planning.scene_segments.settled_plan`); feature_grasps: where a segment's
    planning adds grasps on its cloud's own features (the planner's ``features``, when the parts give too
    few): one of :data:`FEATURE_GRASPS`, by default ``"fallback"``: in scenes with a ``min_gap``, and
    in others only for a frame planned afresh (no ``previous``) whose parts give no grasp at all (with
    the other models its clusters fitted, too: the plan whose best grasp scores highest is kept);
    sparse_between: a grasp closing on fewer of its segment's points than this keeps
    :data:`SPARSE_SHARE` of its robust score (:data:`SPARSE_BETWEEN`, the default; 0: off);
    shadow_depth [m]: where objects may touch (no ``min_gap``), with the camera's viewpoint
    known and ``neighbours`` on, the space up to this far behind each other segment's seen
    points, along the camera's rays, is one more obstacle of a segment's grasps (an object
    goes on behind its seen front; sampled on a ``solid_step`` grid across the rays and more
    sparsely along them, :func:`~graspsim.planning.scene.shadow_step`, above the table);
    :data:`SHADOW_DEPTH`, the measured default; 0: off."""

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
    good_enough: float | None = None
    feature_grasps: str = "fallback"
    sparse_between: int = SPARSE_BETWEEN
    shadow_depth: float = SHADOW_DEPTH

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE.saying("> 0 m"), "plane_sigma", "table_band", "max_height", "voxel", "max_radius",
                     "reach", "solid_step", "reuse_tol", owner="SceneConfig")
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
        check_fields(self, integer(1), "plane_repetitions", "min_points", "per_segment", "enough", "keep",
                     owner="SceneConfig")
        check_fields(self, integer(0), "sparse_between", owner="SceneConfig")
        if isinstance(self.shadow_depth, bool) or not isinstance(self.shadow_depth, (int, float)) \
                or not 0 <= self.shadow_depth <= MAX_SHADOW_DEPTH:
            raise InvalidParameterError(f"SceneConfig.shadow_depth must be in [0, {MAX_SHADOW_DEPTH:g}] m (0: off), "
                                        f"got {self.shadow_depth!r}")
        scene_workers(self.workers)  # validates it
        if self.good_enough is not None and not (isinstance(self.good_enough, (int, float))
                                                 and not isinstance(self.good_enough, bool)
                                                 and 0 < self.good_enough <= 1):
            raise InvalidParameterError(f"SceneConfig.good_enough must be a robust score in (0, 1] or None, "
                                        f"got {self.good_enough!r}")
        if self.plane_confidence is not None and not 0 < self.plane_confidence < 1:
            raise InvalidParameterError(f"SceneConfig.plane_confidence must be in (0, 1) or None, "
                                        f"got {self.plane_confidence!r}")
        if self.feature_grasps not in FEATURE_GRASPS:
            raise InvalidParameterError(f"SceneConfig.feature_grasps must be one of {', '.join(FEATURE_GRASPS)}, "
                                        f"got {self.feature_grasps!r}")
        if not isinstance(self.planner, PlannerConfig) or self.planner.rank != "robust":
            raise InvalidParameterError("SceneConfig.planner must be a PlannerConfig ranking by the robust score "
                                        f"(the scene check is part of it), got {self.planner!r}")

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "planner"}

    @property
    def segment_features(self) -> FeatureConfig | None:
        """The feature-grasp settings a segment of this scene is planned with: the planner's
        ``features`` where :attr:`feature_grasps` applies to this scene, else None (``"fallback"``
        outside a scene with a ``min_gap``: :func:`~graspsim.planning.scene.plan_scene` turns them
        on for a frame with no other grasp)."""
        apart = self.feature_grasps in ("apart", "fallback") and self.min_gap is not None
        on = self.feature_grasps == "always" or apart
        return self.planner.features if on else None

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


#: [m] The widest unseen margin a scene's planning takes (:func:`with_unseen_margin`): 10 cm is
#: past any table-top object's depth the gripper can close across.
MAX_UNSEEN_MARGIN = 0.1


def with_unseen_margin(scene: SceneConfig, margin: float | None) -> SceneConfig:
    """``scene`` with its planner's robust score keeping ``margin`` [m] off an object's
    unseen back (``RobustConfig.unseen_margin``; :data:`graspsim.maps.robust.UNSEEN_MARGIN`
    the measured value and the scene planner's default; 0: none); None: ``scene`` itself.
    The one path from a margin a user gives (``graspsim scene`` / ``plan-scene
    --unseen-margin``, E10 ``--unseen-margin``) to the planner; a margin outside [0,
    :data:`MAX_UNSEEN_MARGIN`] m is an :class:`~graspsim.errors.InvalidParameterError`."""
    from dataclasses import replace

    if margin is None:
        return scene
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not 0 <= margin <= MAX_UNSEEN_MARGIN:
        raise InvalidParameterError(f"the unseen margin must be in [0, {MAX_UNSEEN_MARGIN:g}] m "
                                    f"(the measured and default: 0.02; 0: none), got {margin!r}")
    planner = scene.planner
    return replace(scene, planner=replace(planner, robust=replace(planner.robust, unseen_margin=float(margin))))


def with_seen_between(scene: SceneConfig, points: int | None) -> SceneConfig:
    """``scene`` with its planner keeping only grasps that close on at least ``points`` of
    their own segment's points (``PlannerConfig.seen_between``;
    :data:`~graspsim.planning.observed.SEEN_BETWEEN` the measured value and the scene
    planner's default; 0: off); None: ``scene`` itself. The one path from a count a user
    gives (``graspsim scene`` / ``plan-scene --seen-between``, E10 ``--seen-between``) to
    the planner; anything but a whole number >= 0 is an
    :class:`~graspsim.errors.InvalidParameterError`."""
    from dataclasses import replace

    if points is None:
        return scene
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 0:
        raise InvalidParameterError(f"the points a grasp must close on must be a whole number >= 0 (the measured "
                                    f"and default: {SEEN_BETWEEN}; 0: off), got {points!r}")
    return replace(scene, planner=replace(scene.planner, seen_between=int(points)))


def with_sparse_between(scene: SceneConfig, points: int | None) -> SceneConfig:
    """``scene`` with a grasp closing on fewer than ``points`` of its own segment's points
    keeping :data:`SPARSE_SHARE` of its score (``SceneConfig.sparse_between``;
    :data:`SPARSE_BETWEEN` the measured value and the default; 0: off); None: ``scene`` itself.
    The one path from a count a user gives (``graspsim scene`` / ``plan-scene
    --sparse-between``, E10 ``--sparse-between``) to the planner; anything but a whole number
    >= 0 is an :class:`~graspsim.errors.InvalidParameterError`."""
    from dataclasses import replace

    if points is None:
        return scene
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 0:
        raise InvalidParameterError(f"the points below which a grasp's score is discounted must be a whole number "
                                    f">= 0 (the measured and default: {SPARSE_BETWEEN}; 0: off), got {points!r}")
    return replace(scene, sparse_between=int(points))


def with_shadow_depth(scene: SceneConfig, depth: float | None) -> SceneConfig:
    """``scene`` with the space up to ``depth`` [m] behind each neighbour's seen points kept
    clear where objects may touch (``SceneConfig.shadow_depth``; :data:`SHADOW_DEPTH` the measured
    value and the default; 0: off); None: ``scene`` itself. The one
    path from a depth a user gives (E10 ``--shadow-depth``) to the planner; a depth outside
    [0, :data:`MAX_SHADOW_DEPTH`] m is an :class:`~graspsim.errors.InvalidParameterError`."""
    from dataclasses import replace

    if depth is None:
        return scene
    return replace(scene, shadow_depth=depth)  # SceneConfig checks the bounds


def with_feature_grasps(scene: SceneConfig, when: str | None) -> SceneConfig:
    """``scene`` with its segments given grasps on their cloud's own features ``when`` (one of
    :data:`FEATURE_GRASPS`: ``SceneConfig.feature_grasps``); None: ``scene`` itself. The one
    path from a user's choice (``graspsim scene`` / ``plan-scene --feature-grasps``, E10
    ``--feature-grasps``) to the planner; anything else is an
    :class:`~graspsim.errors.InvalidParameterError`."""
    from dataclasses import replace

    if when is None:
        return scene
    if when not in FEATURE_GRASPS:
        raise InvalidParameterError(f"feature grasps must be one of {', '.join(FEATURE_GRASPS)} (the default, "
                                    f"fallback: where objects are known to stand apart, elsewhere only when "
                                    f"nothing else gives a grasp), got {when!r}")
    return replace(scene, feature_grasps=when)


#: The largest pose error a scene's planning takes (:func:`with_pose_error`): 2 cm and 10 deg
#: sigmas at the TCP, past which a two-jaw grasp of a table-top object is a guess.
MAX_POSE_ERROR = (0.02, 10.0)


def with_pose_error(scene: SceneConfig, position_sigma: float, rotation_deg: float) -> SceneConfig:
    """``scene`` with its planner's robust score judging every grasp under the robot's pose
    error: Gaussian sigmas at the TCP, ``position_sigma`` [m] and ``rotation_deg`` [deg]
    (``RobustConfig.position_sigma`` / ``rotation_sigma``; the default 3 mm / 2 deg,
    :data:`graspsim.maps.robust.POSITION_SIGMA`). The one path from the accuracy a user
    states (``graspsim plan-scene --pose-error``) to the planner, as ``graspsim scene
    --noise`` (``ClutterConfig.plan_for_execution``) passes the simulated arm's. A sigma
    outside [0, :data:`MAX_POSE_ERROR`] is an :class:`~graspsim.errors.InvalidParameterError`."""
    import math
    from dataclasses import replace

    values = (position_sigma, rotation_deg)
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in values) or not (
            0 <= position_sigma <= MAX_POSE_ERROR[0] and 0 <= rotation_deg <= MAX_POSE_ERROR[1]):
        raise InvalidParameterError(f"the pose error must be a position sigma in [0, {MAX_POSE_ERROR[0]:g}] m and a "
                                    f"rotation sigma in [0, {MAX_POSE_ERROR[1]:g}] deg (default 0.003 m, 2 deg), "
                                    f"got {position_sigma!r} m, {rotation_deg!r} deg")
    planner = scene.planner
    robust = replace(planner.robust, position_sigma=float(position_sigma), rotation_sigma=math.radians(rotation_deg))
    return replace(scene, planner=replace(planner, robust=robust))
