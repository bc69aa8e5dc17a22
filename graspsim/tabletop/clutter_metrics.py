"""Clutter removal's metrics: what an episode's results add up to (:func:`summarize`: GSR,
DR, stops, causes, planning time, segmentation quality), the failure table per object
(:func:`per_object`, :func:`failure_rows`) and how an object's points were segmented
(:func:`one_cluster_objects`, :func:`object_segmentation`). Read by
:mod:`graspsim.tabletop.clutter` (whose :class:`~graspsim.tabletop.clutter.ClutterResult` they
take), ``graspsim scene`` and E10.
"""

from __future__ import annotations

import numpy as np

__all__ = ["STOPS", "ARM_STOPS", "OTHER", "LEFT", "FAILURE_COLUMNS", "summarize", "per_object", "per_source",
           "failure_rows",
           "one_cluster_objects", "object_segmentation"]

#: Why an episode ended.
STOPS = ("cleared", "failures", "no_grasp", "max_attempts")
#: Why an episode of an arm (``ClutterConfig.robot``) may end besides: grasps were left to
#: try, and the arm reached none of them.
ARM_STOPS = ("unreachable",)
#: The cause of a grasp that lifted an object other than its target.
OTHER = "success_other_object"
#: Why an object was left on the table, judged on the episode's last look
#: (:meth:`graspsim.tabletop.clutter.ClutterEpisode.left_reasons`).
LEFT = ("not_seen", "merged", "split", "no_grasp", "excluded", "not_tried", "off_table", "unreachable")


def object_segmentation(truth: np.ndarray, found: np.ndarray, k: int, *, min_seen: int = 40,
                        share: float = 0.9) -> tuple[str, int | None]:
    """How object ``k`` is segmented: ("not_seen" | "one" | "merged" | "split", its
    segment when "one") by :func:`one_cluster_objects`' rule; merged: the segment holding
    most of its points is less than ``share`` its own (it shares it with another object);
    split: spread over segments, or not segmented."""
    mine = truth == k
    if mine.sum() < min_seen:
        return "not_seen", None
    segs = found[mine & (found >= 0)]
    if not len(segs):
        return "split", None
    ids, counts = np.unique(segs, return_counts=True)
    best = int(ids[np.argmax(counts)])
    pure = np.mean(truth[found == best] == k) >= share
    if not pure:
        return "merged", None
    return ("one", best) if counts.max() >= share * len(segs) else ("split", None)


def one_cluster_objects(truth: np.ndarray, found: np.ndarray, *, min_seen: int = 40,
                        share: float = 0.9) -> tuple[int, int]:
    """(objects seen, objects segmented as one cluster) from per-point ground-truth
    object ids ``truth`` (N,) (< 0: none) and found segment ids ``found`` (N,) (< 0:
    none) of the same points. An object is seen with ``min_seen`` points or more; it is
    one cluster when one segment holds at least ``share`` of its segmented points and at
    least ``share`` of that segment's points are the object's."""
    truth, found = np.asarray(truth), np.asarray(found)
    seen = one = 0
    for k in np.unique(truth[truth >= 0]):
        mine = truth == k
        if mine.sum() < min_seen:
            continue
        seen += 1
        segs = found[mine & (found >= 0)]
        if not len(segs):
            continue
        ids, counts = np.unique(segs, return_counts=True)
        best = ids[np.argmax(counts)]
        if counts.max() >= share * len(segs) and np.mean(truth[found == best] == k) >= share:
            one += 1
    return seen, one


def _spread(values: list[float]) -> dict:
    """count, mean, median and max of seconds (None when there are none)."""
    v = np.asarray(values, float)
    if not len(v):
        return {"count": 0, "mean": None, "median": None, "max": None}
    return {"count": len(v), "mean": float(v.mean()), "median": float(np.median(v)), "max": float(v.max())}


def _count_grasp(row: dict, a) -> None:
    """Attempt ``a`` counted into a failure-table ``row``: a grasp, lifted or failed by its cause."""
    row["grasps"] += 1
    row["lifted"] += a.success
    if not a.success:
        row["failed"][a.cause] = row["failed"].get(a.cause, 0) + 1


def per_object(results: list) -> dict:
    """The failure table per object name, over episodes: placed, removed, grasps aimed
    at it (the target: the object most of the chosen segment's points show), those that
    lifted it, the failed ones by cause (start collisions by what they hit, slips,
    drops, another object lifted, ...), and the copies left on the table by why
    (:data:`LEFT`). Sorted by objects left, then failed grasps, most first."""
    rows: dict[str, dict] = {}
    for r in results:
        names = r.names or tuple(str(k) for k in range(r.placed))
        for k, name in enumerate(names):
            row = rows.setdefault(name, {"placed": 0, "removed": 0, "grasps": 0, "lifted": 0, "failed": {},
                                         "left": {}})
            row["placed"] += 1
            row["removed"] += k not in r.left
        for k, why in r.left.items():
            d = rows[names[k]]["left"]
            d[why] = d.get(why, 0) + 1
        for a in r.attempts:
            if a.target is None:
                continue
            _count_grasp(rows[names[a.target]], a)
    for row in rows.values():
        row["failed"] = dict(sorted(row["failed"].items()))
        row["left"] = dict(sorted(row["left"].items()))
    return dict(sorted(rows.items(), key=lambda kv: (-(kv[1]["placed"] - kv[1]["removed"]),
                                                     -(kv[1]["grasps"] - kv[1]["lifted"]), kv[0])))


def per_source(results: list) -> dict:
    """The grasps by what they were planned from (``Attempt.source``: an identified part's
    primitive, or ``"features"``, the segment's own points): grasps, those that lifted
    their target, the failed ones by cause. Grasps of unknown source (an external
    planner's) are left out. Sorted by grasps, most first."""
    rows: dict[str, dict] = {}
    for a in (a for r in results for a in r.attempts if a.source is not None):
        _count_grasp(rows.setdefault(a.source, {"grasps": 0, "lifted": 0, "failed": {}}), a)
    for row in rows.values():
        row["failed"] = dict(sorted(row["failed"].items()))
    return dict(sorted(rows.items(), key=lambda kv: (-kv[1]["grasps"], kv[0])))


#: The columns of :func:`failure_rows`.
FAILURE_COLUMNS = ("object", "placed", "removed", "grasps", "lifted", "failed grasps", "left on the table")


def failure_rows(table: dict) -> list[tuple]:
    """Rows of :data:`FAILURE_COLUMNS` from a :func:`per_object` table (what the CLI and
    E10 print)."""
    def causes(d: dict) -> str:
        return ", ".join(f"{k} {v}" for k, v in d.items()) or "-"

    return [(name, r["placed"], r["removed"], r["grasps"], r["lifted"], causes(r["failed"]), causes(r["left"]))
            for name, r in table.items()]


def summarize(results: list) -> dict:
    """Pooled metrics of episodes: grasp success rate (successes / attempts), cleared
    rate (objects removed / placed), grasps that lifted another object than their
    target (``other_objects``, not successes), scenes cleared, stops, failure causes,
    planning seconds per grasp (count, mean, median, max; of the episodes' first frames
    and of later frames, which may reuse plans, apart; median per stage of
    ``plan_scene``), segmentation quality of the first frames
    (objects seen, segmented as one cluster), the failure table per object
    (:func:`per_object`) and the grasps by what they were planned from (:func:`per_source`)."""
    attempts = [a for r in results for a in r.attempts]
    ok = sum(a.success for a in attempts)
    placed, removed = sum(r.placed for r in results), sum(r.removed for r in results)
    causes: dict[str, int] = {}
    for a in attempts:
        if not a.success:
            causes[a.cause] = causes.get(a.cause, 0) + 1
    seen, one = sum(r.first_seen for r in results), sum(r.first_one_cluster for r in results)
    stages = sorted({k for a in attempts for k in a.timing})
    medians = {k: float(np.median([a.timing.get(k, 0.0) for a in attempts])) for k in stages}
    first = [r.attempts[0].planning for r in results if r.attempts]
    later = [a.planning for r in results for a in r.attempts[1:]]
    stops = STOPS + (ARM_STOPS if any(getattr(r, "robot", None) for r in results) else ())
    return {"scenes": len(results), "attempts": len(attempts), "successes": ok,
            "other_objects": sum(a.cause == OTHER for a in attempts),
            "grasp_success_rate": ok / len(attempts) if attempts else None,
            "placed": placed, "removed": removed, "cleared_rate": removed / placed if placed else None,
            "scenes_cleared": sum(r.removed == r.placed for r in results),
            "stops": {s: sum(r.stop == s for r in results) for s in stops},
            "failure_causes": dict(sorted(causes.items())),
            "planning_s": {**_spread([a.planning for a in attempts]), "stages_median": medians,
                           "first_frame": _spread(first), "later_frames": _spread(later)},
            "segmentation": {"objects_seen": seen, "one_cluster": one,
                             "share": one / seen if seen else None},
            "per_object": per_object(results), "per_source": per_source(results)}
