"""A scene's segments identified and planned side by side, on worker processes.

Identification is many small numpy and scipy calls on a few hundred points, and so is
most of planning (scaling a map, its collision samples, combining): they hold the
GIL, so threads do not run them side by side, processes do. Each segment draws from
its own generator (spawned from the scene's) and a segment's planning draws nothing,
so the results do not depend on how many workers there are, nor on the order they
finish in: one worker or several give the same result.

The workers are forked once per process and kept: they start with the caller's modules
already imported (milliseconds; ``spawn`` would import graspsim again in each, and
run a user's unguarded script again), and each scene costs only the transfer of points
and results. They never touch MuJoCo, whose GL contexts the fork does not carry, nor
numba's OpenMP pool: a child forked after the parent ran a ``parallel=True`` kernel (the
pad-contact grade's) is terminated if it runs one, so the workers run that kernel's
serial twin (:func:`graspsim.grades.pad_kernel.serial_only`; the same arithmetic); the map
kernels' thread pools are the process's own (:mod:`graspsim.maps.kernels`). A map
database sent to a worker stays there (:func:`resident_database`), with its cache of
loaded maps. Where ``fork`` does not exist (Windows), and inside a process that is
itself a worker (an experiment's executor, this pool), segments are handled one after
another: there the parallelism is already outside.

A new worker loads what planning uses before its first segment (:func:`_warm`: the
compiled kernels from numba's cache, h5py, the modules planning imports when it first
needs them; a few tenths of a second, once). The pool starts on the first scene, so
that first scene waits for it; :func:`start_workers` starts it ahead of time, and the
workers load in the background while the caller waits for something else (a camera's
first frame). Where the caller is busy meanwhile, on as many cores as there are
workers, the warm-up only competes with it (``experiments/bench_scene.py`` measures
both on 2 cores: no faster there).

A caller that plans segments in groups and may stop after any group (a scene planned
lazily: ``SceneConfig.good_enough``) streams them (:func:`stream_segments`): a worker
that finishes its task while the group's last one still runs starts the next group's
first task ahead of time instead of waiting idle. A group's results are those of
planning the groups one after another (each task is planned alone, from its own
inputs); the caller takes them group by group, and when it stops, the tasks begun
ahead of time are given up -- each stops at its next :func:`cancelled` check, and its
result is never read.
"""

from __future__ import annotations

import atexit
import ctypes
import itertools
import logging
import multiprocessing as mp
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import closing

import numpy as np

from graspsim.errors import IdentificationError, InvalidParameterError, PointCloudError
from graspsim.perception.identify import Identification, identify
from graspsim.perception.identify_config import IdentifyConfig

__all__ = ["cancelled", "identify_segment", "identify_segments", "run_segments", "stream_segments",
           "resident_database", "scene_workers", "start_workers", "shutdown_workers"]

log = logging.getLogger(__name__)

_pools: dict[int, tuple[int, ProcessPoolExecutor]] = {}  # workers -> (pid, pool)
_lock = threading.Lock()
_databases: dict[tuple, object] = {}  # in a worker: the map databases sent to it, by folder and settings
_in_worker = False  # this process is one of the scene's workers
# tasks of stream_segments are numbered (tickets, in the process that streams); a task whose
# ticket's slot (ticket mod _SLOTS) is set was given up by its stream. Shared memory made
# before any pool forks, so every worker reads what the caller writes; a stream sets only its
# own tickets' slots (streams in other threads go on), and a slot is cleared as its ticket is
# handed out (a task would have to run while _SLOTS more are handed out to read another's).
_SLOTS = 4096
_given_up = mp.RawArray(ctypes.c_ubyte, _SLOTS)
_tickets = itertools.count()  # in the streaming process: the next ticket
_ticket: int | None = None  # in a worker: the ticket of the task it runs (None: a task without one)


def identify_segment(points: np.ndarray, rng: np.random.Generator, config: IdentifyConfig
                     ) -> tuple[Identification | None, str]:
    """The segment's identification, or None and why it could not run (e.g. a flat
    face seen head-on)."""
    try:
        return identify(points, rng=rng, config=config), ""
    except (IdentificationError, PointCloudError) as err:
        return None, str(err)


def scene_workers(workers: int | None) -> int:
    """Worker processes to identify segments on: ``workers`` (None: one per core this
    process may use), 1 (in this process) inside a process that is itself a worker."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InvalidParameterError(f"workers must be an integer >= 1 or None, got {workers!r}")
    if mp.parent_process() is not None or "fork" not in mp.get_all_start_methods():
        return 1
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return int(workers)


def _pool(workers: int) -> ProcessPoolExecutor:
    with _lock:
        pid, ex = _pools.get(workers, (None, None))
        if ex is None or pid != os.getpid():
            ex = ProcessPoolExecutor(workers, mp_context=mp.get_context("fork"), initializer=_start_worker)
            _pools[workers] = (os.getpid(), ex)
        return ex


def _start_worker() -> None:
    global _in_worker
    from graspsim.grades.pad_kernel import serial_only

    serial_only()  # the parent may have started numba's OpenMP pool: this child must not
    _databases.clear()
    _in_worker = True
    try:
        _warm()
    except Exception as err:  # noqa: BLE001 -- a warm-up that fails is no failure: the first segment loads lazily
        log.debug("scene worker warm-up failed (%s); loading on first use", err)


def _warm() -> None:
    """Load what identifying and planning a segment uses, ahead of the first one: every
    compiled kernel (:func:`~graspsim.maps.warmup.compile_all`, from numba's on-disk
    cache; the pad-contact grade's serial twin only), h5py (stored maps) and the modules
    planning imports on first use, so the first segment does not wait for them. Changes
    no result."""
    import importlib

    import h5py  # noqa: F401

    from graspsim.maps.warmup import compile_all

    compile_all(parallel=False)
    # trimesh: a part's mesh (``maps.table_clearance.low_part``), 0.7 s to import where the caller had not
    for name in ("graspsim.perception.decompose", "graspsim.perception.acceptance", "graspsim.maps.occlusion",
                 "graspsim.grades.models", "trimesh"):
        importlib.import_module(name)


def _nothing() -> None:
    """A task that only makes the pool start its workers."""


def start_workers(workers: int | None = None) -> int:
    """Start this process's segment workers for ``workers`` (as :attr:`SceneConfig.workers
    <graspsim.planning.scene.SceneConfig.workers>`; None: one per core) now, without
    waiting for them: each loads what planning uses in the background (a few tenths
    of a second) while this process goes on, so the first :func:`plan_scene
    <graspsim.planning.scene.plan_scene>` does not wait for it. Returns the number of
    workers (1: none started; segments are planned in this process). Call it once, early
    (e.g. before a camera's first frame arrives); :func:`shutdown_workers` stops them."""
    n = scene_workers(workers)
    if n > 1:
        _pool(n).submit(_nothing)
    return n


def resident_database(db):
    """In a scene worker: the :class:`~graspsim.maps.database.MapDatabase` already here
    for ``db``'s folder and settings (with the maps it has loaded), else ``db``, kept;
    elsewhere (this process, any other child process) ``db`` itself."""
    if not _in_worker:
        return db
    key = (str(db.root), db.settings_digest, db.tol, db.cache_size, db.cache_bytes)
    return _databases.setdefault(key, db)


def shutdown_workers() -> None:
    """Stop this process's segment workers (the next parallel call starts new ones)."""
    with _lock:
        pools = [ex for pid, ex in _pools.values() if pid == os.getpid()]
        _pools.clear()
    for ex in pools:
        ex.shutdown(wait=True, cancel_futures=True)


atexit.register(shutdown_workers)


def cancelled() -> bool:
    """Whether the task this process runs was given up by the caller that streamed it
    (:func:`stream_segments`; its result will not be read): a long task checks between
    its steps and returns early. False outside such a task."""
    return _ticket is not None and _given_up[_ticket % _SLOTS] != 0


def _ticketed(ticket: int, fn: Callable, *task):
    """``fn(*task)`` run as task number ``ticket`` (what :func:`cancelled` checks)."""
    global _ticket
    _ticket = ticket
    try:
        return fn(*task)
    finally:
        _ticket = None


def identify_segments(segments: list[np.ndarray], rngs: list[np.random.Generator], config: IdentifyConfig,
                      workers: int | None = 1) -> list[tuple[Identification | None, str]]:
    """:func:`identify_segment` of every segment (M_i, 3) [m] with its own generator,
    on ``workers`` processes (see :func:`scene_workers`); results in segment order."""
    if len(rngs) != len(segments):
        raise InvalidParameterError(f"one generator per segment needed: {len(segments)} segments, {len(rngs)}")
    return run_segments(identify_segment, [(s, r, config) for s, r in zip(segments, rngs)],
                        [len(s) for s in segments], workers)


def run_segments(fn, tasks: list[tuple], sizes: list[float], workers: int | None = 1) -> list:
    """``fn(*task)`` of every task (a module-level function, for the workers to find it)
    on ``workers`` processes (see :func:`scene_workers`), the largest ``sizes`` first
    (the longest tasks, so that none is left to run alone at the end); results in task
    order."""
    if len(sizes) != len(tasks):
        raise InvalidParameterError(f"one size per task needed: {len(tasks)} tasks, {len(sizes)} sizes")
    n = scene_workers(workers)
    if min(n, len(tasks)) <= 1:
        return [fn(*t) for t in tasks]
    with closing(stream_segments(fn, [(tasks, sizes, True)], n)) as stream:  # one group
        return next(stream)


def stream_segments(fn: Callable, groups: list[tuple[list[tuple], list[float], bool]], workers: int | None = 1
                    ) -> Iterator[list]:
    """The results of ``fn(*task)`` for each group ``(tasks, sizes, parallel)``, one list
    per group in task order, yielded group after group: the same results as
    :func:`run_segments` on each group in turn. A parallel group's tasks run on
    ``workers`` processes (see :func:`scene_workers`), its largest ``sizes`` first; a
    worker free before its group ends starts the next groups' tasks -- up to the next
    group that is not parallel, which runs in this process once every group before it
    has been yielded (a task that may change what later ones read). Closing the
    generator (the caller needs no more groups) gives up the tasks started ahead: those
    not begun are cancelled, those running stop at their next :func:`cancelled` check,
    and their results are never read."""
    n = scene_workers(workers)
    if n <= 1:
        for tasks, _, _ in groups:
            yield [fn(*t) for t in tasks]
        return
    # the order tasks are started in: group by group, each group's largest first
    order = [(g, i) for g, (tasks, sizes, _) in enumerate(groups)
             for i in sorted(range(len(tasks)), key=lambda i: -sizes[i])]
    futures: dict[tuple[int, int], Future] = {}
    tickets: dict[tuple[int, int], int] = {}
    at = 0  # the next task in ``order`` to start
    pool: ProcessPoolExecutor | None = _pool(n)
    try:
        for g, (tasks, _, parallel) in enumerate(groups):
            if not parallel or pool is None:  # here, after every earlier group (none of its tasks started ahead)
                yield [fn(*t) for t in tasks]
                at = max(at, next((j for j, (h, _) in enumerate(order) if h > g), len(order)))
                continue
            try:
                while True:
                    running = [f for f in futures.values() if not f.done()]
                    # started in order, so never past a group that runs here (one not parallel)
                    while len(running) < n and at < len(order) and groups[order[at][0]][2]:
                        h, i = order[at]
                        ticket = next(_tickets)
                        _given_up[ticket % _SLOTS] = 0
                        futures[h, i] = pool.submit(_ticketed, ticket, fn, *groups[h][0][i])
                        tickets[h, i] = ticket
                        running.append(futures[h, i])
                        at += 1
                    if all((g, i) in futures and futures[g, i].done() for i in range(len(tasks))):
                        break
                    wait(running, return_when=FIRST_COMPLETED)
                out = [futures.pop((g, i)).result() for i in range(len(tasks))]
            except BrokenProcessPool as err:  # a worker was killed (e.g. out of memory): go on without them
                log.warning("a scene worker process died (%s); its pool is dropped and the segments are handled in "
                            "this process (the result is the same)", err)
                _drop(n, pool)
                pool = None
                futures.clear()
                out = [fn(*t) for t in tasks]  # and every later group, as pool is None
            yield out
    finally:  # the caller stopped (or every group is done): give up what was started ahead
        for key, f in futures.items():
            if not f.cancel() and not f.done():  # running: it stops at its next check
                _given_up[tickets[key] % _SLOTS] = 1


def _drop(n: int, pool: ProcessPoolExecutor) -> None:
    """Forget the pool of ``n`` workers (one died): the next call starts a new one."""
    with _lock:
        if _pools.get(n, (None, None))[1] is pool:
            del _pools[n]
    pool.shutdown(wait=False, cancel_futures=True)
