"""Map scaling for familiar objects (paper 2.4): Quality, Feasibility, Combined.

A full-scale (FS) map of a primitive is adapted to a size variant of the same
primitive by moving only the FS map's successful grasps (paper: unsuccessful grasps are
assumed to stay unsuccessful), keeping each grasp's orientation:

* **Quality** (eqs. 3-4): the grasp point keeps its place relative to the shape -- it
  is mapped with the primitive's shape-normalised coordinates (per-axis factors
  R_N/R_O, H_N/H_O for a cylinder) -- and the wrist follows at the same contact depth.
* **Feasibility** (eqs. 5-6): the wrist is translated with the change in dimensions --
  by the displacement of the surface point nearest to it (for a cylinder: the radius
  change outwards, the end faces' shift along the axis) -- and the grasp point moves
  with it.
* **Combined**: Quality first; where the Quality pose collides, the finger length is
  used: the wrist slides along the approach axis by the Feasibility displacement
  while the grasp point stays where Quality put it (the contact moves along the pad);
  if the contact would leave the pad, the Feasibility pose is tried.

Every candidate is recentred on the new object's chord along its closing axis (new
contacts, width), re-graded with the same quality model and re-checked for collision;
only collision-free grasps within the opening range and above ``keep_min_grade`` are
kept. :func:`scale_stream` yields the result best-first in growing batches.
"""

from __future__ import annotations

import logging
import time
import weakref
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from enum import Enum

import numpy as np

from graspsim._version import __version__
from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.collide import grasps_collision_free
from graspsim.maps.generate import object_description
from graspsim.maps.graspmap import GraspabilityMap, MapMeta
from graspsim.maps.map_config import MapConfig
from graspsim.maps.table_clearance import stream_order
from graspsim.primitives import Primitive
from graspsim.primitives.base import MIN_DIM
from graspsim.transforms import quat_to_matrix

__all__ = ["ScalingMethod", "ScalingConfig", "scale_map", "scale_stream", "scale_factors"]

log = logging.getLogger(__name__)


class ScalingMethod(str, Enum):
    QUALITY = "quality"
    FEASIBILITY = "feasibility"
    COMBINED = "combined"


@dataclass(frozen=True)
class ScalingConfig:
    """method: the scaling algorithm.
    source_min_grade: FS grasps above this grade are scaled (None: the quality model's
        threshold, as in the paper: only successful grasps are scaled).
    keep_min_grade: scaled grasps above this grade are kept (None: the threshold, as in
        the paper; 0 keeps every valid grasp).
    max_ratio: largest allowed change of any dimension (new / old or old / new); the
        paper limits scaling to a range because large changes break its assumption.
    first_batch, growth: streaming batch sizes (grasps), growing geometrically; batches
        of up to ``small_batch`` grasps are checked by branch and bound (no set-up), larger
        ones by the compiled sweep (whose sample hierarchy for the target is built once).
    """

    method: ScalingMethod = ScalingMethod.COMBINED
    source_min_grade: float | None = None
    keep_min_grade: float | None = None
    max_ratio: float = 3.0
    first_batch: int = 1
    growth: float = 4.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "method", ScalingMethod(self.method))
        if not self.max_ratio >= 1.0:
            raise InvalidParameterError(f"max_ratio must be >= 1, got {self.max_ratio!r}")
        if self.first_batch < 1 or self.growth < 1:
            raise InvalidParameterError("first_batch must be >= 1 and growth >= 1")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["method"] = self.method.value
        return d


def scale_factors(source: Primitive, target: Primitive) -> dict[str, float]:
    """Per-dimension ratios target / source, each value taken as at least ``MIN_DIM``
    (a cone's pointed top: :func:`~graspsim.maps.match.size_ratio`'s rule)."""
    return {k: max(float(target.dims[k]), MIN_DIM) / max(float(v), MIN_DIM) for k, v in source.dims.items()}


def _feasibility_shift(source: Primitive, target: Primitive, points: np.ndarray) -> np.ndarray:
    """Displacement (N, 3) of the source surface point nearest to each point, when the
    surface is carried to the target by the shape correspondence."""
    s = points - source.sdf(points)[:, None] * source.normals(points)
    return target.from_unit(source.to_unit(s)) - s


@dataclass(frozen=True)
class _Chords:
    """Grasps recentred on the target's chords: per grasp (or per line) the contacts,
    normals, grasp point, width, quality and a validity mask."""

    ok: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    n1: np.ndarray
    n2: np.ndarray
    gp: np.ndarray
    width: np.ndarray
    q: object


def _chords(target: Primitive, gripper: GripperSpec, quality: QualityModel, d_ref: float,
            cfg: MapConfig, gp: np.ndarray, u: np.ndarray, keep_min: float) -> _Chords:
    """Chord of the target through each point ``gp`` along ``u``: contacts, width,
    re-graded quality; ``ok`` where the point is inside, the width fits the gripper and
    the grade exceeds ``keep_min``."""
    n = len(gp)
    inside = target.sdf(gp) < 0.0
    t1 = np.full(n, np.nan)
    t2 = np.full(n, np.nan)
    if np.any(inside):
        t1[inside] = target.ray_exit(gp[inside], -u[inside])
        t2[inside] = target.ray_exit(gp[inside], u[inside])
    width = t1 + t2
    ok = inside & np.isfinite(width) & (width >= max(cfg.min_width, gripper.min_opening)) \
        & (width + 2 * gripper.approach_clearance <= gripper.max_opening + 1e-12)
    t1, t2 = np.where(ok, t1, 0.0), np.where(ok, t2, 0.0)
    c1, c2 = gp - t1[:, None] * u, gp + t2[:, None] * u
    n1, n2 = target.normals(c1), target.normals(c2)
    q = quality.evaluate(c1, c2, n1, n2, target.com, d_ref)
    ok &= q.grade > keep_min
    return _Chords(ok, c1, c2, n1, n2, 0.5 * (c1 + c2), width, q)


def _columns(ch: _Chords, sel: np.ndarray, R: np.ndarray, depth: np.ndarray,
             gripper: GripperSpec) -> dict[str, np.ndarray]:
    """Map columns of grasps ``sel`` (indices into the chords) with rotations R and
    contact depths ``depth`` (one per selected grasp)."""
    gp = ch.gp[sel]
    return {"wrist_position": gripper.wrist_from_grasp_point(gp, R[:, :, 2], depth),
            "grasp_point": gp, "contacts": np.stack([ch.c1[sel], ch.c2[sel]], 1),
            "normals": np.stack([ch.n1[sel], ch.n2[sel]], 1), "width": ch.width[sel],
            "fc_angle": ch.q.fc_angle[sel], "q_fc": ch.q.q_fc[sel],
            "stability_distance": ch.q.stability_distance[sel], "q_st": ch.q.q_st[sel],
            "grade": ch.q.grade[sel]}


@dataclass(frozen=True)
class _Source:
    """The FS grasps to scale, grouped by closing line, lines best-first."""

    rows: np.ndarray  # FS row indices, grouped by line, lines best first
    line_of: np.ndarray  # (n,) line index of each row in ``rows``
    gp: np.ndarray  # (L, 3) grasp point of each line
    u: np.ndarray  # (L, 3) closing axis of each line


_SOURCES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # map -> {min_grade: _Source}


def _source(fs_map: GraspabilityMap, min_grade: float) -> _Source:
    """Line structure of an FS map's grasps above ``min_grade``, kept as long as the map
    object lives (a database's cached map: scaling it to every new object a scene shows
    prepares it once; preparing a stored map for scaling is a-priori work)."""
    per_map = _SOURCES.setdefault(fs_map, {})
    if min_grade not in per_map:
        per_map[min_grade] = _line_structure(fs_map, min_grade)
    return per_map[min_grade]


def _line_structure(fs_map: GraspabilityMap, min_grade: float) -> _Source:
    sel = np.flatnonzero(fs_map.grade > min_grade)
    c = np.ascontiguousarray(fs_map.contacts[sel]).reshape(len(sel), 6)
    _, first, line = np.unique(c.view(np.dtype((np.void, 24))).ravel(), return_index=True,
                               return_inverse=True)
    line = line.ravel()
    best = np.full(len(first), -np.inf, np.float32)
    np.maximum.at(best, line, fs_map.grade[sel])
    rank = np.empty(len(first), np.int64)
    rank[np.lexsort((first, -best))] = np.arange(len(first))  # best first, ties by FS order
    line = rank[line]
    order = np.lexsort((np.arange(len(sel)), line))
    rows, line = sel[order], line[order]
    lead = rows[np.searchsorted(line, np.arange(len(first)))]
    c = fs_map.contacts[lead].astype(float)
    u = c[:, 1] - c[:, 0]
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return _Source(rows, line, c.mean(axis=1), u)


def _check(target, gripper, cfg, gp, R, depth, width, line=None) -> np.ndarray:
    if len(gp) == 0:
        return np.zeros(0, bool)
    return grasps_collision_free(target, gripper, gp, R, depth, width, cfg, line=line)


def scale_stream(fs_map: GraspabilityMap, target: Primitive, *, quality: QualityModel | None = None,
                 scaling: ScalingConfig | None = None, config: MapConfig | None = None,
                 gripper: GripperSpec | None = None, prefer=None, skip=None) -> Iterator[GraspabilityMap]:
    """Scale ``fs_map`` (a primitive's FS map) to ``target`` (the same primitive at
    another size), yielding maps of kept grasps in batches, best FS lines first.
    quality, config, gripper: the map's own (from its metadata) unless given -- a
    caller that holds them (the planner's database) passes them. ``prefer``: a
    function of predicted scaled poses -- wrist quaternions (m, 4), wrist positions
    (m, 3) and contact widths (m,) in the target's frame, from the grasp's contacts
    mapped as Quality maps them, before the exact chord -- returning (m,) bool: those
    grasps are scaled first (see :func:`graspsim.maps.table_clearance.stream_order`); the same
    grasps are kept, only the order they stream in changes. ``skip``: a function of the
    same predicted poses returning (m,) bool: those grasps are not scaled at all (a
    caller that would drop them anyway, e.g. poses predicted far under the table)."""
    sc = scaling or ScalingConfig()
    source, ratios = _scalable(fs_map, target, sc.max_ratio)
    gripper = gripper or fs_map.meta.gripper_spec
    quality = quality or fs_map.meta.quality_model
    cfg = config or fs_map.meta.map_config
    src_min = fs_map.threshold if sc.source_min_grade is None else sc.source_min_grade
    keep_min = quality.threshold if sc.keep_min_grade is None else sc.keep_min_grade
    d_ref = quality.reference_distance(target.circumradius)
    src = _source(fs_map, float(src_min))
    meta = MapMeta(object=object_description(target, None, cfg.density), gripper=fs_map.meta.gripper,
                   quality={**quality.to_dict(), "d_ref": d_ref}, resolution=fs_map.meta.resolution,
                   method=f"scaled/{sc.method.value}", version=__version__,
                   extra={"source": fs_map.meta.object, "scaling": sc.to_dict(), "factors": ratios,
                          "source_grasps": int(len(src.rows)), "collision_tolerance": float(cfg.collision_tolerance)})
    lo = gripper.depth_lo - 1e-6
    hi = gripper.depth_hi + 1e-6
    def poses(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted scaled poses of rows ``pos``: wrist quaternions, positions, widths."""
        r = src.rows[pos]
        c = fs_map.contacts[r].astype(float)
        c2 = target.from_unit(source.to_unit(c.reshape(-1, 3))).reshape(c.shape)
        wrist = fs_map.wrist_position[r] + ((c2[:, 0] + c2[:, 1]) / 2 - (c[:, 0] + c[:, 1]) / 2)  # = mean(1)
        return fs_map.wrist_quat[r], wrist, np.linalg.norm(c2[:, 1] - c2[:, 0], axis=1)

    # with both a preference and a skip, one prediction per row serves both: the stream
    # order asks about every row before it yields it, and the skip is asked then, about
    # the same predicted poses (the same call: a caller may share work between the two)
    skipped = known = None
    if prefer is not None and skip is not None:
        skipped, known = np.zeros(len(src.rows), bool), np.zeros(len(src.rows), bool)

    def predicted(pos: np.ndarray) -> np.ndarray:
        p = poses(pos)
        first = prefer(*p)
        if skipped is not None:
            skipped[pos], known[pos] = np.asarray(skip(*p), bool), True
        return first

    for rows in stream_order(len(src.rows), sc.first_batch, sc.growth, None if prefer is None else predicted):
        if skip is not None:
            out = skipped[rows] if known is not None and known[rows].all() else np.asarray(skip(*poses(rows)), bool)
            rows = rows[~out]
            if not len(rows):
                continue
        line = src.line_of[rows]
        R = quat_to_matrix(fs_map.wrist_quat[src.rows[rows]])
        wrist = fs_map.wrist_position[src.rows[rows]].astype(float)
        depth = gripper.contact_depth(src.gp[line], wrist, R[:, :, 2])
        pieces = []
        rest = np.arange(len(rows))
        if sc.method in (ScalingMethod.QUALITY, ScalingMethod.COMBINED):
            # rows come grouped by line in increasing line order: the batch's lines and
            # each row's chord without a sort
            starts = np.empty(len(line), bool)
            starts[0] = True
            np.not_equal(line[1:], line[:-1], out=starts[1:])
            lines = line[starts]
            li = np.cumsum(starts) - 1  # chord of each row
            gp_q = target.from_unit(source.to_unit(src.gp[lines]))
            ch = _chords(target, gripper, quality, d_ref, cfg, gp_q, src.u[lines], keep_min)
            cand = np.flatnonzero(ch.ok[li])
            free = _check(target, gripper, cfg, ch.gp[li[cand]], R[cand], depth[cand],
                          ch.width[li[cand]], line=li[cand])
            kept = cand[free]
            pieces.append((_columns(ch, li[kept], R[kept], depth[kept], gripper), kept))
            left = np.ones(len(rows), bool)
            left[kept] = False
            rest = np.flatnonzero(left)
        if sc.method is ScalingMethod.COMBINED and len(rest):
            # slide the wrist along the approach axis by the feasibility shift: the
            # contact moves along the pad, the grasp point stays where Quality put it
            shift = _feasibility_shift(source, target, wrist[rest])
            d2 = depth[rest] + np.einsum("ni,ni->n", shift, R[rest, :, 2])
            on_pad = ch.ok[li[rest]] & (d2 >= lo) & (d2 <= hi)
            cand = rest[on_pad]
            free = _check(target, gripper, cfg, ch.gp[li[cand]], R[cand], d2[on_pad],
                          ch.width[li[cand]], line=li[cand])
            kept = cand[free]
            pieces.append((_columns(ch, li[kept], R[kept], d2[on_pad][free], gripper), kept))
            rest = rest[~on_pad]  # off the pad or no chord: try the feasibility pose
        if sc.method in (ScalingMethod.FEASIBILITY, ScalingMethod.COMBINED) and len(rest):
            shift = _feasibility_shift(source, target, wrist[rest])
            gp_f = src.gp[line[rest]] + shift
            chf = _chords(target, gripper, quality, d_ref, cfg, gp_f, R[rest, :, 0], keep_min)
            cand = np.flatnonzero(chf.ok & (depth[rest] >= lo) & (depth[rest] <= hi))
            free = _check(target, gripper, cfg, chf.gp[cand], R[rest][cand], depth[rest][cand],
                          chf.width[cand])
            kept = cand[free]
            pieces.append((_columns(chf, kept, R[rest][kept], depth[rest][kept], gripper), rest[kept]))
        batch = _assemble(pieces, fs_map, src.rows[rows], meta)
        if len(batch):
            yield batch


def _scalable(fs_map: GraspabilityMap, target: Primitive, max_ratio: float) -> tuple[Primitive, dict]:
    """(the map's primitive, its scale factors to ``target``) if the map may be scaled
    to it: the same kind, every factor within ``max_ratio``."""
    source = fs_map.meta.shape
    if not isinstance(source, Primitive) or source.kind != target.kind:
        raise InvalidParameterError(
            f"can only scale a map of a {target.kind} to another {target.kind}; the map is of "
            f"{fs_map.meta.object.get('primitive')}")
    ratios = scale_factors(source, target)
    bad = {k: r for k, r in ratios.items() if max(r, 1.0 / r) > max_ratio}
    if bad:
        raise InvalidParameterError(
            f"scaling {source} to {target} changes {sorted(bad)} by more than the allowed "
            f"factor {max_ratio}; generate an FS map for this size instead")
    return source, ratios


def _assemble(pieces, fs_map: GraspabilityMap, fs_rows: np.ndarray, meta: MapMeta):
    """One batch map from the per-method pieces (columns, batch-local row indices),
    best grade first."""
    pieces = [(c, k) for c, k in pieces if len(k)]
    if not pieces:
        return GraspabilityMap.empty(meta)
    local = np.concatenate([k for _, k in pieces])
    cols = {name: np.concatenate([c[name] for c, _ in pieces]) for name in pieces[0][0]}
    src = fs_rows[local]
    cols["wrist_quat"] = fs_map.wrist_quat[src]
    cols["part"] = fs_map.part[src]
    m = GraspabilityMap(**cols, meta=meta)
    return m.select(np.argsort(-m.grade, kind="stable"))


def scale_map(fs_map: GraspabilityMap, target: Primitive, *, quality: QualityModel | None = None,
              scaling: ScalingConfig | None = None, config: MapConfig | None = None) -> GraspabilityMap:
    """The whole scaled map (the concatenation of :func:`scale_stream`'s batches)."""
    t0 = time.perf_counter()
    batches = list(scale_stream(fs_map, target, quality=quality, scaling=scaling, config=config))
    sc = scaling or ScalingConfig()
    if batches:
        out = GraspabilityMap.concat(batches)
    else:
        log.warning("scaling %s to %s kept no grasp", fs_map.meta.shape, target)
        density = (config or fs_map.meta.map_config).density
        out = GraspabilityMap.empty(MapMeta(
            object=object_description(target, None, density), gripper=fs_map.meta.gripper,
            quality=fs_map.meta.quality, resolution=fs_map.meta.resolution,
            method=f"scaled/{sc.method.value}", version=__version__))
    return out.with_meta(timing={"total": time.perf_counter() - t0})
