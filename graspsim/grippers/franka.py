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

Boxes (all from the hulls, at the closed position; each encloses its part):
* housing: the hand's hull;
* finger (the pad carrier): the part of the finger hull from the top of its flat inner
  face (the pad: hull vertices within ``PAD_TOL`` of the innermost plane) to the tip;
* jaw: the rest of the finger below the hand's hull; the finger's root inside the
  hand's hull is covered by the housing box.
"""

from __future__ import annotations

import functools

import numpy as np

from graspsim.grippers.spec import GripperSpec
from graspsim.grippers.vendored import Mount, model_folder

__all__ = ["franka_hand_spec", "franka_hand_mount", "hand_to_wrist", "PAD_TOL"]

NAME = "franka_hand"
PAD_TOL = 2.5e-4  # [m] hull vertices this close to the innermost finger plane form the pad
GRID = 1e-5  # [m] measured lengths are rounded outwards to this
_Q_RIGHT = float(np.sqrt(0.5))


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


@functools.lru_cache(maxsize=1)
def _measure() -> dict:
    """Measurements [m, N, kg] of the vendored model in its hand frame, fingers closed."""
    from graspsim._gl import import_mujoco

    mujoco = import_mujoco()
    from scipy.spatial import ConvexHull

    model = mujoco.MjModel.from_xml_path(str(model_folder(NAME) / f"{NAME}.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # qpos0: fingers closed (joints at 0)
    hand = hull_points(model, data, "hand_collision")
    finger = hull_points(model, data, "left_finger_collision")  # the +y_H finger
    inner = finger[:, 1].min()
    pad_top = finger[finger[:, 1] <= inner + PAD_TOL, 2].min()
    tip = finger[:, 2].max()
    palm = hand[:, 2].max()  # the hull's face towards the fingers
    pad_part = clip_z(finger, pad_top, np.inf)
    jaw_part = clip_z(finger, palm, pad_top)
    jnt = model.joint("finger_joint1")
    act = model.actuator("grip")
    return {
        "z0": _grid(hand[:, 2].min(), np.floor), "palm": _grid(palm), "pad_top": _grid(pad_top),
        "tip": _grid(tip),
        "hand_half": (_grid(np.abs(hand[:, 1]).max()), _grid(np.abs(hand[:, 0]).max())),
        "pad_box": (_grid(pad_part[:, 1].max()), _grid(2 * np.abs(pad_part[:, 0]).max())),
        "jaw_box": (_grid(jaw_part[:, 1].max()), _grid(2 * np.abs(jaw_part[:, 0]).max())),
        "range": tuple(float(x) for x in jnt.range),
        "force": float(act.gainprm[0]), "damping": float(model.dof_damping[jnt.dofadr[0]]),
        "hand_mass": float(model.body("hand").mass[0]),
        "finger_mass": float(model.body("left_finger").mass[0]),
        "pad_share": float(ConvexHull(pad_part).volume / ConvexHull(finger).volume),
    }


@functools.lru_cache(maxsize=1)
def franka_hand_spec() -> GripperSpec:
    """The Franka hand's spec, measured from the vendored model (see the module doc).

    Stroke and closed gap: the finger joints' range (0-0.04 m each: the pad gap is twice
    the joint value). Grip force: the model's actuator gain (the maker's continuous
    70 N); closing speed: force / joint damping. The planning margins (contact depth
    margin, approach clearance) and the arm keep-out are graspsim's defaults."""
    m = _measure()
    lo, hi = m["range"]
    fx, fy = m["pad_box"]
    jx, jy = m["jaw_box"]
    hx, hy = m["hand_half"]
    r = lambda v: round(v, 8)  # noqa: E731  (differences of grid values, exactly on the grid)
    share = round(m["pad_share"], 4)
    return GripperSpec(
        name=NAME, model=NAME,
        housing_size=(2 * hx, 2 * hy, r(m["palm"] - m["z0"])),
        jaw_size=(jx, jy, r(m["pad_top"] - m["palm"])),
        finger_size=(fx, fy, r(m["tip"] - m["pad_top"])),
        pad_length=r(m["tip"] - m["pad_top"]),
        stroke_per_jaw=r(hi - lo), closed_gap=r(2 * lo),
        rated_force=m["force"], closing_speed=m["force"] / m["damping"],
        housing_mass=m["hand_mass"], jaw_mass=r((1 - share) * m["finger_mass"]),
        finger_mass=r(share * m["finger_mass"]),
    )


@functools.lru_cache(maxsize=1)
def franka_hand_mount() -> Mount:
    """The hand frame in the wrist frame: origin at (0, 0, -z0), turned Rz(-90 deg)."""
    return Mount(name=NAME, root_body="hand", jaw_joints=("finger_joint2", "finger_joint1"),
                 pad_geoms=("right_finger_collision", "left_finger_collision"), actuator="grip",
                 pos=(0.0, 0.0, -_measure()["z0"]), quat=(_Q_RIGHT, 0.0, 0.0, -_Q_RIGHT))
