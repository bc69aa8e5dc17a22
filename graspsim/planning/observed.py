"""What the observed cloud rules out of -- and adds to -- one plan's grasps (robust mode).

The adapted map's grasps are made on the identified primitives; the observed points are
the object. For each plan made from a cloud in robust identification mode,
:class:`ObservedChecks` holds the cloud once and applies, batch by batch:

* :meth:`~ObservedChecks.borne_out`: the cloud bears each grasp's contacts out
  (:mod:`graspsim.maps.agreement`);
* :meth:`~ObservedChecks.clear`: no grasp is offered whose gripper (fingers, jaws,
  housing, arm keep-out, as the robust score models it) holds an observed point at its
  nominal pose, at the opening it is executed with (``PlannerConfig.clear_observed``;
  :func:`clear_of_cloud`): where the primitives miss the object -- a bowl's rim, a
  tool's handle, a rounded box's bulge -- the fingers would start inside it;
* :meth:`~ObservedChecks.feature_batch`: where the parts give too few grasps expected to
  succeed, grasps fitted to the cloud's own features (:mod:`graspsim.maps.feature_grasps`),
  through the same checks and the robust score without its primitives term.

:meth:`~ObservedChecks.record` is what the map records of them (``extra["observed"]``,
``extra["features"]``).
"""

from __future__ import annotations

import time
from dataclasses import replace
from functools import cached_property

import numpy as np

from graspsim.geometry.spacing import median_spacing
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.agreement import ObservedSurface
from graspsim.maps.feature_grasps import feature_columns
from graspsim.maps.graspmap import GraspabilityMap, MapMeta
from graspsim.maps.occlusion import ViewDepth, finger_occlusion
from graspsim.maps.robust import RobustConfig, cloud_in_object, score_map, score_rows, view_of
from graspsim.maps.rowids import first_rows, row_ids
from graspsim.maps.table_clearance import clears_table
from graspsim.planning.plan_results import GraspBatch

__all__ = ["ObservedChecks", "clear_of_cloud", "first_clear", "HIDDEN_FACE_ANGLE", "MEASURED_SHARE",
           "SEEN_BETWEEN", "SEEN_FINGER_SHARE", "SPACING_TOLERANCE", "UNSEEN_CONE_DEG"]

#: A box part's extent along an axis counts as measured by a single view when at least this share
#: of its points lie on faces running along the axis (normal > 60 deg from it): ObservedChecks.unseen_depth
MEASURED_SHARE = 0.1
#: A grasp closes across an unmeasured extent when its closing axis lies within this angle [deg]
#: of it: of a box part's unmeasured axis, of a curved part's line of sight (ObservedChecks.unseen_depth)
UNSEEN_CONE_DEG = 45.0

#: A grasp across a box part's unmeasured depth (ObservedChecks.unseen_depth) is still offered when at most
#: this share of its finger volume, at its pre-grasp opening, lies in space the view did not see
#: (:func:`~graspsim.maps.occlusion.finger_occlusion`): its far finger then goes where the camera saw through to
#: something farther, so the object does not go on there. A thin part standing up (a domino on its edge, seen
#: from above and in front: its top edge too narrow for its normals to count) has its grasps across its
#: thickness back; a carton seen from the front, whose far finger goes into the carton's own shadow, does not.
#: The value: in ``experiments/study_occlusion.py``'s household-tuning run none of the 126 executed grasps with
#: at most 5 % of their finger volume unseen started in collision, 4 of the 23 with 5-10 % did.
SEEN_FINGER_SHARE = 0.05

#: The points of its own segment a grasp planned in a scene must have between its pads
#: (``PlannerConfig.seen_between``, as the scene planner sets it; :meth:`ObservedChecks.closes_on_seen`).
#: Measured by ``experiments/study_seen_between.py`` on E10's tuning sets (household-tuning and
#: random-tuning, pile and packed, 5 objects, no execution error, E10's first 5 seeds x 10 scenes), the
#: filter off: of 992 executed grasps, the 10 with fewer than 5 of their segment's points between the pads
#: (``Attempt.between``) lifted their target 5 times, 4 closed on nothing; the 982 with 5 or more lifted it
#: 947 times (the median of the grasps that lifted: 115 points). With it on, the same scenes: 3 of the 200
#: episodes went otherwise, all on random-tuning's packed tables, 8 more objects removed. Such a grasp
#: closes where the camera saw little or nothing of the object -- on a fitted part's extrapolation -- and
#: 5 points of the 3 mm grid are some 45 mm^2 of seen surface, so a stray point or two does not count.
SEEN_BETWEEN = 5

#: [deg] A face of a box part turned further than this from the direction to a single view's camera (its
#: outward normal against the direction from the part to the viewpoint; a back face is turned > 90 deg) is
#: hidden from it: the cloud shows it with too few points, if any, to bear a contact out or count against it
#: (at 80 deg a face's projected area is 17 % of its area seen head-on, and the depth noise along the ray
#: lies nearly in the face's plane). ObservedChecks.borne_out.
HIDDEN_FACE_ANGLE = 80.0

#: Where both contacts of a grasp must be borne out (a cloud seen all round), a contact
#: counts as observed within this many median point spacings of a cloud point (or
#: ``PlannerConfig.contact_tolerance``, whichever is larger): on a surface sampled at
#: random, with median nearest-neighbour spacing s, no point lies within r of a surface
#: location with probability 2^-((r / s)^2) -- 0.2 % at 3 s, 4 % at the 4 mm setting in a
#: cloud spaced 1.8 mm (E09's full clouds), 21 % at 4 mm when spaced 2 mm (the tests'
#: synthetic clouds): a true contact in a sampling gap must not read as closing on air.
SPACING_TOLERANCE = 3.0


def clear_of_cloud(gmap, rows: np.ndarray, cloud_obj: np.ndarray, config: RobustConfig = RobustConfig(),
                   gripper: GripperSpec | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Whether the map's ``rows`` hold no observed point in the gripper at their nominal
    pose: (keep (n,) bool, extra opening per side (n,) [m]), the narrowest of
    ``config.openings`` at which the gripper's volume (fingers, jaws, housing, arm
    keep-out, as the robust score models it) holds none of ``cloud_obj`` (M, 3, object
    frame) closer than ``config.margin``; keep False where no opening clears. The
    robust score's own kernel and gripper model at no pose error: no draw, no
    success term, the table and the primitives not asked."""
    nominal = replace(config, position_sigma=0.0, rotation_sigma=0.0, samples=1, terms=("cloud",),
                      success="none", occlusion=False)
    s = score_rows(gmap, rows, cloud_obj, nominal, gripper, with_clearance=False)  # whether, not how far
    keep = s.robust > 0
    return keep, np.where(keep, s.extra_opening, 0.0)


def first_clear(gmap, order: np.ndarray, n: int, cloud_obj: np.ndarray, config: RobustConfig = RobustConfig(),
                gripper: GripperSpec | None = None, also=None) -> tuple[np.ndarray, int]:
    """The first ``n`` rows of ``order`` (the map's rows, best first) whose gripper holds
    no point of ``cloud_obj`` (M, 3, object frame; the object's and its neighbours')
    at its nominal pose at some opening the robust score may choose -- ``config.openings``
    and the wider ``unseen_openings`` -- as :func:`clear_of_cloud` checks them: (those
    rows in ``order``'s order, how many rows were checked). The rows passed over would
    score 0 (the robust score is 0 for a pose that holds a point at every opening), so a
    scoring budget spent on the rows returned goes to grasps that can score. The rows
    are checked in chunks of the rows still wanted (at least 64), stopping once ``n``
    are found; rows after the ``n``-th clear one count as unchecked. ``also``: None, or a
    further test a row must pass (rows (k,) -> (k,) bool, asked of the clear rows only:
    :meth:`ObservedChecks.closes_on_seen`)."""
    order = np.asarray(order, int).reshape(-1)
    if n <= 0 or not len(order):
        return order[:0], 0
    wide = replace(config, openings=tuple(config.openings) + tuple(
        v for v in config.unseen_openings if v > max(config.openings)))
    found: list[np.ndarray] = []
    got = at = 0
    while got < n and at < len(order):
        chunk = order[at:at + max(n - got, 64)]
        ok = np.flatnonzero(clear_of_cloud(gmap, chunk, cloud_obj, wide, gripper)[0])
        if also is not None and len(ok):
            ok = ok[also(chunk[ok])]
        ok = ok[:n - got]
        found.append(chunk[ok])
        got += len(ok)
        # checked: up to the n-th clear row (the clear rows after it in the chunk are not passed over)
        at += int(ok[-1]) + 1 if got >= n else len(chunk)
    return np.concatenate(found), at


class ObservedChecks:
    """The observed ``points`` (N, 3, cloud frame) of one plan and ``cloud_obj`` (the
    points the gripper must keep clear of -- the object's and any obstacles' -- in the
    object frame at ``T_cloud_obj``); ``noise`` [m]: the cloud's sigma estimate;
    ``gripper``, ``quality``: the database's; ``cfg``: the
    :class:`~graspsim.planning.planner.PlannerConfig`."""

    def __init__(self, points: np.ndarray, cloud_obj: np.ndarray | None, T_cloud_obj: np.ndarray, *,
                 viewpoint: np.ndarray | None, noise: float, gripper: GripperSpec, quality, cfg) -> None:
        self.points, self.cloud_obj, self.T_cloud_obj = points, cloud_obj, T_cloud_obj
        self.surface = ObservedSurface(points, viewpoint=viewpoint)
        self.viewpoint = viewpoint
        self.noise, self.gripper, self.quality, self.cfg = float(noise), gripper, quality, cfg
        self.dropped = self.unseen = self.on_nothing = 0
        self.features: int | None = None
        self.view: ViewDepth | None = None  # the depth image of what was seen, cloud frame, if the caller has it
        self.camera: np.ndarray | None = None  # what the camera saw (cloud frame) if cloud_obj holds more
        self._unmeasured: dict[bytes, np.ndarray | None] = {}  # unseen_depth's per-part axes, by part size and pose

    @classmethod
    def of_plan(cls, ident, points, cloud_obj, T_cloud_obj, viewpoint, db, cfg) -> ObservedChecks | None:
        """The checks of a plan whose identification ``ident`` is in robust mode, else
        None (paper mode: the paper's grasps as they are); ``db``: its database."""
        if ident is None or ident.mode != "robust":
            return None
        return cls(points, cloud_obj, T_cloud_obj, viewpoint=viewpoint, noise=ident.noise, gripper=db.gripper,
                   quality=db.quality, cfg=cfg)

    @property
    def min_observed(self) -> int:
        """Contacts of a grasp the cloud must bear out: 1 for a single view (its far
        contact lies where the camera never looked: no evidence either way), 2 for a
        cloud seen all round (no viewpoint; ``PlannerConfig.both_contacts_all_round``,
        off in scene planning) -- there a finger whose closing path meets no
        observed point closes on air: E09's mug, whose half-toroid laid over the rim
        put one contact 9-11 mm above it, the pads meeting the rim with their edges."""
        return 2 if self.surface.viewpoint is None and self.cfg.both_contacts_all_round else 1

    @cached_property
    def spacing(self) -> float:
        """The cloud's median point spacing [m]."""
        return median_spacing(self.surface.points)

    @property
    def contact_tolerance(self) -> float:
        """How near a cloud point must lie to a contact (or its closing path) for the
        cloud to show the finger's touch [m]: ``PlannerConfig.contact_tolerance``; where
        both contacts must be borne out (:attr:`min_observed` 2) at least
        :data:`SPACING_TOLERANCE` median point spacings, so that a sampling gap at either
        contact does not drop a true grasp. A single view, which needs one, keeps the
        setting as it is (scene planning's thinned segments included)."""
        tol = float(self.cfg.contact_tolerance)
        return tol if self.min_observed < 2 else max(tol, SPACING_TOLERANCE * self.spacing)

    def borne_out(self, part_map: GraspabilityMap, T_cloud_map: np.ndarray, prim=None,
                  T_cloud_part: np.ndarray | None = None, bounded: np.ndarray | None = None) -> GraspabilityMap:
        """The grasps of ``part_map`` (frame ``T_cloud_map`` in the cloud's) the observed
        cloud bears out (:meth:`~graspsim.maps.agreement.ObservedSurface.borne_out`, at
        :attr:`contact_tolerance` and :attr:`min_observed`); the answer depends on a
        grasp's contacts alone, so it is found once per closing line.

        A single view cannot bear out a contact on a face it could not see. Of a box
        part ``prim`` (posed at ``T_cloud_part``) closed across an axis whose two faces
        are both hidden from the camera (turned more than :data:`HIDDEN_FACE_ANGLE` from
        it: a block or carton lying with its long sides edge-on to the camera, or away
        from it), neither contact can be; such a grasp is kept when no contact is
        evidence against it and the view measured the part's extent along every axis (a
        seen face runs along each, as the top face spans the block's width and the near
        end its height: :meth:`unseen_depth`'s test) -- the contacts' places and the
        hidden faces' extents are then the seen faces' edges, not a guess
        (``PlannerConfig.hidden_faces``). Without ``prim`` or a viewpoint, or with
        ``hidden_faces`` off: the plain rule. ``bounded`` (k, 3): the part's axes the table
        bounds or its segment's points reach along (its faces' extents along them no guess):
        measured."""
        line = row_ids(part_map.contacts)
        c = part_map.contacts[first_rows(line)].astype(float) @ T_cloud_map[:3, :3].T + T_cloud_map[:3, 3]
        agree, borne = self.surface.evidence(c, tol=self.contact_tolerance, max_angle=self.quality.friction_angle)
        keep = agree & (borne >= self.min_observed)
        hidden = self._hidden_axes(prim, T_cloud_part, bounded)
        if hidden is not None and self.cfg.hidden_faces:
            unseen = agree & (borne == 0) & ~keep
            if unseen.any():
                u = c[:, 1] - c[:, 0]
                u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
                keep |= unseen & np.any(np.abs(u @ hidden.T) >= np.cos(np.radians(45.0)), axis=1)
        return part_map.select(keep[line])

    def _hidden_axes(self, prim, T_cloud_part, bounded: np.ndarray | None = None) -> np.ndarray | None:
        """(k, 3) the axes of box part ``prim`` (at ``T_cloud_part``, cloud frame) whose
        faces a single view could not see (both turned more than :data:`HIDDEN_FACE_ANGLE`
        from the viewpoint), when it measured the part's extent along every axis (so also
        the hidden faces' own extents: a plate fitted to a block's top alone has its height
        guessed, and contacts on its sides would hold the block by its top few mm; an axis in
        ``bounded`` (k, 3), which the table or the segment bounds, counts as measured); None:
        none, not every extent measured, not a box, or no viewpoint."""
        if self.viewpoint is None or prim is None or prim.kind != "box" or T_cloud_part is None:
            return None
        T = np.asarray(T_cloud_part, float)
        to_eye = np.asarray(self.viewpoint, float) - T[:3, 3]
        to_eye /= max(float(np.linalg.norm(to_eye)), 1e-12)
        faces_hidden = np.abs(T[:3, :3].T @ to_eye) <= np.cos(np.radians(HIDDEN_FACE_ANGLE))
        shares = self._along_shares(prim, T)
        if shares is None:
            return None
        measured = shares >= MEASURED_SHARE
        if bounded is not None:  # an extent the table or the segment bounds is no guess
            B = np.asarray(bounded, float).reshape(-1, 3)
            measured |= np.any(np.abs(T[:3, :3].T @ B.T) > np.cos(np.radians(UNSEEN_CONE_DEG)), axis=1)
        if not np.all(measured):  # a face's extent is a guess (a plate fitted to a block's top)
            return None
        axes = T[:3, :3][:, faces_hidden].T
        return axes if len(axes) else None

    def unseen_depth(self, part_map: GraspabilityMap, prim, T_cloud_part: np.ndarray,
                     T_cloud_map: np.ndarray, bounded: np.ndarray | None = None) -> GraspabilityMap:
        """The grasps of ``part_map`` (frame ``T_cloud_map`` in the cloud's) that do not
        close across an extent of part ``prim`` (posed at ``T_cloud_part``) that a single
        view did not measure (within :data:`UNSEEN_CONE_DEG`), unless its fingers stay in
        space the view saw.

        A box's extent along one of its axes is measured where the view shows a face that
        runs along that axis; where the part's points show only the faces across it (fewer
        than ``MEASURED_SHARE`` of them with a surface normal more than 60 deg from the
        axis: a carton seen from the front is fitted as a plate a few mm thick, a gable as
        a slab) the box's depth there is the fit's guess, and a grasp closing across it puts
        its far finger where the object may go on unseen.

        A curved part (cylinder, cone, sphere, half-toroid) shows the view only the side
        turned to the camera: its extent along the line of sight is the fit's extrapolation
        of that side's curvature, right only if the object is the primitive. A grasp
        closing along the line of sight through its grasp point has its near contact on
        the seen side and its far one on the back the camera never saw, where a real
        object goes on as its own shape does (a duck's body fitted as a cylinder from its
        flank: its back reached 10 to 17 mm beyond the fitted cylinder, into the far
        finger); a grasp closing across the line of sight closes on the silhouette's two
        edges, which the view measured.

        Such a grasp is still offered when at most :data:`SEEN_FINGER_SHARE` of its finger
        volume (at its pre-grasp opening) lies in space the view did not see: there the
        camera saw past the part, so the object does not go on where the far finger goes
        (a domino standing on its edge, grasped across its thickness from above).
        ``bounded`` (3,) or (k, 3): a box part's axes the table bounds (the part completed
        down to it: :mod:`~graspsim.planning.table_completion`): measured, whatever its
        faces show.
        Unchanged without a viewpoint (a cloud seen all round shows depths) or with
        ``PlannerConfig.seen_depth`` off."""
        if self.viewpoint is None or not self.cfg.seen_depth or not len(part_map):
            return part_map
        T_map = np.asarray(T_cloud_map, float)
        wrist = T_map[None, :3, :3] @ part_map.wrist_transforms()[:, :3, :]  # (n, 3, 4) rotation and position
        wrist[:, :, 3] += T_map[:3, 3]
        closing = wrist[:, :, 0]
        cone = np.cos(np.radians(UNSEEN_CONE_DEG))
        if prim.kind == "box":
            thin = self._unmeasured_axes(prim, T_cloud_part)
            if thin is not None and bounded is not None:  # the table bounds that extent: measured
                B = np.asarray(bounded, float).reshape(-1, 3)
                thin = thin[np.all(np.abs(thin @ B.T) < cone, axis=1)]
            if thin is None or not len(thin):
                return part_map
            keep = np.all(np.abs(closing @ thin.T) < cone, axis=1)
        else:
            at = np.asarray(part_map.grasp_point, float) @ T_map[:3, :3].T + T_map[:3, 3]
            sight = at - np.asarray(self.viewpoint, float)
            sight /= np.maximum(np.linalg.norm(sight, axis=1, keepdims=True), 1e-12)
            keep = np.abs(np.einsum("ni,ni->n", closing, sight)) < cone
        across = np.flatnonzero(~keep)
        if len(across):  # across the unmeasured extent: offered where the fingers stay in space the view saw
            opening = self.gripper.pregrasp_opening(np.asarray(part_map.width, float)[across])
            f = finger_occlusion(self._view, wrist[across, :, :3], wrist[across, :, 3], opening, self.gripper)
            keep[across] = f <= SEEN_FINGER_SHARE
        self.unseen += int(len(keep) - keep.sum())
        return part_map.select(keep)

    @cached_property
    def _view(self) -> ViewDepth:
        """The depth image, from the viewpoint, of what the camera saw (``camera``, else the
        object's points and any obstacles: ``cloud_obj``, else the plan's points) in the
        cloud frame, as the robust score's occlusion term sees it (``view`` when the
        caller made it already)."""
        if self.view is not None:
            return self.view
        T = np.asarray(self.T_cloud_obj, float)
        cloud = self.camera if self.camera is not None else self.points if self.cloud_obj is None \
            else np.asarray(self.cloud_obj, float) @ T[:3, :3].T + T[:3, 3]
        return ViewDepth(cloud, self.viewpoint)

    @property
    def least_hidden_depth(self) -> float:
        """[m] the least extent a single view leaves a box along an axis it did not measure
        (``PlannerConfig.hidden_depth``): a far face nearer its seen face than the contact
        tolerance plus two noise sigmas lies among that face's own points, which then stand
        as evidence against every contact on it; the view cannot tell such a depth from
        this one."""
        return self.contact_tolerance + 2.0 * self.noise

    def unmeasured_axes(self, prim, T_cloud_part: np.ndarray) -> np.ndarray | None:
        """(k, 3) the axes of box part ``prim`` (posed at ``T_cloud_part``, cloud frame) a
        single view did not measure (see :meth:`unseen_depth`); None: none, too few points,
        or no viewpoint."""
        if self.viewpoint is None:
            return None
        return self._unmeasured_axes(prim, T_cloud_part)

    def _unmeasured_axes(self, prim, T_cloud_part: np.ndarray) -> np.ndarray | None:
        """(k, 3) the axes of box part ``prim`` (posed at ``T_cloud_part``) a single view did
        not measure, in the cloud frame (see :meth:`unseen_depth`); None: too few points on
        the part to tell, or every axis measured."""
        T = np.asarray(T_cloud_part, float)
        along = self._along_shares(prim, T)
        if along is None:
            return None
        axes = T[:3, :3][:, along < MEASURED_SHARE].T  # (k, 3): the unmeasured axes, cloud frame
        return axes if len(axes) else None

    def _along_shares(self, prim, T: np.ndarray) -> np.ndarray | None:
        """(3,) the share of box part ``prim``'s points (posed at ``T``) on faces running
        along each of its axes (normal more than 60 deg from it); None: too few points
        on the part to tell. It depends on the part alone, not on the batch, so it is
        found once per part and plan: a part streams many batches."""
        half = 0.5 * np.array([prim.x, prim.y, prim.z])
        key = half.tobytes() + T.tobytes()
        if key in self._unmeasured:
            return self._unmeasured[key]
        along = None
        local = (self.surface.points - T[:3, 3]) @ T[:3, :3]
        inside = np.flatnonzero(np.all(np.abs(local) <= half + self.cfg.contact_tolerance, axis=1))
        if len(inside) >= 3 * self.surface.k:
            normals = self.surface.normals_at(inside) @ T[:3, :3]  # in the part's frame
            along = np.mean(np.abs(normals) < np.cos(np.radians(60.0)), axis=0)
        self._unmeasured[key] = along
        return along

    def clear(self, batch: GraspabilityMap) -> GraspabilityMap:
        """The batch's grasps whose gripper holds no observed point at the opening each is
        executed with (``PlannerConfig.clear_observed``; unchanged when it is off)."""
        if not self.cfg.clear_observed or self.cloud_obj is None or not len(batch):
            return batch
        # a scored grasp clear at the opening its score chose stays as it is; the others (unscored,
        # or scored 0 at an opening that holds points) are checked at every opening
        clear = np.isfinite(batch.robust) & (np.nan_to_num(batch.clearance, nan=-1.0) >= self.cfg.robust.margin)
        keep = np.ones(len(batch), bool)
        rest = np.flatnonzero(~clear)
        if len(rest):
            ok, extra = clear_of_cloud(batch, rest, self.cloud_obj, self.cfg.robust, self.gripper)
            keep[rest] = ok
            col = batch.robust_extra_opening.copy()
            col[rest] = np.where(ok, extra, np.nan)
            batch = replace(batch, robust_extra_opening=col)
        self.dropped += int(len(keep) - keep.sum())
        return batch.select(keep)

    def closes_on_seen(self, batch: GraspabilityMap, rows: np.ndarray) -> np.ndarray:
        """(k,) bool: whether each of the batch's ``rows`` closes on what the camera saw of
        the object -- at least ``PlannerConfig.seen_between`` of the plan's own points (not
        its obstacles') in its closing region at its pre-grasp opening
        (:meth:`~graspsim.grippers.spec.GripperSpec.points_between`; all True when that is
        0). Counted in the record's ``on_nothing``."""
        rows = np.asarray(rows, int).reshape(-1)
        need = int(self.cfg.seen_between)
        if need <= 0 or not len(rows):
            return np.ones(len(rows), bool)
        T = batch.select(rows).wrist_transforms()  # object frame, as cloud_obj
        own = np.asarray(self.cloud_obj, float)[:len(self.points)]  # the plan's points come first
        ok = self.gripper.points_between(T, self.gripper.pregrasp_opening(batch.width[rows]), own) >= need
        self.on_nothing += int(len(ok) - ok.sum())
        return ok

    def wants_features(self, batches: list[GraspabilityMap]) -> bool:
        """Whether the parts' ``batches`` give fewer grasps expected to succeed (robust
        score > 0; any grasp when unscored) than ``features.min_grasps``."""
        f = self.cfg.features
        usable = sum(int(np.sum(b.robust > 0)) if self.cfg.rank == "robust" else len(b) for b in batches)
        return f is not None and usable < f.min_grasps

    def feature_batch(self, meta: MapMeta, part: int, T_table_obj: np.ndarray | None, view_obj, view,
                      scored_only: bool = False) -> GraspabilityMap:
        """The grasps on the cloud's own features as part ``part`` of a map with ``meta``:
        borne out by the cloud, clear of the table, the best robust-scored against the
        cloud (no primitives term: the parts are what these grasps do without), clear of
        the cloud; ``scored_only``: the scored ones alone."""
        cfg = self.cfg
        gap = 3.0 * self.spacing + 4.0 * self.noise
        up = None if T_table_obj is None else T_table_obj[2, :3]  # the table's normal in the object frame
        fmap = GraspabilityMap(**feature_columns(cloud_in_object(self.points, self.T_cloud_obj), self.gripper,
                                                 self.quality, gap=gap, config=cfg.features, part=part, up=up),
                               meta=meta)
        if len(fmap):
            fmap = self.borne_out(fmap, self.T_cloud_obj)
        if T_table_obj is not None and len(fmap):
            fmap = fmap.select(clears_table(fmap, T_table_obj, self.gripper, cfg.table.clearance))
        if cfg.rank == "robust" and len(fmap):
            rcfg = replace(cfg.robust, terms=tuple(t for t in cfg.robust.terms if t != "primitives"),
                           success="grade")
            rows = np.argsort(-fmap.grade, kind="stable")[:cfg.robust.top]
            fmap = score_map(fmap, self.cloud_obj, rcfg, rows=rows, gripper=self.gripper, viewpoint=view_obj,
                             view=view if view is not None else view_of(self.cloud_obj, view_obj, rcfg)).ranked()
            if scored_only:  # a caller that keeps only scored grasps (a scene): the rest would cost their check
                fmap = fmap.select(np.isfinite(fmap.robust))
        fmap = self.clear(fmap)
        self.features = len(fmap)
        return fmap

    def stream_features(self, batches: list, meta: MapMeta, part: int, T_table_obj, view_obj, view,
                        scored_only: bool, stage, t0: float):
        """The planner's step after the parts: yield the feature grasps' batch
        (:class:`~graspsim.planning.plan_results.GraspBatch`, appended to ``batches``) where the
        parts gave too few grasps; return ``meta.extra`` with :meth:`record` added.
        ``stage``: the plan's :class:`~graspsim.planning.stages.StageClock`; ``t0``: its start."""
        if self.wants_features(batches):
            stage.start()
            batch = self.feature_batch(meta, part, T_table_obj, view_obj, view, scored_only)
            stage.lap("features")
            if len(batch):
                batches.append(batch)
                yield GraspBatch(batch, time.perf_counter() - t0)
        return {**meta.extra, **self.record(part)}

    def record(self, parts: int) -> dict:
        """The map's record of these checks (``extra`` entries); ``parts``: the parts
        planned (the feature grasps' part index). ``unseen_margin``: the margin the object's
        grasps were scored with (``RobustConfig.unseen_margin``: the settings', or the
        object's own where the scene planner widened it for a face seen alone,
        ``planner._face_depth``; the score bounds it further by the object's shadow and
        thickness)."""
        f = self.cfg.features
        return {"observed": {"clear_observed": bool(self.cfg.clear_observed), "dropped": self.dropped,
                             "seen_depth": bool(self.cfg.seen_depth), "unseen_depth": self.unseen,
                             "seen_between": int(self.cfg.seen_between), "on_nothing": self.on_nothing,
                             "contact_tolerance": self.contact_tolerance, "min_observed": self.min_observed,
                             "unseen_margin": float(self.cfg.robust.unseen_margin)},
                "features": None if f is None else {**f.to_dict(), "grasps": self.features or 0, "part": parts}}
