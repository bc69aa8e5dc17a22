"""Where independent jobs run: in this process, in local worker processes, or on Ray.

Jobs bigger than one machine -- FS databases over many primitives x sizes, trial
campaigns over many maps, calibration runs -- are lists of independent tasks: a
picklable top-level function applied to frozen task records that carry their own
seeds. Every executor returns the same results for the same tasks (only the order in
which they complete differs), so ``--executor ray`` never changes a number.

Ray is optional (``pip install 'graspsim[ray]'``) and imported only when asked for;
``address=None`` starts a local Ray instance, ``address="auto"`` or
``"ray://head:10001"`` joins an existing cluster.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from graspsim.errors import DependencyNotInstalled, InvalidParameterError

__all__ = ["Executor", "SerialExecutor", "ProcessExecutor", "RayExecutor", "make_executor",
           "EXECUTORS"]

log = logging.getLogger(__name__)


class Executor:
    """Runs ``fn(task)`` for every task; ``imap`` yields ``(index, result)`` as tasks
    finish. Use as a context manager (``close`` releases workers)."""

    name = "executor"

    def imap(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        raise NotImplementedError

    def map(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> list[Any]:
        """All results, in task order."""
        out: list[Any] = [None] * len(tasks)
        for i, r in self.imap(fn, tasks):
            out[i] = r
        return out

    def close(self) -> None:
        pass

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SerialExecutor(Executor):
    """In this process, one task after another (debugging, tiny jobs)."""

    name = "serial"

    def imap(self, fn, tasks):
        for i, t in enumerate(tasks):
            yield i, fn(t)


class ProcessExecutor(Executor):
    """Local worker processes (default: one per core). Tasks that use threads inside
    (numba, mujoco.rollout) should then use one thread each."""

    name = "local"

    def __init__(self, workers: int | None = None):
        self.workers = int(workers or os.cpu_count() or 1)
        if self.workers < 1:
            raise InvalidParameterError(f"workers must be >= 1, got {workers!r}")
        self._pool: ProcessPoolExecutor | None = None

    def imap(self, fn, tasks):
        if self.workers == 1 or len(tasks) <= 1:
            yield from SerialExecutor().imap(fn, tasks)
            return
        if self._pool is None:
            import multiprocessing as mp

            self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"))
        futures = {self._pool.submit(fn, t): i for i, t in enumerate(tasks)}
        for f in as_completed(futures):
            yield futures[f], f.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None


class RayExecutor(Executor):
    """Tasks as Ray remote functions, on a local instance or a cluster."""

    name = "ray"

    def __init__(self, address: str | None = None, num_cpus: int | None = None,
                 task_cpus: float = 1.0):
        try:
            import ray
        except ImportError as err:
            raise DependencyNotInstalled(
                "the Ray executor needs Ray: pip install 'graspsim[ray]' (or pip install ray)") from err
        self._ray = ray
        self._owns = False
        if not ray.is_initialized():
            kw: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                  "configure_logging": False}
            if address is None:
                kw["num_cpus"] = num_cpus or os.cpu_count()
            else:
                kw["address"] = address
            blas = os.environ.get("OPENBLAS_CORETYPE")  # graspsim._blas's pin (or the user's choice)
            if blas:  # a local instance's workers inherit it; a cluster's are told (every node must run them)
                kw["runtime_env"] = {"env_vars": {"OPENBLAS_CORETYPE": blas}}
            os.environ.setdefault("RAY_AUTH_MODE", "disabled")
            ray.init(**kw)
            self._owns = True
        self.task_cpus = float(task_cpus)

    def imap(self, fn, tasks):
        ray = self._ray
        remote = ray.remote(num_cpus=self.task_cpus)(_call)
        fn_ref = ray.put(fn)
        refs = {remote.remote(fn_ref, t): i for i, t in enumerate(tasks)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for r in done:
                yield refs[r], ray.get(r)

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
            self._owns = False


def _call(fn: Callable[[Any], Any], task: Any) -> Any:
    """Ray's remote entry point: any picklable callable (builtins included) on a task."""
    return fn(task)


EXECUTORS = ("serial", "local", "ray")


def make_executor(kind: str = "local", *, workers: int | None = None,
                  address: str | None = None) -> Executor:
    """``"serial"``, ``"local"`` (processes; ``workers``) or ``"ray"`` (``address``)."""
    if kind == "serial":
        return SerialExecutor()
    if kind == "local":
        return ProcessExecutor(workers)
    if kind == "ray":
        return RayExecutor(address=address, num_cpus=workers)
    raise InvalidParameterError(f"unknown executor {kind!r}; valid: {list(EXECUTORS)}")
