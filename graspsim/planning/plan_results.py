"""What the run-time planner (:mod:`graspsim.planning.planner`) returns: a plan's status, each
part's record, the batches it streams and the finished result (importable from
:mod:`graspsim.planning.planner` as well)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.match import MatchKind
from graspsim.perception import Identification
from graspsim.primitives import Primitive

__all__ = ["PlanStatus", "PartPlan", "GraspBatch", "PlanResult"]


class PlanStatus(str, Enum):
    COMPLETE = "complete"  # every cluster identified
    PARTIAL = "partial"  # clustering failed; map of the identified clusters only
    FAILED = "failed"  # nothing identified



@dataclass(frozen=True)
class PartPlan:
    """primitive: as identified (box edges ascending); match: the database's decision
    (:class:`~graspsim.maps.match.MatchKind`: KNOWN, FAMILIAR, or BUILD: an FS map was
    built for the part -- or, with ``build_missing`` off, none: ``source`` is empty);
    source: the FS map's object; T_cloud_part (4, 4); T_obj_part (4, 4) in the map's
    object frame; stored: which stored map served the part -- ``{"key": its database
    key, "ratio": the largest per-dimension size ratio between it and the part (1: the
    same size), "max_diff": the largest per-dimension difference [m]}`` (for a BUILD the
    map built, ratio 1), None when no map served it."""

    primitive: Primitive
    match: MatchKind
    source: dict
    T_cloud_part: np.ndarray
    T_obj_part: np.ndarray
    stored: dict | None = None

    def to_dict(self) -> dict:
        return {"primitive": self.primitive.kind, "dims": self.primitive.dims, "match": self.match.value,
                "source": self.source, "stored": self.stored, "T_cloud_part": self.T_cloud_part.tolist()}


@dataclass(frozen=True)
class GraspBatch:
    """Grasps found so far: ``map`` (object frame), best first in the plan's ranking
    (:func:`~graspsim.maps.robust.ranking`: a scored batch by its robust scores, an unscored
    one by grade), seconds since the cloud arrived. When the
    planner identifies the cloud again (``PlannerConfig.restarts``: the map so far held no
    accepted grasp), the batches start again: the final map holds only the last attempt's."""

    map: GraspabilityMap
    seconds: float


@dataclass(frozen=True, eq=False)
class PlanResult:
    """status; map: adapted map (object frame; ``extra["T_cloud_obj"]``); parts;
    identification (None for :func:`plan_shape`); T_cloud_obj (4, 4); timing [s] per
    stage (``identify``; ``maps``: all that follows, of which ``adapt``: retrieval and
    scaling, ``agreement``: the cloud-agreement filter, ``combine``, ``table``: the table
    filter, ``robust``: scoring) plus ``first`` and ``tenth`` (time to the first and tenth grasp with grade
    > 0.95, None if never), ``first_robust`` (time to the first grasp with a robust
    score > 0; None if never or ``rank="paper"``), ``first_robust_cpu`` (the calling
    thread's CPU seconds from the end of identification to that grasp: a measure that
    other processes' load barely changes) and ``robust`` (seconds spent scoring). attempts:
    the identifications made (``PlannerConfig.restarts``: more than one when the first maps
    held no accepted grasp); the result is the last one's, and its timing counts them all."""

    status: PlanStatus
    map: GraspabilityMap
    parts: tuple[PartPlan, ...]
    identification: Identification | None
    T_cloud_obj: np.ndarray
    timing: dict
    attempts: int = 1

    def summary(self) -> dict:
        return {"status": self.status.value, "parts": [p.to_dict() for p in self.parts],
                "grasps": len(self.map), "accepted": int(self.map.accepted.sum()),
                "seconds": self.timing.get("total"), "time_to_first_0.95": self.timing.get("first"),
                "time_to_tenth_0.95": self.timing.get("tenth"),
                "time_to_first_robust": self.timing.get("first_robust"),
                "T_cloud_obj": self.T_cloud_obj.tolist(),
                "identification": None if self.identification is None else {
                    "mode": self.identification.mode, "uncovered": self.identification.uncovered,
                    "approximate": [p.approximate for p in self.identification.parts], "attempts": self.attempts},
                "fit": (self.map.meta.extra.get("identification") or {}).get("fit"),
                "table": None if self.map.meta.placement is None else self.map.meta.placement.table}
