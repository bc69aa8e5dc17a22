"""Candidate grasps for the selection environment: a pooled map database and the
fixed-size candidate feature table.

* :class:`PooledDatabase` is a :class:`MapDatabase` whose run-time reads
  (``load_entry(..., accepted_only=True)``, what the planner uses) return a fixed,
  surface-uniform subset of ``pool_size`` accepted grasps of each stored map instead of
  all of them (10^4 - 10^5). Scaling a pool of 10^3 grasps takes tens of milliseconds
  instead of half a second, so an episode costs little more than its trial; the adapted
  map is a uniform subsample of the full one. The pool is drawn once per map from the
  stream ``rng_for(seed, "pool", key)`` of the seed rule (:mod:`graspsim.seeding`), so it
  is the same in every process for a given ``seed`` (default 0).
* Whether a candidate clears the table is :meth:`GripperSpec.lowest_point` (the arm
  keep-out included) at the pre-grasp opening.
* :func:`candidate_features` lays K grasps out as the observation's rows.

Pure numpy: no mujoco here.
"""

from __future__ import annotations

import logging

import numpy as np

from graspsim.maps.database import MapDatabase
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.robust import extra_openings
from graspsim.seeding import rng_for

__all__ = ["PooledDatabase", "candidate_features", "CANDIDATE_FEATURES"]

log = logging.getLogger(__name__)

#: Columns of the ``candidates`` observation (one row per candidate): wrist position
#: [m] and quaternion (w, x, y, z) in the estimated object frame, grade and its
#: components q_fc, q_st, force-closure angle [rad], stability distance [m], contact
#: width [m] (the jaws open to width + 2 x the approach clearance), the planner's robust
#: score (expected success under the execution error; 0 when not scored) and the
#: gripper's clearance to the observed cloud [m] (clipped to +-5 cm; 5 cm when not
#: scored) -- see :mod:`graspsim.maps.robust` -- and the extra pad gap per side [m] the
#: robust score chose and the trial opens the jaws by (0: the map's pre-grasp opening).
CANDIDATE_FEATURES = ("x", "y", "z", "qw", "qx", "qy", "qz", "grade", "q_fc", "q_st",
                      "fc_angle", "stability_distance", "width", "robust", "clearance", "extra_opening")
_CLEARANCE_CAP = 0.05
_LOW = np.array([-1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, -_CLEARANCE_CAP, 0], np.float32)
_HIGH = np.array([1, 1, 1, 1, 1, 1, 1, 1, 1, 1, np.pi, 1, 1, 1, _CLEARANCE_CAP, 0.05], np.float32)


class PooledDatabase(MapDatabase):
    """A map database whose planner reads return ``pool_size`` surface-uniform accepted
    grasps per stored map (see the module docstring), drawn from the stream
    ``rng_for(seed, "pool", map key)``. Other reads are unchanged."""

    def __init__(self, *args, pool_size: int = 1000, seed: int = 0, **kwargs):
        super().__init__(*args, **kwargs)
        self.pool_size = int(pool_size)
        self.seed = int(seed)
        self._pools: dict[str, GraspabilityMap] = {}

    def load_entry(self, entry: dict, *, accepted_only: bool = False) -> GraspabilityMap:
        if not accepted_only:
            return super().load_entry(entry)
        key = entry["key"]
        pool = self._pools.get(key)
        if pool is None:
            full = super().load_entry(entry, accepted_only=True)
            if len(full) > self.pool_size:
                sub = full.sample_uniform_surface(self.pool_size, rng_for(self.seed, "pool", key))
                pool = sub.select(np.argsort(-sub.grade, kind="stable"))  # best first, as stored
            else:
                pool = full
            self._pools[key] = pool
            log.debug("pooled %d of %d grasps of %s", len(pool), len(full), key)
        return pool


def candidate_features(gmap: GraspabilityMap, rows: np.ndarray, k: int) -> np.ndarray:
    """(k, F) float32 rows of :data:`CANDIDATE_FEATURES` for map ``rows`` (at most k);
    missing rows are zeros (masked out by the caller)."""
    out = np.zeros((k, len(CANDIDATE_FEATURES)), np.float32)
    rows = np.asarray(rows, int)[:k]
    n = len(rows)
    out[:n, 0:3] = gmap.wrist_position[rows]
    out[:n, 3:7] = gmap.wrist_quat[rows]
    out[:n, 7] = gmap.grade[rows]
    out[:n, 8] = gmap.q_fc[rows]
    out[:n, 9] = gmap.q_st[rows]
    out[:n, 10] = gmap.fc_angle[rows]
    out[:n, 11] = gmap.stability_distance[rows]
    out[:n, 12] = gmap.width[rows]
    out[:n, 13] = np.nan_to_num(gmap.robust[rows], nan=0.0)
    out[:n, 14] = np.nan_to_num(gmap.clearance[rows], nan=_CLEARANCE_CAP)
    out[:n, 15] = extra_openings(gmap, rows)
    return np.clip(out, _LOW, _HIGH)


def feature_bounds() -> tuple[np.ndarray, np.ndarray]:
    """(low, high) (F,) bounds of the candidate features."""
    return _LOW.copy(), _HIGH.copy()
