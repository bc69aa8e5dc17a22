"""Progress bars on stderr: the command line's, and those of the few library entry points a
user meets interactively (a gym environment's first resets, which prepare meshes and build
maps). A bar is drawn only on a terminal, and only once its wait passes ``delay`` seconds, so
work that is already cached stays quiet."""

from __future__ import annotations

import contextlib
import sys

__all__ = ["progress", "map_build_bar"]


def progress(total: int | None, desc: str, enabled: bool = True, unit: str = "it", delay: float = 0.0, *,
             tick: float | None = None):
    """A tqdm progress bar on stderr (disabled when not wanted or not a terminal; shown
    only after ``delay`` seconds: set its postfix with ``refresh=False``). With
    ``tick`` [s] the bar is redrawn that often even when nothing finished (its elapsed
    time runs: steps that take long, such as maps built in worker processes, do not look
    stuck); the redrawing stops when the bar is closed."""
    import threading
    import time

    from tqdm.auto import tqdm

    on = enabled and sys.stderr.isatty()
    bar = tqdm(total=total, desc=desc, unit=unit, disable=not on, file=sys.stderr, leave=False, delay=delay)
    if on and tick:
        stop = threading.Event()
        shown = time.monotonic() + delay

        def redraw() -> None:
            while not stop.wait(tick):
                if time.monotonic() >= shown:  # a refresh draws the bar: not before its delay
                    bar.refresh()

        threading.Thread(target=redraw, name="graspsim-progress", daemon=True).start()
        close = bar.close

        def closing() -> None:
            stop.set()
            close()

        bar.close = closing
    return bar


@contextlib.contextmanager
def map_build_bar(shape, delay: float = 0.0):
    """A bar for one FS map the database builds on demand (the value
    ``graspsim.maps.database.BUILD_PROGRESS`` takes): yields the fraction callback."""
    with progress(100, f"building the FS map of {shape} (stored for next time)", unit="%", delay=delay) as b:
        def report(frac: float) -> None:
            b.update(int(100 * frac) - b.n)  # drawn once the delay has passed

        yield report
