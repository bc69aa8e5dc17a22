"""Invariants every usable graspability map keeps: the one home of map validation.

A map is usable when it has grasps, every column is finite and in its range (grades
in [0, 1]; a map read from a third-party grasp file, ``meta.method`` "imported:...",
may lack the analytic columns and the contacts: NaN there means missing), force-closure
angles in [0, pi], stability distances and part ids >= 0,
widths > 0), the wrist quaternions are unit, its object is a valid shape (dimensions
at or above the primitive floor, :data:`graspsim.primitives.base.MIN_DIM`), and its
gripper, quality model and metadata can be used (the scaler and the simulator build
a :class:`~graspsim.grippers.spec.GripperSpec` and a quality model from them).

:func:`~graspsim.maps.io.load_map` refuses a file whose map breaks them (file layout
checks are its own), the map database refuses to store such a map, and ``graspsim db
check`` reports (and with ``--repair`` removes) stored maps that do.
"""

from __future__ import annotations

import math

import numpy as np

from graspsim.errors import GraspsimError, InvalidMapError
from graspsim.maps.graspmap import COLUMNS, GraspabilityMap

__all__ = ["map_problems", "validate_map"]

_NON_SHAPES = ("mesh",)  # objects described by a file, not by dimensions
_RANGES = {"grade": (0.0, 1.0), "q_fc": (0.0, 1.0), "q_st": (0.0, 1.0), "fc_angle": (0.0, math.pi),
           "stability_distance": (0.0, math.inf), "part": (0, math.inf)}
_TOL = 1e-5  # float32 columns: rounding at the range's ends
#: columns a third-party grasp file does not give (NaN: missing; see graspsim.maps.formats)
MISSING_WHEN_IMPORTED = ("grade", "fc_angle", "q_fc", "q_st", "stability_distance", "contacts", "normals")
_META_KINDS = {"object": dict, "gripper": dict, "quality": dict, "resolution": dict, "method": str,
               "timing": dict, "version": str, "extra": dict}


def _rows(bad: np.ndarray, what: str) -> str | None:
    """"<what> in K grasps (first at row R)" for the rows flagged by ``bad``, or None."""
    k = int(bad.sum())
    return f"{what} in {k} grasps (first at row {int(np.argmax(bad))})" if k else None


def _columns_pass(gmap: GraspabilityMap) -> bool:
    """The column invariants from each column's min and max (NaN propagates through
    both): one pass per column and no per-row temporaries, so a valid million-grasp map
    is checked in a few ms; :func:`_column_problems` names the rows only when it fails."""
    if not len(gmap):
        return True
    bounds = {name: (-np.inf, np.inf) for name, (_, dtype) in COLUMNS.items() if np.issubdtype(dtype, np.floating)}
    bounds.update(_RANGES)
    may_miss = _may_miss(gmap)
    for name, (lo, hi) in bounds.items():
        a = getattr(gmap, name)
        if name in may_miss:
            if np.isnan(a).all():
                continue
            a_min, a_max = float(np.nanmin(a)), float(np.nanmax(a))
        else:
            a_min, a_max = float(a.min()), float(a.max())
        if not (math.isfinite(a_min) and math.isfinite(a_max) and lo - _TOL <= a_min and a_max <= hi + _TOL):
            return False
    q = gmap.wrist_quat
    return float(gmap.width.min()) > 0 and float(np.abs(np.einsum("ij,ij->i", q, q) - 1.0).max()) <= 2e-3


def _may_miss(gmap: GraspabilityMap) -> tuple[str, ...]:
    """The columns ``gmap`` may hold NaN in (missing): those of an imported map."""
    return MISSING_WHEN_IMPORTED if str(gmap.meta.method).startswith("imported:") else ()


def _column_problems(gmap: GraspabilityMap) -> list[str]:
    if _columns_pass(gmap):
        return []
    out = []
    finite = {}
    may_miss = _may_miss(gmap)
    for name, (_, dtype) in COLUMNS.items():
        a = getattr(gmap, name)
        if np.issubdtype(dtype, np.floating):
            ok = np.isfinite(a).reshape(len(a), int(np.prod(a.shape[1:]))).all(axis=1)
            finite[name] = ok
            if name in may_miss:  # NaN: missing; infinities are still wrong
                ok = ok | np.isnan(a).reshape(len(a), -1).all(axis=1)
            out.append(_rows(~ok, f"{name} has non-finite values"))
    for name, (lo, hi) in _RANGES.items():
        a = getattr(gmap, name)
        ok = finite.get(name, np.ones(len(a), bool))
        out.append(_rows(ok & ((a < lo - _TOL) | (a > hi + _TOL)), f"{name} outside [{lo:g}, {hi:g}]"))
    w = gmap.width
    out.append(_rows(finite["width"] & (w <= 0), "width <= 0"))
    q = gmap.wrist_quat.astype(np.float64)
    norm = np.einsum("ij,ij->i", q, q)
    out.append(_rows(finite["wrist_quat"] & (np.abs(norm - 1.0) > 2e-3), "wrist_quat holds non-unit quaternions"))
    return [p for p in out if p]


def _meta_problems(meta) -> list[str]:
    from graspsim.grades.paper import QualityModel
    from graspsim.grippers.spec import GripperSpec

    bad = [f"{k} is {type(getattr(meta, k)).__name__}, not {t.__name__}" for k, t in _META_KINDS.items()
           if not isinstance(getattr(meta, k), t)]
    if bad:
        return [f"its metadata is damaged: {'; '.join(bad)}"]
    out = []
    checks = (("gripper", lambda: GripperSpec.from_dict(meta.gripper)),
              ("quality model", lambda: QualityModel.from_meta(meta.quality)))
    for what, build in checks:
        try:
            build()
        except GraspsimError as err:
            out.append(f"its {what} is not valid: {err}")
    obj = meta.object
    if not (obj.get("primitive") in _NON_SHAPES or "file" in obj):
        from graspsim.primitives import shape_from_dict

        try:
            shape_from_dict(obj)
        except GraspsimError as err:
            out.append(f"its object is not a valid shape: {err}")
    return out


def map_problems(gmap: GraspabilityMap, *, allow_empty: bool = False) -> list[str]:
    """What is wrong with ``gmap`` (empty when nothing): one short sentence per problem.
    ``allow_empty``: a map without grasps is not a problem (a slice of a stored map)."""
    out = [] if len(gmap) or allow_empty else ["it has no grasps"]
    return out + _column_problems(gmap) + _reach_problems(gmap) + _meta_problems(gmap.meta)


def _reach_problems(gmap: GraspabilityMap) -> list[str]:
    """The ``reachable`` column holds only :data:`~graspsim.maps.graspmap.REACH_VALUES` or NaN."""
    from graspsim.maps.graspmap import REACH_VALUES

    r = gmap.reachable
    bad = ~(np.isnan(r) | np.isin(r, np.asarray(REACH_VALUES, r.dtype)))
    p = _rows(bad, f"reachable holds values other than {list(REACH_VALUES)} or NaN")
    return [p] if p else []


def validate_map(gmap: GraspabilityMap, *, error: type[GraspsimError] = InvalidMapError,
                 what: str = "the map", allow_empty: bool = False) -> GraspabilityMap:
    """``gmap`` if it keeps the invariants, else ``error`` naming every problem."""
    problems = map_problems(gmap, allow_empty=allow_empty)
    if problems:
        raise error(f"{what} is invalid: " + "; ".join(problems))
    return gmap
