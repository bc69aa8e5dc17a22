"""Choosing the grasps to try: table clearance and grade-stratified samples (pure numpy).

Maps are planned without the table, so many of their poses put the gripper into it:
those are START_COLLISION in simulation, not failed grasps. Calibration therefore draws
its grasps among the poses that clear the table (checked here with the planner's own
gripper boxes) and reports the rest apart.
"""

from __future__ import annotations

import numpy as np

from graspsim.errors import InvalidParameterError

__all__ = ["stratified_rows"]



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
