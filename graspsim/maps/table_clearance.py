"""The table under the object: which map poses keep the gripper clear of it.

Graspability maps, the paper's and ours, know only the object: a pose that approaches
from below, or skims the object's base, is in the map although the table it stands on
makes it unreachable (in simulation it is START_COLLISION). :class:`TablePlane` describes
the support plane in the cloud's frame; :func:`clears_table` tests a map's poses with the
gripper's collision boxes (arm keep-out included), as :meth:`GripperSpec.lowest_point`.

A pose whose gripper would go below the table can often be lifted clear of it: moved
back along its own approach until its lowest point is at the clearance, the same two
contacts held nearer the fingertip (:func:`lift_clear`). For an object lower than the
pad's planned region -- a domino, a lid, a flat tool lying down -- these low-profile
grasps are the only ones a two-jaw gripper has: the stored maps plan no contact closer
than the gripper's tip margin (``GripperSpec.depth_lo``, 5 mm by default) to the
fingertip, so every pose of a 6 mm object puts the fingertips under the table.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from graspsim.checks import NON_NEGATIVE, check_fields
from graspsim.errors import InvalidParameterError
from graspsim.geometry.table import TablePlane
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.transforms import quat_to_matrix

__all__ = ["clears_table", "heights_above", "lift_clear", "low_part", "LowProfile", "stream_order", "table_height"]


@dataclass(frozen=True)
class LowProfile:
    """Low-profile grasps (:func:`lift_clear`) of a part lower than the pad's planned
    region (:func:`low_part`): its poses may come to ``clearance`` [m] of the table (the
    table's own clearance where that is smaller), a pose lower than that lifted along its
    approach until it is there, offered where its contacts then lie at least
    ``min_depth`` [m] from the fingertip and both pads' tip edges at most ``max_tip`` [m]
    above the table.

    The defaults: contacts at least 1 mm up the pad from its tip edge; the fingertips
    0.5 mm above the table, as a two-jaw gripper picks a domino, the pad overlapping a 6 mm
    object over 5.5 mm. In MuJoCo a 3-5 g box 6 mm thick squeezed by the default
    gripper's 250 N slips out of the pads when they overlap it by 5 mm or less (the
    fingertips 1 mm up: most of ``tests/test_low_profile.py``'s box's best grasps failed;
    0.5 mm up: none). The robust score's table term still judges every pose under the execution
    error, so these grasps rank by how often the fingertips would meet the table.

    ``max_tip`` [m]: the pads' tip edges (the middle of each, at the pre-grasp opening)
    at most this high above the table. An approach tilted across the finger's width
    keeps its lowest corner at ``clearance`` but lifts the pad's edge: 20 deg over the
    default finger's 20 mm width lifts it by 3.4 mm, and a pad 4 mm over the table
    overlaps a domino by 2 mm: in household-tuning piles such domino grasps, tilted 12-25
    deg with their pad edges 3-5.5 mm up, mostly closed on nothing or dropped it.
    The default 2 mm allows tilts up to about 8 deg for the default finger."""

    min_depth: float = 0.001
    clearance: float = 0.0005
    max_tip: float = 0.002

    def __post_init__(self) -> None:
        check_fields(self, NON_NEGATIVE.saying(">= 0 m"), "min_depth", "clearance", "max_tip", owner="LowProfile")

    def to_dict(self) -> dict:
        return asdict(self)


def clears_table(gmap: GraspabilityMap, T_table_obj: np.ndarray, gripper: GripperSpec,
                 clearance: float = 0.0, chunk: int = 100_000) -> np.ndarray:
    """(N,) bool: the gripper at each of the map's poses, jaws at its pre-grasp opening,
    stays ``clearance`` [m] or more above the table, whose frame (z up, origin on the
    plane) is at ``T_table_obj`` (4, 4) in the map's object frame. Works in chunks (a
    million poses at once would take gigabytes)."""
    T_table_obj = np.asarray(T_table_obj, float)
    if T_table_obj.shape != (4, 4) or not np.all(np.isfinite(T_table_obj)):
        raise InvalidParameterError(f"T_table_obj must be a finite 4x4 transform, got shape {T_table_obj.shape}")
    out = np.zeros(len(gmap), bool)
    for a in range(0, len(gmap), chunk):
        sl = slice(a, a + chunk)
        out[sl] = heights_above(gripper, T_table_obj, gmap.wrist_quat[sl], gmap.wrist_position[sl],
                                gmap.width[sl]) >= clearance
    return out


def heights_above(gripper: GripperSpec, T_table_obj: np.ndarray, wrist_quat: np.ndarray,
                  wrist_position: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(N,) lowest height [m] of the gripper above the table (frame ``T_table_obj`` in
    the object frame) at wrist poses given by quaternions (N, 4) (w, x, y, z) and
    positions (N, 3) in the object frame, jaws at the pre-grasp opening of contact
    widths (N,) [m]."""
    n, h = T_table_obj[2, :3], T_table_obj[2, 3]  # the table's z axis and offset in the object frame
    up = _in_wrist_frames(wrist_quat, n)
    height = np.asarray(wrist_position, float) @ n + h
    return gripper.lowest_along(up, height, gripper.pregrasp_opening(width))


def low_part(shape, T_table_part: np.ndarray, gripper: GripperSpec, clearance: float, surface_step: float) -> bool:
    """Whether a part -- ``shape`` with the table's frame at ``T_table_part`` (4, 4) in its
    own -- is lower than the pad's planned region: its top less than ``clearance`` +
    ``gripper.depth_lo`` + ``surface_step`` [m] above the table (12 mm for the default
    gripper, clearance and maps). The shallowest planned contact sits ``depth_lo`` above
    fingertips ``clearance`` above the table, and the maps' contacts lie up to a surface
    step apart: below that height a part has no contact the planned pad region reaches
    from above, or only a row or two. Only such parts get low-profile grasps
    (:func:`lift_clear`); a taller object keeps the map's own poses alone."""
    T = np.asarray(T_table_part, float)
    v = np.asarray(shape.mesh().vertices, float)
    top = float(np.max(v @ T[2, :3] + T[2, 3]))
    return top < clearance + gripper.depth_lo + surface_step


def lift_clear(gmap: GraspabilityMap, T_table_obj: np.ndarray, gripper: GripperSpec, clearance: float,
               low: LowProfile = LowProfile()) -> tuple[np.ndarray, np.ndarray]:
    """Low-profile grasps: the map's poses that do not clear the table by ``clearance``
    [m], lifted clear (:class:`LowProfile` ``low``).

    A low part's pose may come nearer the table than the other grasps: its gripper's lowest
    point ``min(low.clearance, clearance)`` above the table (``target``; frame
    ``T_table_obj`` in the map's object frame). A pose lower than that is moved back along
    its own approach (the wrist by -s x approach) until its lowest point is there, its grasp
    point and contacts unchanged, so the contacts sit s nearer the fingertip: contact depth
    d - s; a pose between ``target`` and ``clearance`` is moved down its approach to
    ``target`` where its contacts then stay within the pad's planned region (d - s <=
    ``gripper.depth_hi``, s < 0), else it stays as it is (s = 0): a pad with one planned
    depth (shorter than the maps' depth step, as the Franka hand's) has no deeper pose to
    lift to the target, and a plate seen a few mm above where it lies (a domino's top
    face) would keep its fingertips 1-2 mm up, where most such grasps slip. A pose is
    offered where its contacts stay at least ``low.min_depth`` from the fingertip (else they
    would leave the pad) and both pads' tip edges at most ``low.max_tip`` above the table.
    Lifting cannot add a collision with the object the pose was checked against: the
    gripper's boxes nest (finger in jaw in housing in the arm keep-out, widening towards
    the wrist), so the moved gripper lies in the unmoved one but for a slab s thick behind
    the arm keep-out's far end, ``arm_length + fingertip_z - d`` behind the contacts (at
    least 210 mm for the default gripper); moving down can (the fingers go deeper over a
    part that may widen towards the table): the robust score's primitives term judges it.
    The planner's checks against the observed points and its robust score see the whole
    moved gripper. Poses of one closing
    line and roll at several depths come to one pose (or to poses between ``target`` and
    ``clearance``): the lowest of them stands for them, a lifted one before one moved down.

    Returns (rows (K,) of ``gmap``, wrist positions (K, 3) of the lifted poses, object
    frame); the grasps are ``gmap.select(rows)`` with those positions."""
    T_table_obj = np.asarray(T_table_obj, float)
    none = (np.zeros(0, np.int64), np.zeros((0, 3)))
    if not len(gmap):
        return none
    target = min(float(low.clearance), float(clearance))
    pos = np.asarray(gmap.wrist_position, float)
    h = heights_above(gripper, T_table_obj, gmap.wrist_quat, pos, gmap.width)
    below = np.flatnonzero(h < clearance)
    if not len(below):
        return none
    n = T_table_obj[2, :3]  # the table's normal in the object frame
    a = gmap.approach[below].astype(float)
    rise = -(a @ n)  # height gained per metre moved back along the approach
    gp = np.asarray(gmap.grasp_point[below], float)
    depth = gripper.contact_depth(gp, pos[below], a)
    hb = h[below]
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(rise > 1e-6, (target - hb + 1e-7) / rise, np.inf)  # moved to the target
    # a pose between the target and the clearance moves down to the target, its contacts deeper
    # on the pad while they stay in its planned region (depth_hi): for a pad whose depth grid
    # has no deeper contact to lift from (the Franka hand's 18 mm pad has one depth at the maps'
    # 1 cm step) the only pose with its fingertips at the target; one that cannot stays
    down = (hb >= target) & np.isfinite(up) & (depth - up <= gripper.depth_hi + 1e-9)
    s = np.where(down, up, np.where(hb >= target, 0.0, up))
    ok = np.isfinite(s) & (depth - s >= low.min_depth)
    rows, s, low_h, down = below[ok], s[ok], hb[ok] + s[ok] * rise[ok], down[ok]
    if not len(rows):
        return none
    # one pose per closing line and roll: the lowest (lowest point nearest the target), one
    # lifted before one moved down to the same height (1 nm, past the float noise)
    by = np.argsort(low_h + 1e-9 * down, kind="stable")
    rows, s = rows[by], s[by]
    key = np.column_stack([gmap.contacts[rows].reshape(len(rows), 6), gmap.wrist_quat[rows]]).astype(np.float32)
    _, first = np.unique(key.view(np.dtype((np.void, key.dtype.itemsize * key.shape[1]))).ravel(),
                         return_index=True)
    order = np.argsort(rows[first], kind="stable")  # back in the map's order
    rows, s = rows[first][order], s[first][order]
    new = pos[rows] - s[:, None] * gmap.approach[rows].astype(float)
    # float32 storage must not take a pose back under the clearance
    keep = heights_above(gripper, T_table_obj, gmap.wrist_quat[rows], new.astype(np.float32),
                         gmap.width[rows]) >= target
    # the pads reach down to the table: both tip edges' middles at most max_tip above it
    R = gmap.approach[rows].astype(float), _closing_axis(gmap.wrist_quat[rows])
    half = 0.5 * gripper.pregrasp_opening(gmap.width[rows])
    tip = new @ n + T_table_obj[2, 3] + gripper.fingertip_z * (R[0] @ n)
    keep &= tip + half * np.abs(R[1] @ n) <= low.max_tip
    return rows[keep], new[keep]


def _closing_axis(q_wxyz: np.ndarray) -> np.ndarray:
    """(N, 3) the wrist x axes (closing axes) of quaternions (N, 4) (w, x, y, z)."""
    return quat_to_matrix(np.asarray(q_wxyz, float))[:, :, 0]


def _in_wrist_frames(q_wxyz: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3) R(q)^T v: the object-frame vector ``v`` (3,) in each wrist frame of
    quaternions (N, 4) (w, x, y, z; normalised here), without building the matrices."""
    q = np.asarray(q_wxyz, float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    x, y, z = -x, -y, -z  # the inverse rotation: v' = v + 2 w (u x v) + 2 u x (u x v)
    tx, ty, tz = 2.0 * (y * v[2] - z * v[1]), 2.0 * (z * v[0] - x * v[2]), 2.0 * (x * v[1] - y * v[0])
    return np.column_stack([v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz),
                            v[2] + w * tz + (x * ty - y * tx)])


def stream_order(n: int, first: int, growth: float, prefer=None, chunk: int = 4096):
    """Yield the positions 0..n-1 in batches of growing size (``first``, then x
    ``growth``), each ascending. ``prefer``: a function of positions (m,) returning
    (m,) bool, evaluated lazily in chunks that double from 256 up to ``chunk`` (a
    planner that stops after its first batches asks about few positions): the
    positions it prefers stream first, in order, the others after them (e.g. poses
    likely to clear a table, so a streaming planner's first batches are not emptied by
    it). Every position is yielded exactly once; the batches do not depend on the
    chunks."""
    size, grow = max(1, int(first)), max(float(growth), 1.0)
    if prefer is None:
        start = 0
        while start < n:
            yield np.arange(start, min(n, start + size))
            start, size = start + size, int(size * grow)
        return
    queue, later = np.zeros(0, np.int64), []
    for a, b in _chunks(n, chunk):
        pos = np.arange(a, b)
        ok = np.asarray(prefer(pos), bool)
        queue = np.concatenate([queue, pos[ok]])
        later.append(pos[~ok])
        while len(queue) >= size:
            yield queue[:size]
            queue, size = queue[size:], int(size * grow)
    if len(queue):
        yield queue
        size = int(size * grow)
    rest = np.concatenate(later) if later else np.zeros(0, np.int64)
    start = 0
    while start < len(rest):
        yield rest[start:start + size]
        start, size = start + size, int(size * grow)


def _chunks(n: int, chunk: int, least: int = 256) -> list[tuple[int, int]]:
    """Position ranges covering 0..n-1: within the first ``chunk``, ranges doubling from
    ``least`` (256, 512, 1024, ...; none shorter than ``least``, the last one included),
    then whole ``chunk`` s from the multiples of ``chunk`` as before (a preference is
    asked about a chunk of rows at once, and numpy's matrix products over a chunk give
    each row the same value wherever a range of at least ``least`` rows starts)."""
    cuts, c = [], least
    while c < chunk and chunk - c >= least and n - c >= least:
        cuts.append(c)
        c = 2 * c + least
    cuts += range(chunk, n, chunk)
    edges = [0, *cuts, n] if n else [0]
    return list(zip(edges[:-1], edges[1:]))


def table_height(table: TablePlane, points: np.ndarray, shape, T_cloud_obj: np.ndarray) -> float:
    """The table's offset along its normal: given, or the object's lowest observed point,
    the cloud's 0.5 % quantile along the normal (the identified shape's lowest point only
    for a cloud without points).

    The same rule for a cloud seen all round and for a single view. Seen all round, the
    points reach the table. A single view's lowest visible point lies above the real
    table (by 2-14 mm, median 3 mm, for the 42 development meshes seen from 40 deg
    elevation, E09), so a table there is too high if anything: grasps near the base are
    dropped, none let into the table. A fitted shape's lowest point is no substitute: a
    box fitted over a multi-part object, or a shape extrapolated behind a single view,
    reaches 1-2 cm under the real table (E09's single views: 10-17 mm for five of the
    random meshes) and lets grasps through into it."""
    if table.height is not None:
        return table.height
    n = np.asarray(table.normal)
    pts = np.asarray(points, float)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts):
        return float(np.quantile(pts @ n, 0.005))
    v = np.asarray(shape.mesh().vertices, float)
    return float(np.min((v @ T_cloud_obj[:3, :3].T + T_cloud_obj[:3, 3]) @ n))
