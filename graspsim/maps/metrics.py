"""Map quality metrics: surface rate SR and volume rate VR (paper eqs. 7-8), and the
voxel view of a map (docs/design.md §6).

* SR: the object's surface is divided into pixels (the surface samples at the map's
  surface step); SR = share of pixels holding a contact of at least one grasp whose
  grade exceeds ``min_grade`` (paper: quality > 0).
* VR: wrist positions binned into voxels at the map resolution inside the box that
  can hold a wrist (the object's bounding box grown by the gripper's reach from the
  grasp point to the wrist); VR = share of those voxels holding a grasp.
* SRN, VRN: a map's SR / VR relative to a reference (full-scale) map of the same
  object, in percent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.graspmap import GraspabilityMap

__all__ = ["MapRates", "map_rates", "relative_rates", "voxel_keys", "orientation_bins"]


@dataclass(frozen=True)
class MapRates:
    """sr, vr in [0, 1]; pixels, voxels: the normalising counts; hit_pixels, hit_voxels."""

    sr: float
    vr: float
    pixels: int
    voxels: int
    hit_pixels: int
    hit_voxels: int


def map_rates(gmap: GraspabilityMap, *, shape=None, min_grade: float = 0.0,
              resolution: float | None = None, box_gripper: GripperSpec | None = None) -> MapRates:
    """SR and VR of ``gmap`` (its object rebuilt from the map's metadata unless given).
    box_gripper: the gripper whose reach sizes VR's voxel box (default: the map's own;
    give one gripper to compare maps of different grippers over the same box)."""
    shape = shape if shape is not None else gmap.meta.shape
    res = float(resolution or gmap.meta.surface_step)
    if not res > 0:
        raise InvalidParameterError(f"resolution must be > 0 m, got {res!r}")
    sel = gmap.above(min_grade)
    pixels = shape.surface_samples(res).points
    c = gmap.contacts[sel]
    # maps repeat each contact pair over rolls and depths in consecutive rows
    if len(c) > 1:
        c = c[np.r_[True, np.any(c[1:] != c[:-1], axis=(1, 2))]]
    hit = np.zeros(len(pixels), bool)
    if len(c):
        _, pix = cKDTree(pixels).query(c.reshape(-1, 3).astype(float))
        hit[pix] = True
    hit_pixels = int(hit.sum())
    lo, hi = wrist_box(shape, box_gripper or gmap.meta.gripper_spec)
    n_vox = np.ceil((hi - lo) / res - 1e-9).astype(np.int64)
    # voxel coordinates as whole float32 numbers, bounds-checked before the integer cast
    # (in place: maps hold millions of rows)
    f = (gmap.wrist_position if sel.all() else gmap.wrist_position[sel]) - lo.astype(np.float32)
    f /= np.float32(res)
    np.floor(f, out=f)
    v = f[np.all((f >= 0) & (f < n_vox.astype(np.float32)), axis=1)].astype(np.int64)
    occupied = np.zeros(int(np.prod(n_vox)), bool)
    occupied[(v[:, 0] * n_vox[1] + v[:, 1]) * n_vox[2] + v[:, 2]] = True
    hit_voxels = int(occupied.sum())
    voxels = int(occupied.size)
    return MapRates(hit_pixels / len(pixels), hit_voxels / voxels, len(pixels), voxels,
                    hit_pixels, hit_voxels)


def wrist_box(shape, gripper: GripperSpec) -> tuple[np.ndarray, np.ndarray]:
    """Box that can hold a wrist: the object's bounds grown by the longest grasp point
    to wrist distance (the TCP offset at the smallest contact depth) [m]."""
    reach = float(gripper.tcp_offset(gripper.depth_lo))
    b = shape.aabb
    return b[0] - reach, b[1] + reach


def relative_rates(gmap: GraspabilityMap, reference: GraspabilityMap, *, shape=None,
                   min_grade: float = 0.0) -> dict[str, float]:
    """SRN and VRN [%] of ``gmap`` against ``reference`` (paper eqs. 7-8)."""
    shape = shape if shape is not None else reference.meta.shape
    a = map_rates(gmap, shape=shape, min_grade=min_grade)
    b = map_rates(reference, shape=shape, min_grade=min_grade)
    return {"SR": a.sr, "VR": a.vr, "SR_ref": b.sr, "VR_ref": b.vr,
            "SRN": 100.0 * a.sr / b.sr if b.sr else math.nan,
            "VRN": 100.0 * a.vr / b.vr if b.vr else math.nan}


def orientation_bins(quat_wxyz: np.ndarray, step: float) -> np.ndarray:
    """(N, 2) integer orientation bins at angular ``step`` [rad]: the approach axis's
    nearest direction on a quasi-uniform sphere grid, and the roll of the closing
    axis about it in a fixed frame of that grid direction."""
    from graspsim.transforms import quat_to_matrix

    R = quat_to_matrix(np.asarray(quat_wxyz, float))
    n_dirs = max(12, int(round(4 * math.pi / step**2)))
    i = np.arange(n_dirs) + 0.5
    phi = np.arccos(1 - 2 * i / n_dirs)
    theta = math.pi * (1 + 5**0.5) * i
    grid = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    _, d = cKDTree(grid).query(R[:, :, 2])
    g = grid[d]
    helper = np.where(np.abs(g[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(helper, g)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(g, t1)
    x = R[:, :, 0]
    roll = np.arctan2(np.sum(x * t2, axis=1), np.sum(x * t1, axis=1))
    n_roll = max(1, int(round(2 * math.pi / step)))
    return np.column_stack([d, np.floor((roll + math.pi) / (2 * math.pi) * n_roll).astype(np.int64) % n_roll])


def voxel_keys(gmap: GraspabilityMap, resolution: float | None = None,
               rotation_step: float | None = None) -> np.ndarray:
    """(N, 5) int64 voxel of each grasp: wrist position bin (3) at the map resolution
    and orientation bin (2) at the rotation step -- the map's voxel view."""
    res = float(resolution or gmap.meta.surface_step)
    step = float(rotation_step or gmap.meta.rotation_step)
    pos = np.floor(gmap.wrist_position.astype(float) / res).astype(np.int64)
    return np.column_stack([pos, orientation_bins(gmap.wrist_quat, step)])
