"""Invariants every usable graspability map keeps.

A map is usable when it has grasps, every column is finite, the wrist quaternions are
unit, the grasp widths are positive, and its object is a valid shape (dimensions at
or above the primitive floor, :data:`graspsim.primitives.base.MIN_DIM`). The map
database refuses to store a map that breaks them and ``graspsim db check`` reports
(and with ``--repair`` removes) stored maps that do.
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import GraspsimError, InvalidMapError
from graspsim.maps.graspmap import COLUMNS, GraspabilityMap

__all__ = ["map_problems", "validate_map"]

_NON_SHAPES = {"mesh"}  # objects described by a file, not by dimensions


def map_problems(gmap: GraspabilityMap) -> list[str]:
    """What is wrong with ``gmap`` (empty when nothing): one short sentence per problem."""
    out = []
    if len(gmap) == 0:
        out.append("it has no grasps")
    for name, (_, dtype) in COLUMNS.items():
        a = getattr(gmap, name)
        if np.issubdtype(dtype, np.floating):
            nonfinite = ~np.isfinite(a)
            bad = int((nonfinite.any(axis=tuple(range(1, a.ndim))) if a.ndim > 1 else nonfinite).sum())
            if bad:
                out.append(f"{bad} grasps have non-finite {name}")
    norm = np.linalg.norm(gmap.wrist_quat.astype(np.float64), axis=1)
    if np.any(np.abs(norm - 1.0) > 1e-3):
        out.append(f"{int(np.sum(np.abs(norm - 1.0) > 1e-3))} wrist quaternions are not unit")
    if np.any(gmap.width <= 0):
        out.append(f"{int(np.sum(gmap.width <= 0))} grasps have a width <= 0")
    obj = gmap.meta.object
    if obj.get("primitive") not in _NON_SHAPES and "file" not in obj:
        from graspsim.primitives import shape_from_dict

        try:
            shape_from_dict(obj)
        except GraspsimError as err:
            out.append(f"its object is not a valid shape: {err}")
    return out


def validate_map(gmap: GraspabilityMap, *, error: type[GraspsimError] = InvalidMapError,
                 what: str = "the map") -> GraspabilityMap:
    """``gmap`` if it keeps the invariants, else ``error`` naming every problem."""
    problems = map_problems(gmap)
    if problems:
        raise error(f"{what} is invalid: " + "; ".join(problems))
    return gmap
