"""Box parts of one segment that are one box: merged.

The fit-and-split identification may cut one box-shaped object into parallel slabs (a
milk carton lying on its side, seen from above, fitted as an 8 mm and a 24 mm slab side
by side, each the carton's length and height). The planner combines the parts' maps:
a grasp of one slab alone has a finger inside the other and is dropped, and no part's
map holds the grasps across the whole carton -- the object is left with no grasp.

Two box parts whose axes agree (within :data:`PARALLEL_DEG`) are one box -- their
union's box, in the first part's frame -- when the volume of that box neither part
fills lies in the camera's shadow (at least
:data:`~graspsim.planning.table_completion.HIDDEN_SHARE` of it, judged above the table's
band as :func:`~graspsim.planning.table_completion.complete_to_table` does): the carton's
slabs with its seen top over the space between them. Where the camera saw into that
space (the table through the notch of an L, between two blocks side by side, the gap
of a U) the parts stay as identified.

The planner merges after completing parts down to the table (a slab whose foot a
neighbour hid fills the union only once completed). Scene planning only
(``PlannerConfig.merge_boxes``); single-object planning, and the
paper's identification mode, are unchanged.
"""

from __future__ import annotations

import numpy as np

from graspsim.geometry.table import TablePlane
from graspsim.maps.occlusion import ViewDepth
from graspsim.planning.table_completion import HIDDEN_SHARE
from graspsim.primitives import make_primitive

__all__ = ["PARALLEL_DEG", "merge_boxes"]

#: [deg] two boxes' axes agree when each of one's lies this near one of the other's
PARALLEL_DEG = 10.0


def _corners(prim, T: np.ndarray) -> np.ndarray:
    half = 0.5 * np.array([prim.x, prim.y, prim.z])
    s = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    return (s * half) @ T[:3, :3].T + T[:3, 3]


def _inside(prim, T: np.ndarray, X: np.ndarray) -> np.ndarray:
    half = 0.5 * np.array([prim.x, prim.y, prim.z])
    return np.all(np.abs((X - T[:3, 3]) @ T[:3, :3]) <= half, axis=1)


def _merged(a, Ta: np.ndarray, b, Tb: np.ndarray, view: ViewDepth, table: TablePlane | None, band: float,
            samples: int):
    """(box, pose) of box parts ``a`` at ``Ta`` and ``b`` at ``Tb`` merged, or None."""
    C = np.abs(Ta[:3, :3].T @ Tb[:3, :3])
    if not np.all(C.max(axis=0) >= np.cos(np.radians(PARALLEL_DEG))):
        return None
    local = (np.concatenate([_corners(a, Ta), _corners(b, Tb)]) - Ta[:3, 3]) @ Ta[:3, :3]
    lo, hi = local.min(axis=0), local.max(axis=0)
    dims = hi - lo
    u = (np.arange(samples) + 0.5) / samples  # the union's box sampled inside
    g = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
    X = (lo + g * dims) @ Ta[:3, :3].T + Ta[:3, 3]
    X = X[~_inside(a, Ta, X) & ~_inside(b, Tb, X)]  # the volume neither part fills
    if table is not None and table.height is not None:
        X = X[X @ np.asarray(table.normal, float) - float(table.height) > band]
    if len(X) and float(np.mean(view.occluded(X))) < HIDDEN_SHARE:
        return None
    T = Ta.copy()
    T[:3, 3] = Ta[:3, 3] + Ta[:3, :3] @ (0.5 * (lo + hi))
    return make_primitive("box", x=float(dims[0]), y=float(dims[1]), z=float(dims[2])), T


def merge_boxes(prims: list, T_cloud: list, view: ViewDepth, table: TablePlane | None = None,
                band: float = 0.006, samples: int = 8) -> tuple[list, list, list]:
    """The parts ``prims`` posed at ``T_cloud`` (cloud frame) with every pair of box parts
    that is one box merged (see the module docstring), until no pair is: (parts, poses,
    per part the indices of the given parts it stands for). ``view``: the depth image of
    what the camera saw (the segment's and its neighbours' points); ``table``, ``band``:
    the table and the height above it whose points were cut away as its. Parts other than
    boxes are kept as they are."""
    prims, T_cloud = list(prims), [np.asarray(T, float) for T in T_cloud]
    groups = [[i] for i in range(len(prims))]
    changed = True
    while changed:
        changed = False
        for i in range(len(prims)):
            for j in range(i + 1, len(prims)):
                if prims[i].kind != "box" or prims[j].kind != "box":
                    continue
                m = _merged(prims[i], T_cloud[i], prims[j], T_cloud[j], view, table, band, samples)
                if m is None:
                    continue
                prims[i], T_cloud[i] = m
                groups[i] = groups[i] + groups[j]
                del prims[j], T_cloud[j], groups[j]
                changed = True
                break
            if changed:
                break
    return prims, T_cloud, groups
