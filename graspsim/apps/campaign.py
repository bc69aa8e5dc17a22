"""Map-file simulation campaigns: simulate grasps of many map files, resumably, on any
executor (``graspsim campaign``). Calibration trials -- grasps drawn from maps in
memory and run under several physics conditions for the grade-vs-success statistics --
are :mod:`graspsim.calibration.trials`.

A campaign is a list of :class:`CampaignTask` s -- one map file, a grasp selection, a
protocol, execution noise and a seed each -- run by ``graspsim.executors`` (local
processes by default, Ray with ``--executor ray``). Every finished task is written at
once, atomically, to ``OUT/tasks/<task_id>.npz``; a rerun skips the tasks already
there, so an interrupted campaign continues where it stopped and ends with exactly the
trials of an uninterrupted one. ``OUT/spec.json`` pins the task list: resuming with a
different one is refused.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graspsim._atomic import atomic_path, atomic_write_text
from graspsim.errors import CampaignError, InvalidParameterError
from graspsim.executors import Executor, SerialExecutor
from graspsim.stats import wilson_interval

if TYPE_CHECKING:  # graspsim.sim loads mujoco
    from graspsim.sim.noise import ExecutionNoise

__all__ = ["CampaignTask", "CampaignResult", "campaign_tasks", "run_campaign", "run_task",
           "load_campaign"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CampaignTask:
    """One unit of work: simulate ``top`` best / ``sample`` uniform grasps (grade >
    ``min_grade``) of ``map_path`` with ``protocol``; ``noise``: an
    :class:`~graspsim.sim.ExecutionNoise` or None (exact execution); ``mesh`` simulates against a given mesh instead of
    the
    map's primitives; ``threads`` inside the task (1 when tasks run in parallel)."""

    task_id: str
    map_path: str
    protocol: str = "lift_place"
    top: int | None = None
    sample: int | None = None
    min_grade: float | None = None
    noise: ExecutionNoise | None = None
    seed: int = 0
    mesh: str | None = None
    threads: int = 1

    def to_dict(self) -> dict:
        d = asdict(self)
        n = self.noise  # recorded as [sigma_pos, sigma_rot] in spec.json
        d["noise"] = [n.position_sigma, n.rotation_sigma] if n else None
        return d


def campaign_tasks(maps: Sequence[str | os.PathLike], *, protocol: str = "lift_place",
                   top: int | None = None, sample: int | None = None, min_grade: float | None = None,
                   noise: ExecutionNoise | None = None, seeds: Sequence[int] = (0,),
                   mesh: str | None = None, threads: int = 1) -> list[CampaignTask]:
    """The task list of a campaign: every map x seed, with ids stable across runs."""
    if not maps:
        raise InvalidParameterError("a campaign needs at least one map file")
    _check_settings(top=top, sample=sample, threads=threads, min_grade=min_grade)
    tasks = []
    for m in maps:
        p = Path(m)
        for s in seeds:
            tid = f"{p.stem}-{protocol}-{'noise' if noise else 'exact'}-s{int(s)}"
            tasks.append(CampaignTask(tid, str(p.resolve()), protocol, top, sample, min_grade,
                                      noise, int(s), mesh, threads))
    ids = [t.task_id for t in tasks]
    if len(set(ids)) != len(ids):
        raise InvalidParameterError("map files in a campaign must have distinct names")
    return tasks


def run_task(task: CampaignTask) -> dict:
    """Run one task in this process; returns its arrays and a JSON-able record."""
    from graspsim.maps import load_map
    from graspsim.sim import make_protocol, simulate_map

    t0 = time.perf_counter()
    trials = simulate_map(task.map_path, protocol=make_protocol(task.protocol), top=task.top,
                          sample=task.sample, min_grade=task.min_grade, threads=task.threads,
                          seed=task.seed, noise=task.noise, mesh=task.mesh, write=False)
    r = trials.results
    gmap = load_map(task.map_path)
    arrays = {"index": trials.index, "grade": gmap.grade[trials.index], **r.arrays()}
    record = {"task": task.to_dict(), "counts": r.counts(), "feasible": r.feasible,
              "success_rate": r.success_rate, "info": r.info(), "seconds": time.perf_counter() - t0}
    return {"arrays": arrays, "record": record}


@dataclass(frozen=True)
class CampaignResult:
    """Per-task records, pooled outcome counts, success rate over feasible trials with its
    95 % Wilson interval; ``ran`` / ``skipped``: tasks run now / found done."""

    records: list[dict]
    counts: dict[str, int]
    success_rate: float
    interval: tuple[float, float]
    ran: int
    skipped: int
    seconds: float
    out: str
    extra: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {"out": self.out, "tasks": len(self.records), "ran": self.ran, "skipped": self.skipped,
                "counts": self.counts, "success_rate": self.success_rate,
                "interval_95": list(self.interval), "seconds": self.seconds}


def _task_file(out: Path, task: CampaignTask) -> Path:
    return out / "tasks" / f"{task.task_id}.npz"


def _save(out: Path, task: CampaignTask, result: dict) -> None:
    with atomic_path(_task_file(out, task), error=CampaignError) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, record=np.array(json.dumps(result["record"])), **result["arrays"])


def _load(path: Path) -> dict | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files if k != "record"}
            record = json.loads(str(z["record"]))
        return {"arrays": arrays, "record": record}
    except (OSError, ValueError, KeyError) as err:
        log.warning("ignoring damaged task result %s (%s); it will be rerun", path, err)
        return None


def _check_settings(*, top, sample, threads, min_grade) -> None:
    """Task settings a trial can run with, checked before a campaign folder is made
    (``ExecutionNoise`` checks its own sigmas)."""
    for name, n in (("top", top), ("sample", sample), ("threads", threads)):
        if n is not None and not n >= 1:
            raise InvalidParameterError(f"{name} must be >= 1, got {n!r}")
    if min_grade is not None and not min_grade < 1.0:  # grades lie in [0, 1]
        raise InvalidParameterError(f"nothing to simulate: no grasp has a grade > {min_grade!r} (grades lie "
                                    "in [0, 1])")


def run_campaign(tasks: Sequence[CampaignTask], out: str | os.PathLike, *,
                 executor: Executor | None = None, max_tasks: int | None = None,
                 progress: Callable[[int, int], None] | None = None) -> CampaignResult:
    """Run the tasks not yet done in ``out`` (resumable); ``max_tasks`` stops after that
    many new tasks (a controlled interruption)."""
    out = Path(out)
    if max_tasks is not None and not max_tasks >= 0:
        raise InvalidParameterError(f"max_tasks must be >= 0, got {max_tasks!r}")
    (out / "tasks").mkdir(parents=True, exist_ok=True)
    spec = {"format": "graspsim-campaign-1", "tasks": [t.to_dict() for t in tasks]}
    spec_path = out / "spec.json"
    if spec_path.exists():
        try:
            old = json.loads(spec_path.read_text())
        except ValueError as err:
            raise CampaignError(f"{spec_path} is damaged: {err}") from err
        if old != spec:
            raise CampaignError(
                f"{out} holds a different campaign (its spec.json lists other tasks); use a new "
                "folder or the same options to resume")
    else:
        atomic_write_text(spec_path, json.dumps(spec, indent=1), error=CampaignError)
    t0 = time.perf_counter()
    done = {t.task_id: r for t in tasks if _task_file(out, t).exists()
            for r in [_load(_task_file(out, t))] if r is not None}
    todo = [t for t in tasks if t.task_id not in done]
    if max_tasks is not None:
        todo = todo[:max_tasks]
    skipped = len(done)
    executor = executor or SerialExecutor()
    finished = 0
    for i, result in executor.imap(run_task, todo):
        _save(out, todo[i], result)
        done[todo[i].task_id] = result
        finished += 1
        if progress:
            progress(finished, len(todo))
    records = [done[t.task_id]["record"] for t in tasks if t.task_id in done]
    return _summarise(records, out, finished, skipped, time.perf_counter() - t0)


def _summarise(records: list[dict], out: Path, ran: int, skipped: int, seconds: float) -> CampaignResult:
    counts: dict[str, int] = {}
    for r in records:
        for k, v in r["counts"].items():
            counts[k] = counts.get(k, 0) + int(v)
    feasible = sum(int(r["feasible"]) for r in records)
    succ = counts.get("success", 0)
    rate = succ / feasible if feasible else float("nan")
    return CampaignResult(records, counts, rate, wilson_interval(succ, feasible), ran, skipped,
                          seconds, str(out))


def load_campaign(out: str | os.PathLike) -> tuple[list[CampaignTask], dict[str, dict]]:
    """The task list and the finished tasks' results (arrays + record) of a campaign folder."""
    out = Path(out)
    try:
        spec = json.loads((out / "spec.json").read_text())
    except (OSError, ValueError) as err:
        raise CampaignError(f"{out} is not a campaign folder: {err}") from err
    from graspsim.sim import ExecutionNoise

    tasks = [CampaignTask(**{**d, "noise": ExecutionNoise(*d["noise"]) if d["noise"] else None})
             for d in spec["tasks"]]
    done = {t.task_id: r for t in tasks if _task_file(out, t).exists()
            for r in [_load(_task_file(out, t))] if r is not None}
    return tasks, done
