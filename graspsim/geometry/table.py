"""The table an object stands on: :class:`TablePlane` (the support plane in the cloud's
frame and the clearance the gripper keeps above it) and :func:`table_frame`. Which map
poses clear it is :mod:`graspsim.maps.table_clearance`; fitting it to a scene cloud is
:func:`graspsim.perception.plane.fit_table`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.transforms import frame_from_axes, make_transform

__all__ = ["TablePlane", "table_frame"]


@dataclass(frozen=True)
class TablePlane:
    """The plane an object stands on, in the cloud's frame.

    normal: the plane's upward normal (away from the table; normalised here).
    height: signed offset of the plane along the normal [m] (points p on it have
        normal . p = height); None: the object rests on it, so the planner puts it at
        the object's lowest point along the normal (``maps.table_clearance.table_height``: the
        cloud's for a cloud seen all round; for a single view, whose camera rarely sees
        the base, the identified shape's where that is lower).
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
