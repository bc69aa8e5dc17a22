"""Seconds spent per stage of a pipeline whose stages interleave (the planner's
retrieval and scaling, cloud agreement, combination and table filter take turns on
every streamed batch)."""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator

__all__ = ["StageClock"]


class StageClock:
    """Accumulates wall seconds per named stage: :meth:`start`, then :meth:`lap` at the
    end of each stage adds the time since the last start or lap to it; ``seconds``
    holds the totals."""

    def __init__(self, *stages: str) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(stages, 0.0)
        self._since = time.perf_counter()

    def start(self) -> None:
        self._since = time.perf_counter()

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._since
        self._since = now

    def iterate(self, items: Iterable, stage: str) -> Iterator:
        """``items``, the time taken to produce each counted to ``stage``; the clock
        restarts as each item is handed over."""
        it = iter(items)
        while True:
            self.start()
            try:
                item = next(it)
            except StopIteration:
                self.lap(stage)
                return
            self.lap(stage)
            yield item
