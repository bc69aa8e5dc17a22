"""Collision checks of arbitrary gripper poses (the same exact-or-conservative test as
map generation, for poses that do not come in full roll x depth sweeps).

Two implementations with the same semantics -- a pose collides if the gripper
penetrates the object, and poses within ``tolerance`` of touching count as colliding:

* :func:`boxes_clear_sdf`: branch and bound on the object's exact signed distance
  over the gripper's boxes. A (sub-)box whose centre is farther from the object than
  its half-diagonal is clear; a centre inside the object is a certain collision;
  otherwise the box is halved along its longest edge, down to the tolerance. No set-up
  cost, so it suits a handful of poses (the first streamed grasps).
* :func:`collision_free`: the compiled line sweep of ``generate`` with one roll and
  one depth per pose. It builds the object's sample hierarchy once (tenths of a
  second, cached), then costs a few microseconds per pose.
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.generate import ClosingLines, sweep_collisions
from graspsim.maps.map_config import MapConfig

__all__ = ["boxes_clear_sdf", "collision_free", "grasps_collision_free"]


def _check_openings(gripper: GripperSpec, opening: np.ndarray) -> None:
    if np.any(opening < gripper.min_opening - 1e-12) or np.any(opening > gripper.max_opening + 1e-12):
        raise InvalidParameterError(
            f"openings must lie in [{gripper.min_opening}, {gripper.max_opening}] m")


def boxes_clear_sdf(shape, gripper: GripperSpec, T_obj_wrist: np.ndarray, opening: np.ndarray,
                    tolerance: float = 0.00025, max_rounds: int = 64) -> np.ndarray:
    """(N,) bool: gripper at poses ``T_obj_wrist`` (N, 4, 4) with pad gaps ``opening`` (N,)
    clear of ``shape`` (anything with an exact ``sdf``), by branch and bound."""
    T = np.asarray(T_obj_wrist, float).reshape(-1, 4, 4)
    n = len(T)
    opening = np.broadcast_to(np.asarray(opening, float), (n,))
    _check_openings(gripper, opening)
    boxes = gripper.collision_boxes()
    B = len(boxes.names)
    c = np.broadcast_to(boxes.centers, (n, B, 3)).copy()
    c[:, :, 0] += boxes.x_sign[None, :] * 0.5 * opening[:, None]
    # frontier: pose index, centre (wrist frame), half extents
    pose = np.repeat(np.arange(n), B)
    ctr = c.reshape(-1, 3)
    half = np.tile(boxes.half_extents, (n, 1))
    hit = np.zeros(n, bool)
    R, p = T[:, :3, :3], T[:, :3, 3]
    for _ in range(max_rounds):
        if len(pose) == 0:
            break
        keep = ~hit[pose]
        pose, ctr, half = pose[keep], ctr[keep], half[keep]
        if len(pose) == 0:
            break
        world = np.einsum("nij,nj->ni", R[pose], ctr) + p[pose]
        d = shape.sdf(world)
        r = np.linalg.norm(half, axis=1)
        inside = d < 0.0
        small = r <= tolerance
        hit[pose[inside | (small & (d <= r))]] = True
        split = (d <= r) & ~inside & ~small
        pose, ctr, half = pose[split], ctr[split], half[split]
        # halve each remaining box along its longest edge
        k = np.argmax(half, axis=1)
        rows = np.arange(len(k))
        half = half.copy()
        half[rows, k] *= 0.5
        off = np.zeros_like(ctr)
        off[rows, k] = half[rows, k]
        pose = np.concatenate([pose, pose])
        ctr = np.concatenate([ctr - off, ctr + off])
        half = np.concatenate([half, half])
    else:  # ran out of rounds: whatever is left counts as colliding (conservative)
        hit[pose] = True
    return ~hit


def collision_free(shape, gripper: GripperSpec, T_obj_wrist: np.ndarray, opening: np.ndarray,
                   config: MapConfig | None = None, threads: int | None = None) -> np.ndarray:
    """(N,) bool: the gripper at wrist poses ``T_obj_wrist`` (N, 4, 4), jaws at pad gaps
    ``opening`` (N,) [m], does not touch the object (map generation's test)."""
    cfg = config or MapConfig()
    T = np.asarray(T_obj_wrist, float).reshape(-1, 4, 4)
    opening = np.broadcast_to(np.asarray(opening, float), (len(T),))
    _check_openings(gripper, opening)
    if len(T) == 0:
        return np.zeros(0, bool)
    x, z = T[:, :3, 0], T[:, :3, 2]
    d0 = gripper.depth_lo
    gp = gripper.grasp_point_from_wrist(T[:, :3, 3], z, d0)
    # one line per pose, its roll 0 the pose's own approach axis: e1 = z, e2 = x X z
    lines = ClosingLines(p1=gp, p2=gp, n1=z, n2=z, u=x, width=opening - 2 * gripper.approach_clearance,
                         gp=gp, e1=z, e2=np.cross(x, z), outside=np.ones(len(T), bool),
                         contacts=len(T), directions=1)
    free, _ = sweep_collisions(shape, lines, gripper, cfg, threads, rolls=np.zeros(1),
                               depths=np.array([d0]))
    return free[:, 0, 0].astype(bool)


def grasps_collision_free(shape, gripper: GripperSpec, gp: np.ndarray, R: np.ndarray,
                          depth: np.ndarray, width: np.ndarray, config: MapConfig | None = None,
                          *, line: np.ndarray | None = None, small: int = 48) -> np.ndarray:
    """(N,) bool for grasps given as grasp point gp (N, 3), wrist rotation R (N, 3, 3),
    contact depth (N,) and contact width (N,) [m] (pre-grasp opening = width + 2 x
    clearance).

    Grasps that share a closing line (same grasp point, closing axis and width; give
    ``line`` (N,) ids to say which do, else exact equality decides) are checked together
    by the compiled sweep when their rolls and depths fall on a common grid (as scaled
    or combined maps' grasps do); a few grasps go to the branch-and-bound check, and
    anything else pose by pose. Grouped grasps are checked at their roll rounded to
    1e-5 rad (micrometres at the fingertips).
    """
    cfg = config or MapConfig()
    gp, R = np.asarray(gp, float), np.asarray(R, float)
    n = len(gp)
    depth, width = np.asarray(depth, float), np.asarray(width, float)
    opening = width + 2 * gripper.approach_clearance
    if n == 0:
        return np.zeros(0, bool)
    z = R[:, :, 2]
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = gripper.wrist_from_grasp_point(gp, z, depth)
    T[:, 3, 3] = 1.0
    if n <= small:
        return boxes_clear_sdf(shape, gripper, T, opening, cfg.collision_tolerance)
    u = R[:, :, 0]
    if line is None:
        line = np.unique(np.column_stack([gp, u, width]), axis=0, return_inverse=True)[1]
    _, first, row_line = np.unique(np.asarray(line).ravel(), return_index=True, return_inverse=True)
    row_line = row_line.ravel()
    lines = np.column_stack([gp[first], u[first], width[first]])
    # each line's roll 0 is its first grasp's approach axis: grasps that came from one
    # map line keep their rolls on the map's roll grid, whatever frame they are in now
    e1 = z[first]
    e2 = np.cross(lines[:, 3:6], e1)
    roll = np.mod(np.arctan2(np.einsum("ni,ni->n", z, e2[row_line]),
                             np.einsum("ni,ni->n", z, e1[row_line])), 2 * np.pi)
    roll = np.where(roll > 2 * np.pi - 5e-6, 0.0, roll)
    rolls, roll_idx = np.unique(np.round(roll, 5), return_inverse=True)
    depths, depth_idx = np.unique(np.round(depth, 7), return_inverse=True)
    L = len(lines)
    if len(rolls) > 64 or L * len(rolls) * len(depths) > 1 << 24:
        # off any common grid (or the pose grid would not fit in memory): pose by pose
        return collision_free(shape, gripper, T, opening, cfg)
    cl = ClosingLines(p1=lines[:, :3], p2=lines[:, :3], n1=e1, n2=e1, u=lines[:, 3:6],
                      width=lines[:, 6], gp=lines[:, :3], e1=e1, e2=e2,
                      outside=np.ones(L, bool), contacts=L, directions=1)
    ri, di = roll_idx.ravel(), depth_idx.ravel()
    need = np.zeros((L, len(rolls), len(depths)), np.uint8)
    need[row_line, ri, di] = 1  # refine only the poses asked about
    free, _ = sweep_collisions(shape, cl, gripper, cfg, rolls=rolls, depths=depths, need=need)
    return free[row_line, ri, di].astype(bool)
