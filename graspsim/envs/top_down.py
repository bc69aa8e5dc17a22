"""Top-down grasps of a cloud on a table: the classic heuristic, and the same heuristic
checked against what was seen.

:func:`top_down_pose` is the heuristic ``GraspPose-v0`` baselines compare with: approach
straight down over the cloud's centroid, close across its narrowest horizontal
direction (the principal axes of the points' x, y), the pads' middle 2 cm below the
top, opened to the cloud's width there. It knows nothing of where the fingers go: on an
arch (a half torus lying down) or a cylinder lying across, the fingers can come down
onto the object.

:func:`robust_top_down` is the fallback when the planner finds no grasp (identification
failed): top-down candidates at several closing directions, centres and heights, each
closing on the points between its pads, scored with the planner's robust score
(:func:`graspsim.maps.robust.score_poses`: the gripper clear of the observed points and
the table at the pose and under wrist pose error, the contacts on the pads), the best
returned (among equals the one most like the heuristic's pose) -- or None ("no grasp")
when none scores above 0, rather than a pose that collides with what was seen. The
score knows room, not grip: on the episodes where E08's planner found nothing it
trades the heuristic's start collisions for some drops (see the E08 section).
"""

from __future__ import annotations

import math

import numpy as np

from graspsim.grippers.spec import GripperSpec
from graspsim.maps.robust import RobustConfig, score_poses
from graspsim.transforms import frame_from_axes, make_transform

__all__ = ["top_down_pose", "top_down_candidates", "robust_top_down"]

_MIN_BAND_POINTS = 3  # points between the pads for a candidate to close on something


def top_down_pose(cloud: np.ndarray, gripper: GripperSpec) -> tuple[np.ndarray, float]:
    """(T_world_wrist (4, 4), contact width [m]) of the heuristic (module docstring) for
    a cloud (N, 3) in a frame with z up and the table at z = 0."""
    g = gripper
    p = np.asarray(cloud, float)
    c = p[:, :2].mean(axis=0)
    w, v = np.linalg.eigh(np.cov((p[:, :2] - c).T))
    x = np.array([v[0, 0], v[1, 0], 0.0])  # the smaller eigenvalue's axis
    z = np.array([0.0, 0.0, -1.0])
    top = float(p[:, 2].max())
    half_pad = g.nominal_depth  # the nominal TCP's distance from the fingertips
    tcp_z = max(top - half_pad, half_pad + 0.003)  # fingertips stay above the table
    band = p[np.abs(p[:, 2] - tcp_z) < half_pad]
    s = (band if len(band) else p)[:, :2] @ x[:2]
    width = float(np.clip(np.ptp(s), g.min_opening, g.max_opening - 2 * g.approach_clearance))
    centre = c + (0.5 * (s.max() + s.min()) - c @ x[:2]) * x[:2]
    R = frame_from_axes(x, z)
    tcp = np.array([centre[0], centre[1], tcp_z])
    return make_transform(R, tcp - float(g.nominal_tcp[2]) * z), width


def top_down_candidates(cloud: np.ndarray, gripper: GripperSpec, *, yaws: int = 12,
                        offsets: tuple[float, ...] = (-0.25, 0.0, 0.25),
                        depths: tuple[float, ...] = (0.0, 0.01, 0.02),
                        above_table: tuple[float, ...] = (0.003, 0.006, 0.010)
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Top-down candidates of a cloud (N, 3) (z up, table at z = 0): the heuristic's
    pose first, then ``yaws`` closing directions over 180 deg x centres moved by
    ``offsets`` of the cloud's half extent along its two principal axes x TCP heights:
    ``depths`` [m] deeper than the heuristic's, and with the fingertips ``above_table``
    [m] over the table (room for the wrist error on a low object). Each closes on the points between its
    pads: recentred on them, its width their extent, its contacts (n, 2, 3) the extreme
    ones with outward normals (n, 2, 3) along the closing axis. Candidates with fewer
    than 3 points between the pads are dropped. Returns (T (n, 4, 4), width (n,),
    contacts, normals)."""
    g = gripper
    p = np.asarray(cloud, float)
    T0, _ = top_down_pose(p, g)
    c = p[:, :2].mean(axis=0)
    _, v = np.linalg.eigh(np.cov((p[:, :2] - c).T))
    ext = np.ptp((p[:, :2] - c) @ v, axis=0)
    half_pad = g.nominal_depth
    top = float(p[:, 2].max())
    ang = np.arange(yaws) * math.pi / yaws
    centres = np.array([c + a * 0.5 * ext[0] * v[:, 0] + b * 0.5 * ext[1] * v[:, 1] for a in offsets for b in offsets])
    heights = sorted({round(max(h, half_pad + 0.003), 6) for h in
                      [top - half_pad - d for d in depths] + [half_pad + a for a in above_table]
                      if h - half_pad < top - 0.003})  # the fingertips 3 mm below the top at least
    x_dirs = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(yaws)])
    xs = [T0[:3, 0]] + [x for x in x_dirs for _ in centres for _ in heights]
    tcps = [T0[:3, 3] + float(g.nominal_tcp[2]) * T0[:3, 2]] + [
        np.array([cc[0], cc[1], h]) for _ in x_dirs for cc in centres for h in heights]
    x, tcp = np.array(xs), np.array(tcps)
    y = np.cross(np.array([0.0, 0.0, -1.0]), x)
    d = p[None] - tcp[:, None]  # (n, N, 3)
    px, py, pz = np.einsum("nmk,nk->nm", d, x), np.einsum("nmk,nk->nm", d, y), d[..., 2]
    band = (np.abs(py) < 0.5 * g.finger_size[1]) & (np.abs(pz) < half_pad)
    keep = band.sum(axis=1) >= _MIN_BAND_POINTS
    lo = np.where(band, px, np.inf).min(axis=1)
    hi = np.where(band, px, -np.inf).max(axis=1)
    x, y, tcp, lo, hi = x[keep], y[keep], tcp[keep], lo[keep], hi[keep]
    mid = tcp + 0.5 * (lo + hi)[:, None] * x
    half = 0.5 * (hi - lo)[:, None]
    z = np.broadcast_to([0.0, 0.0, -1.0], x.shape)
    T = np.repeat(np.eye(4)[None], len(x), axis=0)
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, y, z
    T[:, :3, 3] = mid - float(g.nominal_tcp[2]) * z
    contacts = np.stack([mid - half * x, mid + half * x], axis=1)
    normals = np.stack([-x, x], axis=1)
    return T, np.maximum(hi - lo, g.min_opening), contacts, normals


def robust_top_down(cloud: np.ndarray, gripper: GripperSpec, *, config: RobustConfig | None = None
                    ) -> tuple[np.ndarray, float] | None:
    """(T_world_wrist (4, 4), contact width [m], plus twice the extra opening per side its
    score chose) of the best-scoring :func:`top_down_candidates` of a cloud (z up, table
    at z = 0), or None when none scores above 0 (module docstring). ``config``: the
    robust score's settings (default: :class:`RobustConfig`, whose jaw openings reach 10 mm
    wider per side)."""
    cfg = config or RobustConfig()
    T, width, contacts, normals = top_down_candidates(cloud, gripper)
    if not len(T):
        return None
    s = score_poses(T, width, contacts, normals, cloud, gripper, table=(np.array([0.0, 0.0, 1.0]), 0.0),
                    config=cfg)
    # ties (the score is a fraction of 32 perturbations): the candidate most like the
    # heuristic's own pose -- its closing direction, then nearest its centre, then its height
    tcp = T[:, :3, 3] + float(gripper.nominal_tcp[2]) * T[:, :3, 2]
    like = np.round(np.abs(T[:, :3, 0] @ T[0, :3, 0]), 3)
    off = np.round(np.linalg.norm(tcp[:, :2] - tcp[0, :2], axis=1), 3)
    i = int(np.lexsort((np.abs(tcp[:, 2] - tcp[0, 2]), off, -like, -s.robust))[0])
    if not s.robust[i] > 0:
        return None
    return T[i], float(width[i] + 2.0 * s.extra_opening[i])
