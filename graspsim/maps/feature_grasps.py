"""Grasps on the observed cloud's own graspable features, where the primitives miss the object.

A graspability map is made on the identified primitives. Where no primitive
decomposition explains the object (a thin-walled bowl identified as one sphere wider
than the gripper, a clamp or scissors lying flat fitted as one box whose gaps the fingers
would close on, a curved banana fitted as a box) the parts' grasps are few, none, or
close on shape that is not there. The graspable features are still in the cloud: a
bowl's rim is a thin wall, a tool's handle a bar. This module fits the gripper to them
directly, as the FS map fits it to a primitive's surface:

* seeds: one observed point per ``seed_step`` voxel (the first in input order);
* at each seed, the local axes of its neighbourhood (PCA within ``radius``): the
  surface normal and the across-width direction are the closing axes tried (a wall is
  pinched across its thickness, a bar across its width), and on a table the horizontal
  direction across the neighbourhood's length; each with ``approaches`` approach
  directions perpendicular to it (the first nearest straight down) and the contact
  ``depths`` along the pad;
* the chord the pads would close on: the observed points inside the pads' footprint
  (finger width x pad length about the closing line), the contiguous run of them along
  the closing axis through the seed (gaps up to ``gap``); its two ends are the contacts,
  the closing axis their (outward) normals, the run's length the contact width, at the
  middle height along the approach of the points at the run's ends (a bar's sides, not
  its top corners); a chord wider than the gripper's opening less its approach clearance
  is dropped;
* the paper's grade of each (force closure angle and stability distance, the quality
  model of the map; the cloud's centroid stands in for the centre of mass).

Nothing here checks collisions: the planner offers these grasps only through the same
checks as every other -- the cloud bears the contacts out
(:mod:`~graspsim.maps.agreement`), the table, the gripper clear of every observed point
(:func:`~graspsim.planning.observed.clear_of_cloud`) and the robust score against the cloud.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from graspsim.checks import POSITIVE, check_fields, integer
from graspsim.errors import InvalidParameterError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import GripperSpec
from graspsim.transforms import matrix_to_quat

__all__ = ["FeatureConfig", "feature_columns"]


@dataclass(frozen=True)
class FeatureConfig:
    """min_grasps: feature grasps are added when the identified parts give fewer grasps
    expected to succeed than this (the planner's rule, ``PlannerConfig.features``);
    seed_step [m]: one seed per voxel of this edge; radius [m]:
    the neighbourhood whose axes give the closing directions; approaches: approach
    directions per closing axis (evenly about it); depths [m]: contact depths from the
    fingertips; gap [m]: the largest gap along the closing axis inside one chord
    (None: 3 x the cloud's spacing + 4 x its noise, given by the caller)."""

    min_grasps: int = 10
    seed_step: float = 0.015
    radius: float = 0.01
    approaches: int = 8
    depths: tuple[float, ...] = (0.006, 0.014, 0.022)
    gap: float | None = None

    def __post_init__(self) -> None:
        check_fields(self, POSITIVE.saying("> 0 m"), "seed_step", "radius", owner="FeatureConfig")
        check_fields(self, integer(0), "min_grasps", owner="FeatureConfig")
        check_fields(self, integer(1), "approaches", owner="FeatureConfig")
        depths = tuple(float(d) for d in np.atleast_1d(self.depths))
        if not depths or any(not (math.isfinite(d) and d >= 0) for d in depths):
            raise InvalidParameterError(f"FeatureConfig.depths must be depths >= 0 m, got {self.depths!r}")
        object.__setattr__(self, "depths", depths)

    def to_dict(self) -> dict:
        return {**asdict(self), "depths": list(self.depths)}


def _seeds(points: np.ndarray, step: float) -> np.ndarray:
    keys = np.floor((points - points.min(axis=0)) / step).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return np.sort(first)


def _axes(points, tree, seeds, radius: float, up: np.ndarray | None):
    """Per seed with enough neighbours: (seed index, closing axes (k, 3)) -- the least-
    and middle-variance axes of the points within ``radius``, and with a table (``up``,
    its unit normal) the horizontal axis across the neighbourhood's longest one (a bar
    lying flat is pinched across its width from above); each with a fixed sign."""
    out = []
    for s in seeds:
        nb = tree.query_ball_point(points[s], radius)
        if len(nb) < 5:
            continue
        q = points[nb] - points[nb].mean(axis=0)
        _, vecs = np.linalg.eigh(q.T @ q)
        axes = [vecs[:, 0], vecs[:, 1]]
        if up is not None:
            across = np.cross(up, vecs[:, 2])
            if np.linalg.norm(across) > 0.5:  # the longest axis not near the vertical
                axes.append(across / np.linalg.norm(across))
        axes = np.array(axes)
        axes *= np.where(axes[np.arange(len(axes)), np.argmax(np.abs(axes), axis=1)] > 0, 1.0, -1.0)[:, None]
        out.append((s, axes))
    return out


def feature_columns(points: np.ndarray, gripper: GripperSpec, quality: QualityModel, *, gap: float,
                    config: FeatureConfig = FeatureConfig(), part: int = 0,
                    up: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The map columns (:data:`~graspsim.maps.graspmap.COLUMNS`, ``part`` as given) of the
    feature grasps of the observed ``points`` (N, 3) [m, the map's object frame]; see
    the module docstring. ``gap`` [m]: the largest gap inside one chord (the caller's
    spacing and noise; ``config.gap`` overrides it); ``up`` (3,): the table's normal
    in the same frame, if there is one (horizontal closing axes and straight-down
    approaches are then among the candidates). Deterministic: no draw."""
    from graspsim.maps._feature_kernel import seed_chords  # compiled: the loops over approaches and depths

    P = np.asarray(points, float).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    gap = float(config.gap if config.gap is not None else gap)
    empty = {"wrist_position": np.zeros((0, 3)), "wrist_quat": np.zeros((0, 4)), "grasp_point": np.zeros((0, 3)),
             "contacts": np.zeros((0, 2, 3)), "normals": np.zeros((0, 2, 3)),
             **{k: np.zeros(0) for k in ("width", "fc_angle", "q_fc", "stability_distance", "q_st", "grade")},
             "part": np.zeros(0, np.int16)}
    if len(P) < 10:
        return empty
    tree = cKDTree(P)
    widest = gripper.max_opening - 2.0 * gripper.approach_clearance
    half_w = 0.5 * gripper.finger_size[1]
    reach = math.hypot(0.5 * gripper.max_opening, math.hypot(half_w, gripper.pad_length))
    margin = gripper.contact_depth_margin
    depths = np.array([d for d in config.depths if margin <= d <= gripper.pad_length - margin], float)
    ang = 2.0 * math.pi * np.arange(config.approaches) / config.approaches
    end_band = 0.5 * gap
    rows = []
    down = None if up is None else -np.asarray(up, float) / np.linalg.norm(up)
    for s, axes in _axes(P, tree, _seeds(P, config.seed_step), config.radius, None if up is None else -down):
        near = P[tree.query_ball_point(P[s], reach)] - P[s]
        for c in axes:
            # the approaches about c start from the one nearest straight down (with a table)
            u = down - (down @ c) * c if down is not None else np.zeros(3)
            if np.linalg.norm(u) < 0.3:
                u = np.cross(c, [1.0, 0.0, 0.0] if abs(c[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            v = np.cross(c, u)
            A = np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v  # approaches about c
            x = near @ c
            Z = np.ascontiguousarray(near @ A.T)  # (M, approaches)
            Y = np.ascontiguousarray(near @ np.cross(A, c).T)
            # per approach and depth, the chord in the pads' footprint (finger width x pad length, tip
            # that deep) and its contacts at the middle height (along the approach) of the points at
            # its two ends -- a bar's sides, not its top corners -- the fingertips kept
            ok, lo, hi, zc = seed_chords(x, Y, Z, depths, half_w, gripper.pad_length, gap, end_band,
                                         gripper.contact_depth_margin, widest)
            for f in np.flatnonzero(ok):
                j, d = divmod(int(f), len(depths))
                rows.append((P[s] + 0.5 * (lo[f] + hi[f]) * c + zc[f] * A[j], c, A[j], hi[f] - lo[f],
                             depths[d] - zc[f]))
    if not rows:
        return empty
    gp = np.array([r[0] for r in rows])
    cl = np.array([r[1] for r in rows])
    ap = np.array([r[2] for r in rows])
    w = np.array([r[3] for r in rows])
    depth = np.array([r[4] for r in rows])
    p1, p2 = gp - 0.5 * w[:, None] * cl, gp + 0.5 * w[:, None] * cl
    n1, n2 = -cl, cl
    com = P.mean(axis=0)
    d_ref = quality.reference_distance(float(np.max(np.linalg.norm(P - com, axis=1))))
    g = quality.evaluate(p1, p2, n1, n2, com, d_ref)
    R = np.stack([cl, np.cross(ap, cl), ap], axis=2)  # wrist x: closing, z: approach
    return {"wrist_position": gripper.wrist_from_grasp_point(gp, ap, depth), "wrist_quat": matrix_to_quat(R),
            "grasp_point": gp, "contacts": np.stack([p1, p2], axis=1), "normals": np.stack([n1, n2], axis=1),
            "width": w, "fc_angle": g.fc_angle, "q_fc": g.q_fc, "stability_distance": g.stability_distance,
            "q_st": g.q_st, "grade": g.grade, "part": np.full(len(w), part, np.int16)}
