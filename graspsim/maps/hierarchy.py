"""The collision sample hierarchy of an object (coarse -> middle -> fine).

The compiled sweep (``_kernel``) tests gripper parts against surface samples on three
levels. Every surface point lies within the fine level's cover radius of a fine
sample; each fine sample belongs to a middle one and each middle one to a coarse one
(the cell that holds it, from the samplings' nested cell grids, else the nearest);
each parent's *patch* -- the largest tangential and normal offsets of what it stands
for -- bounds where those surface points can be, so a coarse test grown by its patch
is conservative and only uncertain poses descend. ``MapConfig.collision_step`` sets the
coarse spacing, ``collision_tolerance`` the fine cover radius.
"""

from __future__ import annotations

import collections
import json
import math

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["sample_levels", "build_levels", "clear_caches", "clusters"]


def _patches(parents, children, parent_normals, grow, parent=None):
    """Assign ``children`` (K, 3) to their nearest parent and measure each parent's
    patch: the largest tangential and normal (along the parent's normal) offsets of
    its children, each grown by the child's own reach ``grow`` (K,) (0 for samples
    that stand only for themselves). Returns the children's order by parent, RT, HN
    (P,) and CSR offsets (P + 1,). ``parent`` (K,): each child's parent if known (the
    cell holding it), else the nearest parent. Compiled
    (:func:`~graspsim.maps._hierarchy_kernel.patch_extents`)."""
    from graspsim.maps._hierarchy_kernel import patch_extents

    if parent is None:
        _, parent = cKDTree(parents).query(children)
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    K, P = len(children), len(parents)
    order, RT, HN = np.empty(K, np.int64), np.zeros(P), np.zeros(P)
    start = patch_extents(f64(parents), f64(children), f64(parent_normals),
                          f64(np.broadcast_to(np.asarray(grow, float), (K,))),
                          np.ascontiguousarray(parent, np.int64), order, RT, HN)
    return order, RT, HN, start


_LEVELS: collections.OrderedDict[tuple, dict] = collections.OrderedDict()  # a few objects


def clear_caches() -> None:
    """Forget cached collision sample hierarchies (to time or free a cold start)."""
    _LEVELS.clear()


def sample_levels(shape, cfg) -> dict[str, np.ndarray | float]:
    """Cached :func:`build_levels` (a few objects: scaling and combining revisit them);
    keyed by the object's description, so compounds (not hashable) are cached too."""
    key = (json.dumps(shape.to_dict(), sort_keys=True), cfg)
    if key in _LEVELS:
        _LEVELS.move_to_end(key)
        return _LEVELS[key]
    lv = build_levels(shape, cfg)
    _LEVELS[key] = lv
    while len(_LEVELS) > 8:
        _LEVELS.popitem(last=False)
    return lv


def build_levels(shape, cfg) -> dict[str, np.ndarray | float]:
    """The three-level collision sample hierarchy (coarse -> middle -> fine).

    Every surface point lies within ``fine_cover`` of a fine sample; each fine sample
    belongs to its nearest middle sample and each middle one to its nearest coarse
    one. A sample's patch (RT: tangential radius, HN: height along its normal) bounds
    where the surface points it stands for can be. Children arrays are ordered by
    parent with CSR offsets. Raises :class:`~graspsim.errors.BudgetExceededError`
    first if the fine samples would not fit the memory budget.
    """
    from graspsim.maps._hierarchy_kernel import regroup
    from graspsim.maps.preflight import check_collision_samples

    check_collision_samples(shape, cfg)
    coarse = shape.surface_samples(min(cfg.collision_step, shape.size_scale))
    fstep = cfg.collision_tolerance * 1.3  # cell-centre grids cover ~ step / sqrt(2)
    fine = shape.surface_samples(fstep)
    while fine.cover_radius > cfg.collision_tolerance:
        fstep *= 0.9
        fine = shape.surface_samples(fstep)
    # middle level: geometric mean spacing, so both refinement steps have ~equal fan-out
    mid = shape.surface_samples(math.sqrt(fstep * min(cfg.collision_step, shape.size_scale)))
    # parents: the cell that holds each child (nested grids), or the nearest sample
    f_order, RTM, HNM, fstart = _patches(mid.points, fine.points, mid.normals, 0.0,
                                         mid.locate(fine))
    # a middle patch reaches at most hypot(RT, HN) from its sample in any direction
    # (Cauchy-Schwarz), which grows the coarse patches that contain it
    m_order, RT, HN, mstart = _patches(coarse.points, mid.points, coarse.normals,
                                       np.hypot(RTM, HNM), coarse.locate(mid))
    # reorder the middle level (and its patch data / fine offsets) by coarse parent
    take = lambda a, i: np.take(a, i, axis=0)  # noqa: E731 -- a[i], without fancy indexing's overhead
    Mp, NMp = take(mid.points, m_order), take(mid.normals, m_order)
    RTMp, HNMp = take(RTM, m_order), take(HNM, m_order)
    # fine samples, grouped by middle parent in the middle level's new order (compiled copies)
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    F, NF, RTF, HNF, fstart_new = regroup(f_order, fstart, np.ascontiguousarray(m_order, np.int64),
                                          f64(fine.points), f64(fine.normals), f64(fine.tangent_radius),
                                          f64(fine.normal_height))
    return {"Q": coarse.points, "NQ": coarse.normals, "RT": RT, "HN": HN,
            "M": Mp, "NM": NMp, "RTM": RTMp, "HNM": HNMp, "mstart": mstart,
            "F": F, "NF": NF, "RTF": RTF, "HNF": HNF, "fstart": fstart_new,
            "fine_cover": float(fine.cover_radius)}


def clusters(points: np.ndarray, reach: np.ndarray, size: int = 16, margin: float = 1e-5):
    """Spatial clusters of samples, for the compiled sweep to pass over the clusters
    that cannot touch the gripper: ``(order, start, centre, radius, reach_max)`` --
    cluster c holds samples ``order[start[c]:start[c + 1]]`` (at most ``size``, by
    halving along the widest extent at the median), all within ``radius[c]`` of
    ``centre[c]`` and with ``reach`` (N,) at most ``reach_max[c]``, both grown by
    ``margin`` [m] (far more than float32 rounding of the coordinates). Compiled
    (:func:`~graspsim.maps._hierarchy_kernel.cluster_tree`)."""
    from graspsim.maps._hierarchy_kernel import cluster_tree

    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    reach = np.ascontiguousarray(np.broadcast_to(np.asarray(reach, float), (len(points),)))
    order, start, centre, radius, reach_max = cluster_tree(points, reach, int(size))
    return order, start, centre, radius + margin, reach_max + margin
