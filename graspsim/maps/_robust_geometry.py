"""Geometry the robust score (:mod:`graspsim.maps.robust`) feeds its kernel: the
identified shape's surface samples, observed points in the object frame, the table per
grasp and the gripper's merged boxes."""

from __future__ import annotations

import functools
import json

import numpy as np

from graspsim.grippers.spec import GripperSpec

__all__ = ["object_points", "cloud_in_object", "map_table", "table_rows", "merged_boxes"]


@functools.lru_cache(maxsize=16)
def _primitive_points(obj_json: str, step: float) -> np.ndarray:
    from graspsim.primitives import shape_from_dict

    shape = shape_from_dict(json.loads(obj_json))
    step = min(step, 0.5 * shape.size_scale) if hasattr(shape, "size_scale") else step
    return np.ascontiguousarray(shape.surface_samples(step).points, float)


def object_points(meta, step: float) -> np.ndarray:
    """Surface samples (M, 3) of the map's identified shape (none for a mesh object)."""
    obj = meta.object
    if obj.get("primitive") in (None, "mesh", "unidentified") or "file" in obj:
        return np.zeros((0, 3))
    key = {k: obj[k] for k in ("primitive", "dims", "parts", "poses", "com") if k in obj}
    return _primitive_points(json.dumps(key, sort_keys=True), float(step))


def cloud_in_object(points: np.ndarray, T_cloud_obj: np.ndarray) -> np.ndarray | None:
    """Observed points (M, 3) given in the cloud (sensor) frame, in the object frame
    whose pose in the cloud is ``T_cloud_obj`` (4, 4) (a map's ``meta.placement``);
    non-finite points dropped; None when no point is left."""
    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not len(pts):
        return None
    T = np.asarray(T_cloud_obj, float)
    return (pts - T[:3, 3]) @ T[:3, :3]


def map_table(gmap) -> tuple[np.ndarray, float] | None:
    """The map's table (``meta.placement``) in the object frame: (unit normal (3,),
    height of the plane along it), or None without one."""
    pl = gmap.meta.placement
    if pl is None or pl.table is None:
        return None
    n = np.asarray(pl.table["normal"], float)
    return pl.T_cloud_obj[:3, :3].T @ n, float(pl.table["height"]) - float(n @ pl.T_cloud_obj[:3, 3])


#: The ceiling column of :func:`table_rows` where there is none (the kernel runs with
#: fastmath, which assumes finite numbers).
NO_CEILING = 1e9


def table_rows(table: tuple[np.ndarray, float] | None, R: np.ndarray, w: np.ndarray,
               ceiling: np.ndarray | None = None) -> np.ndarray:
    """(n, 6) per wrist pose (R (n, 3, 3), w (n, 3)): the table's normal in the wrist
    frame, the wrist origin's height above the table, the required height (0), and the
    ceiling [m] the gripper's lowest point must stay under (``ceiling`` (n,); None or
    non-finite: none); no table: a zero normal and 1 so that every box stays above it."""
    out = np.zeros((len(R), 6))
    out[:, 5] = NO_CEILING
    if table is None:
        out[:, 3] = 1.0
        return out
    n_obj, h_obj = np.asarray(table[0], float), float(table[1])
    out[:, :3] = np.einsum("nji,j->ni", R, n_obj)
    out[:, 3] = w @ n_obj - h_obj
    if ceiling is not None:
        c = np.asarray(ceiling, float).reshape(-1)
        out[:, 5] = np.where(np.isfinite(c), c, NO_CEILING)
    return out


def merged_boxes(g: GripperSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The gripper's boxes (centres, half extents (B, 3), x signs (B,)), with the arm
    keep-out and the housing -- one footprint, stacked -- as one box (the same union)."""
    b = g.collision_boxes()
    c, h, sgn = b.centers.astype(float), b.half_extents.astype(float), b.x_sign.astype(float)
    names = list(b.names)
    if "arm" in names and "housing" in names:
        a, k = names.index("arm"), names.index("housing")
        if np.allclose(h[a, :2], h[k, :2]) and abs((c[a, 2] + h[a, 2]) - (c[k, 2] - h[k, 2])) < 1e-12:
            lo, hi = c[a, 2] - h[a, 2], c[k, 2] + h[k, 2]
            c[k, 2], h[k, 2] = 0.5 * (lo + hi), 0.5 * (hi - lo)
            keep = np.arange(len(names)) != a
            c, h, sgn = c[keep], h[keep], sgn[keep]
    return np.ascontiguousarray(c), np.ascontiguousarray(h), np.ascontiguousarray(sgn)
