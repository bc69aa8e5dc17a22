"""The table under the object: which map poses keep the gripper clear of it.

Graspability maps, the paper's and ours, know only the object: a pose that approaches
from below, or skims the object's base, is in the map although the table it stands on
makes it unreachable (in simulation it is START_COLLISION). :class:`TablePlane` describes
the support plane in the cloud's frame; :func:`clears_table` tests a map's poses with the
gripper's collision boxes (arm keep-out included), as :meth:`GripperSpec.lowest_point`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.gripper import GripperSpec
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.transforms import frame_from_axes, make_transform, quat_to_matrix

__all__ = ["TablePlane", "clears_table", "table_frame"]


@dataclass(frozen=True)
class TablePlane:
    """The plane an object stands on, in the cloud's frame.

    normal: the plane's upward normal (away from the table; normalised here).
    height: signed offset of the plane along the normal [m] (points p on it have
        normal . p = height); None: the object rests on it, so the planner puts it at
        the object's lowest point along the normal (the identified shape's, or the
        cloud's where that is lower: unidentified parts, noise).
    clearance: the gripper must stay this far above the plane [m].
    """

    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    height: float | None = None
    clearance: float = 0.002

    def __post_init__(self) -> None:
        try:
            n = np.asarray(self.normal, float).ravel()
        except (TypeError, ValueError):
            n = np.full(1, np.nan)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or not np.max(np.abs(n)) > 1e-9:
            raise InvalidParameterError(
                f"table normal must be three finite numbers, not all zero; got {self.normal!r}")
        n = n / np.max(np.abs(n))  # (1e300, 0, 0): no overflow in the norm
        object.__setattr__(self, "normal", tuple(float(v) for v in n / np.linalg.norm(n)))
        if self.height is not None:
            h = _number(self.height)
            if not math.isfinite(h):
                raise InvalidParameterError(f"table height must be finite [m] or None (auto), got {self.height!r}")
            object.__setattr__(self, "height", h)
        c = _number(self.clearance)
        if not (math.isfinite(c) and c >= 0):
            raise InvalidParameterError(f"table clearance must be >= 0 m, got {self.clearance!r}")
        object.__setattr__(self, "clearance", c)

    def to_dict(self) -> dict:
        return {"normal": list(self.normal), "height": self.height, "clearance": self.clearance}


def _number(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def table_frame(normal, height: float) -> np.ndarray:
    """T_table_cloud (4, 4): a frame whose z axis is ``normal`` and whose origin lies on
    the plane normal . p = height, so a point's z in it is its height above the table."""
    z = np.asarray(normal, float)
    R = frame_from_axes(np.eye(3)[int(np.argmin(np.abs(z)))], z)  # any x across the normal
    return make_transform(R.T, -height * np.eye(3)[2])


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
        T = T_table_obj @ make_transform(quat_to_matrix(gmap.wrist_quat[sl]), gmap.wrist_position[sl])
        out[sl] = gripper.lowest_point(T, gripper.pregrasp_opening(gmap.width[sl])) >= clearance
    return out
