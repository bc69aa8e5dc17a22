"""Choosing the grasps to try: table clearance and grade-stratified samples (pure numpy).

Maps are planned without the table, so many of their poses put the gripper into it:
those are START_COLLISION in simulation, not failed grasps. Calibration therefore draws
its grasps among the poses that clear the table (checked here with the planner's own
gripper boxes) and reports the rest apart.
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.gripper import GripperSpec

__all__ = ["table_clearance", "pregrasp_openings", "stratified_rows"]

_CORNERS = np.array(np.meshgrid([-1.0, 1.0], [-1.0, 1.0], [-1.0, 1.0], indexing="ij")).reshape(3, -1).T


def pregrasp_openings(gripper: GripperSpec, widths: np.ndarray) -> np.ndarray:
    """Pad gap (N,) [m] at the pose: contact width + 2 x approach clearance, in range
    (as the simulator opens the jaws)."""
    return np.clip(np.asarray(widths, float) + 2.0 * gripper.approach_clearance,
                   gripper.min_opening, gripper.max_opening)


def table_clearance(T_world_wrist: np.ndarray, widths: np.ndarray, gripper: GripperSpec) -> np.ndarray:
    """Lowest height (N,) [m] above the table plane z = 0 of any corner of the
    gripper's collision boxes (arm, housing, jaws, fingers opened to the pre-grasp gap)
    for wrist poses T_world_wrist (N, 4, 4); negative where the gripper is in the table."""
    T = np.asarray(T_world_wrist, float)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) != len(widths):
        raise InvalidParameterError(f"T_world_wrist must be (N, 4, 4) with N widths; got {T.shape}")
    b = gripper.collision_boxes()
    half_open = 0.5 * pregrasp_openings(gripper, widths)
    corners = b.centers[:, None, :] + b.half_extents[:, None, :] * _CORNERS[None]  # (B, 8, 3)
    # z of corner c of box k: row z of R . (corner + x_sign * half_open * e_x) + t_z
    rz = T[:, 2, :3]
    z = np.einsum("nj,kcj->nkc", rz, corners) + T[:, 2, 3][:, None, None]
    z += (rz[:, 0][:, None] * half_open[:, None])[:, :, None] * b.x_sign[None, :, None]
    return z.reshape(len(T), -1).min(axis=1)


def stratified_rows(score: np.ndarray, eligible: np.ndarray, per_bin: int,
                    rng: np.random.Generator, edges=np.linspace(0.0, 1.0, 11)
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``per_bin`` rows drawn without replacement from each score bin among the
    ``eligible`` (N,) rows. Returns the rows (n,) and their inverse inclusion
    probabilities (n,) (bin population / rows drawn from it), which turn sample
    statistics back into statistics of the eligible population."""
    score = np.asarray(score, float)
    eligible = np.asarray(eligible, bool)
    if per_bin < 1:
        raise InvalidParameterError(f"per_bin must be >= 1, got {per_bin}")
    edges = np.asarray(edges, float)
    b = np.clip(np.searchsorted(edges, score, side="right") - 1, 0, len(edges) - 2)
    rows, weights = [], []
    for k in range(len(edges) - 1):
        pool = np.flatnonzero(eligible & (b == k))
        if len(pool) == 0:
            continue
        take = rng.choice(pool, min(per_bin, len(pool)), replace=False)
        rows.append(np.sort(take))
        weights.append(np.full(len(take), len(pool) / len(take)))
    if not rows:
        return np.zeros(0, int), np.zeros(0)
    return np.concatenate(rows), np.concatenate(weights)
