"""Plan reuse between frames of one scene: a segment that did not change keeps its plan.

In clutter removal the scene is seen again after every grasp. Most of it is as it was:
the picked object is gone, the others stand where they stood. A segment of the new
frame whose points are the points of a segment of the previous frame (within
``tol``, both ways: sensor noise moves points by a millimetre or two, a displaced or
newly uncovered object by more) keeps that segment's identification; it keeps its
ranked grasps too when nothing new appeared among the obstacles its grasps were
scored against (points the gripper must clear that the previous check did not have:
a neighbour that moved or was uncovered). Obstacles that disappeared (the picked
object) only free space, so the stored robust scores remain valid lower bounds
(a grasp scored 0 because it hit the picked object stays at 0: the segment is planned
again when no grasp with a score > 0 is left). A grasp that was executed is dropped
from what is reused, with its near twins (:func:`drop_grasp`): a start collision
leaves the scene as it was, and the next rows of the same map would collide the same
way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["SegmentMemory", "same_points", "nothing_new", "find_previous", "reused_grasps", "drop_grasp",
           "near_pose"]


@dataclass(frozen=True, eq=False)
class SegmentMemory:
    """What a frame's planning of one segment leaves for the next frame: its points
    (thinned), the identification (None: it failed, ``why``), the solid samples it
    stands for as a neighbour, the obstacles its grasps were scored against (None:
    not planned or no neighbour check), its SegmentPlan and its ranked SceneGrasps."""

    points: np.ndarray
    ident: object
    why: str
    solids: np.ndarray | None
    obstacles: np.ndarray | None
    plan: object
    grasps: tuple


def _near_share(a: np.ndarray, b: np.ndarray, tol: float) -> float:
    """Share of points ``a`` within ``tol`` of some point of ``b``."""
    if not len(a):
        return 1.0
    if not len(b):
        return 0.0
    d, _ = cKDTree(b).query(a, distance_upper_bound=tol)
    return float(np.mean(np.isfinite(d)))


def same_points(a: np.ndarray, b: np.ndarray, *, tol: float, share: float = 0.97) -> bool:
    """Whether point sets ``a`` and ``b`` show the same surface: their counts within
    10 %, and ``share`` of each within ``tol`` [m] of the other."""
    n, m = len(a), len(b)
    if not n or not m or abs(n - m) > 0.1 * max(n, m):
        return False
    return _near_share(a, b, tol) >= share and _near_share(b, a, tol) >= share


def nothing_new(old: np.ndarray | None, new: np.ndarray | None, *, tol: float, allowed: int = 3,
                within: tuple[np.ndarray, np.ndarray] | None = None, own: np.ndarray | None = None) -> bool:
    """Whether obstacle points ``new`` show nothing that ``old`` did not (None: no
    obstacles): at most ``allowed`` new points farther than ``tol`` [m] from every old
    point that have three or more such points within ``2 tol`` -- a surface, not the
    sensor's speckle (isolated points, e.g. at the table band's edge, that come and go
    between frames). Only new points inside the box ``within`` (lo, hi) count when
    given (a segment's reach box jitters with its points), and none within ``2 tol`` of
    the segment's ``own`` points (stray points at its fringe that clustering left out)."""
    if new is not None and within is not None:
        new = new[np.all((new >= within[0]) & (new <= within[1]), axis=1)]
    if new is not None and own is not None and len(own) and len(new):
        new = new[~np.isfinite(cKDTree(own).query(new, distance_upper_bound=2.0 * tol)[0])]
    if new is None or not len(new):
        return True
    if old is None or not len(old):
        return False
    far = new[~np.isfinite(cKDTree(old).query(new, distance_upper_bound=tol)[0])]
    if len(far) <= allowed:
        return True
    crowd = cKDTree(far).query_ball_point(far, 2.0 * tol, return_length=True) - 1  # neighbours but itself
    return int(np.sum(crowd >= 3)) <= allowed


def find_previous(points: np.ndarray, previous, *, tol: float) -> SegmentMemory | None:
    """The previous frame's segment memory (a sequence of :class:`SegmentMemory`)
    showing the same points as ``points``, or None."""
    if not previous or not len(points):
        return None
    c = points.mean(axis=0)
    for mem in sorted(previous, key=lambda m: float(np.linalg.norm(m.points.mean(axis=0) - c))):
        if np.linalg.norm(mem.points.mean(axis=0) - c) > 2.0 * tol:
            return None
        if same_points(points, mem.points, tol=tol):
            return mem
    return None


def reused_grasps(mem: SegmentMemory, k: int) -> list:
    """The remembered grasps as segment ``k``'s, or [] when none has a score > 0 (the
    segment must be planned again)."""
    if not any(g.score > 0 for g in mem.grasps):
        return []
    return [replace(g, segment=k) for g in mem.grasps]


def near_pose(T_a: np.ndarray, T_b: np.ndarray, *, reach: float = 0.0, distance: float = 0.015,
              angle_deg: float = 20.0) -> bool:
    """Whether wrist poses ``T_a`` and ``T_b`` (4, 4) close on the same contacts, give or
    take: their points ``reach`` [m] out along the approach (wrist z; the fingertips at
    the gripper's ``fingertip_z``) within ``distance`` [m] and their closing axes (wrist
    x, either sign: the jaws are symmetric) within ``angle_deg``, whatever the approach
    turned about that axis (the map's rows of one contact pair)."""
    pa = T_a[:3, 3] + reach * T_a[:3, 2]
    pb = T_b[:3, 3] + reach * T_b[:3, 2]
    if np.linalg.norm(pa - pb) > distance:
        return False
    return abs(float(T_a[:3, 0] @ T_b[:3, 0])) >= np.cos(np.radians(angle_deg))


def drop_grasp(memory, T_world_wrist: np.ndarray, *, reach: float = 0.0) -> tuple:
    """``memory`` (segment memories) without the grasps near pose ``T_world_wrist`` (an
    executed grasp; :func:`near_pose` with ``reach``). A failed grasp's twins (the
    other rows of the same contact pair) fail the same way on a scene that did not change."""
    T = np.asarray(T_world_wrist, float)
    return tuple(replace(m, grasps=tuple(g for g in m.grasps if not near_pose(T, g.T_world_wrist, reach=reach)))
                 for m in memory)
