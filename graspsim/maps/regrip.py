"""A map made for gripper A adapted to gripper B by Combined scaling (paper section 5).

"The Combined scaling algorithm takes gripper dimensions into account. Therefore, using
this algorithm, it is also possible to use a gripper with different dimensions for map
adaptation." The object stays; what changes is the gripper, so only A's successful
grasps are moved (the paper's assumption: unsuccessful grasps stay unsuccessful), each
keeping its contacts, closing axis and orientation:

* **Quality pose**: the grasp point keeps its place on the object and its place along
  the pad in pad-normalised coordinates -- a contact at fraction s of A's usable pad
  (between the margins) sits at fraction s of B's -- and B's wrist follows from B's
  kinematics (:meth:`GripperSpec.wrist_from_grasp_point`).
* **Feasibility pose**, where the Quality pose collides: A's wrist stays where it was
  (the object did not change, so the Feasibility displacement is zero) and the contact
  slides along B's pad to where B's finger meets the grasp point -- clipped to B's pad,
  the nearest B can come to A's wrist.

A grasp is kept if its contact width fits B's opening range (width + 2 x B's approach
clearance <= B's largest opening), the pose is collision-free for B, and its grade is
above ``keep_min_grade``. The paper's grade depends on the contacts only, so it stays; a
map graded by a gripper-dependent model (``meta.quality["grade_model"]``, e.g.
``pad_contact``) is re-graded for B. Robust scores were A's and are dropped (NaN).

The adapted map records B as its gripper and A under ``meta.extra["source_gripper"]``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.collide import grasps_collision_free
from graspsim.maps.graspmap import OPTIONAL_COLUMNS, GraspabilityMap, GripperAdaptation
from graspsim.maps.map_config import MapConfig
from graspsim.maps.rowids import row_ids
from graspsim.transforms import quat_to_matrix

__all__ = ["adapt_to_gripper", "pad_depth"]
log = logging.getLogger(__name__)


def pad_depth(depth: np.ndarray, source: GripperSpec, target: GripperSpec) -> np.ndarray:
    """Contact depths (N,) [m] on ``source``'s pad carried to ``target``'s pad in
    pad-normalised coordinates: the same fraction of the usable pad (between the
    contact-depth margins)."""
    s = (np.asarray(depth, float) - source.depth_lo) / _span(source)
    return target.depth_lo + np.clip(s, 0.0, 1.0) * _span(target)


def _span(g: GripperSpec) -> float:
    return g.depth_hi - g.depth_lo


def _approach(q: np.ndarray) -> np.ndarray:
    """(N, 3) wrist z axes of unit quaternions (N, 4) w, x, y, z (the third column of
    the rotation matrix, without building the matrices)."""
    w, x, y, z = np.asarray(q, float).T
    a = np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    # to 1e-7, below the stored float32 quaternions' own precision: an axis-aligned
    # approach (a box face's) comes out exact, so wrists land where the FS kernel puts them
    # (on the voxel grid's edges, where a last-bit difference changes the voxel)
    return np.round(a, 7)


def _grid_index(depth: np.ndarray, gripper: GripperSpec, step: float) -> np.ndarray:
    """(N,) index of the nearest of ``gripper``'s sampled contact depths."""
    n = gripper.contact_depth_count(step)
    return np.clip(np.rint((depth - gripper.depth_lo) / step), 0, n - 1).astype(np.int64)


def _first_of_each(rows: np.ndarray, key: np.ndarray) -> np.ndarray:
    """``rows`` keeping the first of each ``key`` (keys (len(rows),) >= 0), in order."""
    key = np.asarray(key, np.int64)
    n = len(key)
    if n == 0 or int(key.max()) >= 8 * n + 4096:  # keys too sparse for a table of them
        _, first = np.unique(key, return_index=True)
        return rows[np.sort(first)]
    first = np.full(int(key.max()) + 1, n, np.int64)
    np.minimum.at(first, key, np.arange(n))  # a table instead of a sort
    return rows[np.sort(first[first < n])]


def adapt_to_gripper(gmap: GraspabilityMap, gripper: GripperSpec, *, config: MapConfig | None = None,
                     source_min_grade: float | None = None,
                     keep_min_grade: float | None = None) -> GraspabilityMap:
    """``gmap`` (made for the gripper its metadata records) adapted to ``gripper``.

    source_min_grade: A's grasps above this grade are adapted (None: the map's
        threshold, as the paper scales only successful grasps; 0 adapts every grasp).
    keep_min_grade: adapted grasps above this grade are kept (None: the threshold).
    config: collision-check settings and the contact-depth step (default: the map's).
    Contact depths land on B's depth grid (as B's own map samples them); A's rows that
    become one pose of B give one row. Rows keep the source map's order. Raises
    InvalidParameterError for a map whose object is not a primitive or compound (a
    mesh map: its geometry is not in the map).
    """
    t0 = time.perf_counter()
    if not isinstance(gripper, GripperSpec):
        raise InvalidParameterError(f"gripper must be a GripperSpec, got {type(gripper).__name__}")
    obj = gmap.meta.object
    if obj.get("file") or not (obj.get("primitive") or obj.get("parts")):
        raise InvalidParameterError(
            "adapting to another gripper needs the map's object geometry (a primitive or a "
            f"compound); this map's object is {obj.get('file') or 'not recorded'}")
    source, shape = gmap.meta.gripper_spec, gmap.meta.shape
    cfg = config or gmap.meta.map_config
    for name, value in (("source_min_grade", source_min_grade), ("keep_min_grade", keep_min_grade)):
        if value is not None and not (isinstance(value, (int, float, np.number)) and 0 <= float(value) < 1):
            raise InvalidParameterError(f"{name} must be a grade in [0, 1) (grasps above it are carried; None: "
                                        f"the map's threshold {gmap.threshold:g}), got {value!r}")
    src_min = gmap.threshold if source_min_grade is None else float(source_min_grade)
    rows = np.flatnonzero(gmap.above(src_min))
    quat = gmap.wrist_quat[rows]
    z = _approach(quat)
    gp, width = gmap.grasp_point[rows].astype(float), gmap.width[rows].astype(float)
    d_src = source.contact_depth(gp, gmap.wrist_position[rows].astype(float), z)
    fits = (width >= max(cfg.min_width, gripper.min_opening) - 1e-9) \
        & (width + 2 * gripper.approach_clearance <= gripper.max_opening + 1e-9)
    line = row_ids(gmap.contacts[rows])
    pose = row_ids(line[:, None], quat)  # a closing line at one orientation
    n_grid = gripper.contact_depth_count(cfg.depth_step)
    grid = gripper.contact_depths(cfg.depth_step)

    def check(cand: np.ndarray, idx: np.ndarray) -> np.ndarray:
        return grasps_collision_free(shape, gripper, gp[cand], quat_to_matrix(quat[cand]), grid[idx],
                                     width[cand], cfg, line=line[cand])

    # Quality pose: the grasp point kept, the contact at the same place on the pad
    q_idx = _grid_index(pad_depth(d_src, source, gripper), gripper, cfg.depth_step)
    cand = _first_of_each(np.flatnonzero(fits), (pose * n_grid + q_idx)[fits])
    free = check(cand, q_idx[cand])
    kept, kept_idx = cand[free], q_idx[cand[free]]
    # Feasibility pose: A's wrist kept, the contact slid along B's pad to the grasp point
    f_idx = _grid_index(gripper.fingertip_z - (source.fingertip_z - d_src), gripper, cfg.depth_step)
    rest = cand[~free]
    rest = rest[f_idx[rest] != q_idx[rest]]
    key = pose * n_grid + f_idx
    rest = rest[~np.isin(key[rest], pose[kept] * n_grid + kept_idx)]
    rest = _first_of_each(rest, key[rest])
    free_f = check(rest, f_idx[rest])
    order = np.argsort(np.concatenate([kept, rest[free_f]]), kind="stable")
    keep = np.concatenate([kept, rest[free_f]])[order]
    depth = grid[np.concatenate([kept_idx, f_idx[rest[free_f]]])[order]]
    out = replace(gmap.select(rows[keep]), **{k: None for k in OPTIONAL_COLUMNS},
                  wrist_position=gripper.wrist_from_grasp_point(gp[keep], z[keep], depth))
    extra = {**gmap.meta.extra, "source_gripper": source.to_dict(), "source_method": gmap.meta.method,
             **GripperAdaptation(source_grasps=int(len(rows)), fit_opening=int(fits.sum()),
                                 quality_pose=int(len(kept)), feasibility_pose=int(free_f.sum()),
                                 source_min_grade=src_min).to_extra()}
    out = _regraded(out.with_meta(gripper=gripper.to_dict(), method="gripper/combined", extra=extra,
                                  resolution={**gmap.meta.resolution, "n_depth": n_grid}))
    keep_min = out.threshold if keep_min_grade is None else float(keep_min_grade)
    out = out.select(out.above(keep_min))
    return out.with_meta(timing={"total": time.perf_counter() - t0})


def _regraded(gmap: GraspabilityMap) -> GraspabilityMap:
    """The map re-graded for its (new) gripper when its grade model depends on the
    gripper (a recorded ``grade_model``); the paper's grade sees only the contacts.
    A model fitted for another gripper is replaced by the one fitted for this gripper
    (``pad_contact``: the one shipped for it) or, when there is none, by the paper's
    grade the map was graded with before (logged)."""
    spec = gmap.meta.quality.get("grade_model")
    if not spec or not len(gmap):
        return gmap
    from graspsim.errors import GripperError
    from graspsim.grades.models import FESTO, LogisticGrade, PaperGrade, get_grade
    from graspsim.grades.paper import QualityModel

    name = str(gmap.meta.gripper.get("name"))
    model = LogisticGrade.from_dict(spec)
    if (model.gripper or {"name": FESTO})["name"] != name:
        try:
            model = get_grade(model.name, gripper=name) if model.name == "pad_contact" else None
        except GripperError:
            model = None
        if model is None:
            log.warning("no %r grade model fitted for gripper %r: the adapted map takes the paper's grade",
                        spec.get("name"), name)
            model = PaperGrade(QualityModel.from_meta(gmap.meta.quality))
    return model.apply(gmap)
