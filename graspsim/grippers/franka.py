"""The Franka Emika hand: its :class:`GripperSpec` measured from the vendored model.

Nothing here is typed in from a data sheet: the boxes, the stroke, the force and the
closing speed are read from ``mjcf/franka_hand/franka_hand.xml`` (converted from the
maker's URDF) and from its collision meshes (MuJoCo collides with their convex hulls).

Frame mapping. The hand frame H of the URDF has z = approach and the fingers closing
along y; graspsim's wrist frame W has z = approach and x = closing axis, y = z x x. So

    x_W = y_H,   y_W = -x_H,   z_W = z_H - z0,

a -90 deg turn about z (R_W_H = Rz(-90 deg)) with the origin moved to z0 = the lowest z
of the hand's hull (-25.9 mm: the mesh reaches behind the URDF's hand origin), so the
spec's housing box starts at z_W = 0. The left finger (joint 1, +y_H) is the +x jaw.

Boxes (all from the hulls, at every opening; each encloses its part), measured by
:mod:`graspsim.grippers.model_file` as for any model file:
* housing: the hand's hull;
* finger (the pad carrier): the part of the finger hull from the top of its flat inner
  face (the pad: hull vertices within ``PAD_TOL`` of the innermost plane) to the tip;
* jaw: the rest of the finger below the hand's hull; the finger's root inside the
  hand's hull is covered by the housing box.
"""

from __future__ import annotations

import numpy as np

from graspsim.grippers.model_file import vendored_gripper
from graspsim.grippers.spec import GripperSpec
from graspsim.grippers.vendored import Mount

__all__ = ["franka_hand_spec", "franka_hand_mount", "hand_to_wrist", "hull_points", "clip_z", "PAD_TOL"]

NAME = "franka_hand"
PAD_TOL = 2.5e-4  # [m] hull vertices this close to the innermost finger plane form the pad
GRID = 1e-5  # [m] measured lengths are rounded outwards to this


def hand_to_wrist(p_hand: np.ndarray, z0: float) -> np.ndarray:
    """Points (N, 3) [m] from the hand frame to the wrist frame (see the module doc)."""
    p = np.asarray(p_hand, float)
    return np.stack([p[..., 1], -p[..., 0], p[..., 2] - z0], axis=-1)


def hull_points(model, data, geom: str) -> np.ndarray:
    """(V, 3) [m] world positions of the vertices of a mesh geom's convex hull."""
    from scipy.spatial import ConvexHull

    g = model.geom(geom)
    mid = int(model.geom_dataid[g.id])
    a, n = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
    v = model.mesh_vert[a:a + n]
    v = v[ConvexHull(v).vertices]
    return data.geom_xpos[g.id] + v @ data.geom_xmat[g.id].reshape(3, 3).T


def _grid(v: float, rnd=np.ceil) -> float:
    """``v`` [m] rounded outwards (``rnd``) to 0.01 mm: the boxes still enclose the hulls,
    and the spec's digest does not move with the last bits of a mesh compiler."""
    return round(float(rnd(float(v) / GRID - 1e-6 * np.sign(v))) * GRID, 8)


def clip_z(points: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Vertices (K, 3) of the convex hull of ``points`` (N, 3) cut to lo <= z <= hi: the
    hull vertices inside and the points where hull edges cross the two planes."""
    from scipy.spatial import ConvexHull

    p = points[ConvexHull(points).vertices]
    i, j = np.triu_indices(len(p), 1)  # every vertex pair: crossings of the hull's edges
    a, b = p[i], p[j]                  # are among them, and all lie in the hull
    out = [p[(p[:, 2] >= lo) & (p[:, 2] <= hi)]]
    for z in (lo, hi):
        if not np.isfinite(z):
            continue
        cross = (a[:, 2] - z) * (b[:, 2] - z) < 0
        t = (z - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
        out.append(a[cross] + t[:, None] * (b[cross] - a[cross]))
    q = np.concatenate(out)
    return q[ConvexHull(q).vertices]


def franka_hand_spec() -> GripperSpec:
    """The Franka hand's spec, measured from its vendored model by the path every model
    file takes (:mod:`graspsim.grippers.model_file`). What the file cannot say is in
    ``franka_hand.gripper.json`` beside it: the pad gap is the sum of the two finger
    joints (the URDF's convention: each joint is half the gap; the finger meshes' inner
    faces lie 0.1 mm past the joints' zero). Stroke and closed gap: the joints' range;
    grip force: the actuator's gain (70 N); closing speed: force / joint damping."""
    return vendored_gripper(NAME)[0]


def franka_hand_mount() -> Mount:
    """The hand frame in the wrist frame: origin at (0, 0, -z0), turned Rz(-90 deg)."""
    return vendored_gripper(NAME)[1]
