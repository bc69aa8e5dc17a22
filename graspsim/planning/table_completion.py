"""A single view's box parts completed down to the table they rest on.

One camera sees a resting box's top and near faces; its far (hidden) extent is the fit's
guess. Where the view measured no face along an axis -- a milk carton lying on its side
seen from above and in front, a domino lying flat seen from above -- the fit makes the
box as deep there as the seen faces' noise allows, a few mm (a 6 mm domino fitted 2 to
4 mm thick, a 5 cm carton as a 2 cm plate), and the planner then refuses every grasp
across that extent (:meth:`~graspsim.planning.observed.ObservedChecks.unseen_depth`):
the object is left on the table with no grasp.

An object resting on a known table cannot float: where the box's hidden far face points
down to the table, the segment touches the table (its lowest seen points within
:data:`TOUCH` of it) and the space between that face and the table is space the camera
did not see (behind the object's seen surfaces, at least :data:`HIDDEN_SHARE` of it),
the part is completed down to the table plane: its far face moved along that axis
until the box's lowest corner reaches the table. The extent is then bounded by the
table -- measured, as far as a grasp is concerned -- and a grasp may close across it.
Where the camera saw past the far face (the table beside a box lying on a neighbour,
the neighbour's own top), the box is left as fitted. A segment whose foot a neighbour in
front of it hides (its lowest seen points higher than :data:`TOUCH`) is completed the
same way when none of the neighbours' points lies in the added volume: an object lying
on a neighbour stops on it.

The same view's other parts may show a depth the part's own faces do not: a standing
carton fitted as a plate on its front face and a second part on its top, whose points
reach back the carton's depth. :func:`segment_depth` deepens the part as far as its
segment reaches (``PlannerConfig.hidden_depth``).

Scene planning only (``PlannerConfig.complete_to_table``, ``.hidden_depth``); single-object planning, and
the paper's identification mode, are unchanged.
"""

from __future__ import annotations

import numpy as np

from graspsim.geometry.table import TablePlane
from graspsim.maps.occlusion import ViewDepth
from graspsim.primitives import make_primitive

__all__ = ["TOUCH", "HIDDEN_SHARE", "DOWN_COS", "SEGMENT_QUANTILE", "TableCompletion", "complete_to_table",
           "segment_depth"]

#: [m] a segment touches the table when its lowest seen points lie this near it (a scene's
#: table band, 6 mm, removes the points nearer than that: the lowest ones left lie just above it)
TOUCH = 0.012
#: the share of the completed volume that must lie in space the camera did not see
HIDDEN_SHARE = 0.9
#: an axis points down to the table when within 60 deg of the table's downward normal
DOWN_COS = 0.5
#: [m] a far face this near the table already rests on it
REST = 0.002
#: :func:`segment_depth`: how far the segment reaches along an axis, its points' quantile this high
#: (a few stray or noisy points do not set it)
SEGMENT_QUANTILE = 0.99


class TableCompletion:
    """What :func:`complete_to_table` did to one part: ``axis`` (3,) the completed axis
    (cloud frame; None: left as fitted), ``added`` [m] the extent it gained."""

    __slots__ = ("axis", "added")

    def __init__(self, axis: np.ndarray | None = None, added: float = 0.0) -> None:
        self.axis, self.added = axis, added


def complete_to_table(prim, T: np.ndarray, points: np.ndarray, table: TablePlane,
                      viewpoint: np.ndarray, view: ViewDepth | None = None, samples: int = 6,
                      band: float = 0.006, neighbours: np.ndarray | None = None):
    """Box part ``prim`` posed at ``T`` (4, 4, cloud frame), identified from ``points``
    (N, 3; the segment) seen from ``viewpoint`` (3,), resting on ``table`` (its height
    known): (prim, T, :class:`TableCompletion`), the part completed down to the table
    where its hidden far face hangs above it (see the module docstring), else as given.
    ``view``: the depth image of what the camera saw near the part (default: ``points``);
    ``band`` [m]: the height above the table below which the points were cut away as the
    table's (``SceneConfig.table_band``): the added volume is judged above it only (within
    it the camera's points, table or object, are gone). ``neighbours`` (M, 3): the
    neighbours' observed points; given, a segment whose lowest points lie higher than
    :data:`TOUCH` above the table (its foot hidden by a neighbour in front of it) is
    completed too, when none of them lies in the completed volume (an object lying on a
    neighbour stops on it: the neighbour's seen surface under its far face is there)."""
    if prim.kind != "box" or table.height is None or viewpoint is None or len(points) < 3:
        return prim, T, TableCompletion()
    n = np.asarray(table.normal, float)
    h0 = float(table.height)
    P = np.asarray(points, float)
    touching = float(np.min(P @ n)) - h0 <= TOUCH
    if not touching and neighbours is None:  # the segment does not reach the table: it may lie on a neighbour
        return prim, T, TableCompletion()
    T = np.asarray(T, float)
    R, c = T[:3, :3], T[:3, 3]
    half = 0.5 * np.array([prim.x, prim.y, prim.z])
    eye = np.asarray(viewpoint, float)
    best = None
    for j in range(3):
        for s in (1.0, -1.0):
            d = s * R[:, j]
            down = -float(d @ n)
            if down < DOWN_COS or float((c - eye) @ d) <= 0.0:  # not down to the table, or a face turned to the camera
                continue
            face = c + d * half[j]
            others = [k for k in range(3) if k != j]
            corners = np.array([face + a * half[others[0]] * R[:, others[0]] + b * half[others[1]] * R[:, others[1]]
                                for a in (-1, 1) for b in (-1, 1)])
            gap = float(np.min(corners @ n)) - h0
            if gap <= REST:
                continue
            added = gap / down
            if best is None or down > best[1]:
                best = (j, down, s, added, face)
    if best is None:
        return prim, T, TableCompletion()
    j, _, s, added, face = best
    d = s * R[:, j]
    others = [k for k in range(3) if k != j]
    if 2.0 * half[j] + added > 2.0 * max(half[others]):  # deeper than the box is long: not this box's far side
        return prim, T, TableCompletion()
    view = view if view is not None else ViewDepth(P, eye)
    if not _hidden_slab(R, half, j, face, d, added, table, band, view, samples):
        return prim, T, TableCompletion()
    if not touching and _holds_points(R, half, j, face, d, added, neighbours):  # it rests on a neighbour
        return prim, T, TableCompletion()
    dims = 2.0 * half
    dims[j] += added
    out = T.copy()
    out[:3, 3] = c + 0.5 * added * d
    new = make_primitive("box", x=float(dims[0]), y=float(dims[1]), z=float(dims[2]))
    return new, out, TableCompletion(R[:, j].copy(), float(added))


def _holds_points(R: np.ndarray, half: np.ndarray, j: int, face: np.ndarray, d: np.ndarray, added: float,
                  points: np.ndarray | None) -> bool:
    """Whether any of ``points`` (M, 3) lies in the slab a box (axes ``R``, half extents
    ``half``) gains beyond its face ``face`` along axis ``j``: ``added`` [m] in direction ``d``."""
    if points is None or not len(points):
        return False
    Q = np.asarray(points, float).reshape(-1, 3) - face
    t = Q @ d
    inside = (t > 0.0) & (t < added)
    for k in range(3):
        if k != j:
            inside &= np.abs(Q @ R[:, k]) < half[k]
    return bool(inside.any())


def _hidden_slab(R: np.ndarray, half: np.ndarray, j: int, face: np.ndarray, d: np.ndarray, added: float,
                 table: TablePlane | None, band: float, view: ViewDepth, samples: int) -> bool:
    """Whether the slab a box (axes ``R``, half extents ``half``) gains beyond its face
    ``face`` along axis ``j`` -- ``added`` [m] in direction ``d`` -- lies in space the
    camera did not see (at least :data:`HIDDEN_SHARE` of it; judged above the table's
    ``band``, within which the camera's points were cut away as table's)."""
    others = [k for k in range(3) if k != j]
    # the added slab, sampled inside (not on its faces: a sample on the seen faces' edges is not hidden)
    u = (np.arange(samples) + 0.5) / samples
    a, b, t = np.meshgrid(2 * u - 1, 2 * u - 1, u, indexing="ij")
    X = (face + a.reshape(-1, 1) * half[others[0]] * R[:, others[0]]
         + b.reshape(-1, 1) * half[others[1]] * R[:, others[1]] + t.reshape(-1, 1) * added * d)
    if table is not None and table.height is not None:
        X = X[X @ np.asarray(table.normal, float) - float(table.height) > band]
    return not len(X) or float(np.mean(view.occluded(X))) >= HIDDEN_SHARE


def segment_depth(prim, T: np.ndarray, j: int, d: np.ndarray, points: np.ndarray, view: ViewDepth,
                  table: TablePlane | None = None, band: float = 0.006, samples: int = 6) -> float:
    """[m] how much deeper box part ``prim`` (posed at ``T``, cloud frame) is, along its
    axis ``j`` in direction ``d`` (away from the camera), by its own segment's points.

    A single view that saw only the faces across a box part's axis leaves its depth
    there a guess (see :meth:`~graspsim.planning.observed.ObservedChecks.unseen_depth`);
    the segment's other points may show it. A standing carton seen from above and in
    front is fitted as a plate on its front face and a second part on its sloping top:
    the top's points reach back the carton's whole depth, the plate's depth is 2 to 20 mm.
    The segment is one object, so it reaches at least as far as its points do (their
    :data:`SEGMENT_QUANTILE` along ``d``): the part's far face moves there when the
    volume it gains lies in the camera's shadow (:data:`HIDDEN_SHARE`; ``view``: the
    depth image of what the camera saw, the segment's and its neighbours' points) and the
    part becomes no deeper than it is long. 0: no deeper (already as deep, the gained
    volume seen, or the part would become deeper than long)."""
    if prim.kind != "box" or len(points) < 3:
        return 0.0
    T = np.asarray(T, float)
    R, c = T[:3, :3], T[:3, 3]
    d = np.asarray(d, float)
    half = 0.5 * np.array([prim.x, prim.y, prim.z])
    far = float(c @ d) + half[j]
    added = float(np.quantile(np.asarray(points, float) @ d, SEGMENT_QUANTILE)) - far
    others = [k for k in range(3) if k != j]
    if added <= REST or 2.0 * half[j] + added > 2.0 * max(half[others]):
        return 0.0
    return added if _hidden_slab(R, half, j, c + d * half[j], d, added, table, band, view, samples) else 0.0
