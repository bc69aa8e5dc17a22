"""Checks before a full-scale map is generated: can anything be grasped, and will the
map fit in memory.

Both run before the generator allocates anything, so an impossible request (a 10 m
sphere, a cloud read in millimetres as metres) ends at once with one clear error
instead of filling the machine's memory:

* :func:`check_graspable`: the object's thinnest local width
  (``min_cross_section``) must fit the gripper's maximum opening somewhere;
* :func:`estimate_map_memory`: the generator's allocations, counted from the
  object's surface area, the sampling steps and the gripper, against
  :func:`memory_budget` (``GRASPSIM_MEMORY_BUDGET``, default half the machine's RAM).

The per-item byte costs were calibrated with numpy's traced allocations per stage
on the five paper primitives (``python experiments/bench_map_memory.py`` compares
the estimate with the measured peak resident memory): the closing-line scan takes
280-305 B per line, the collision sample hierarchy 235-241 B per fine sample (plus
its float32 copy in the sweep), the finished map 112-115 B per grasp and writing
or sorting it another 122-130 B.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from graspsim.errors import BudgetExceededError, InvalidParameterError, NoFeasibleGraspError

__all__ = ["MapEstimate", "estimate_map_memory", "collision_sample_count", "check_collision_samples",
           "check_graspable", "check_memory", "check_bytes",
           "memory_budget", "parse_size", "total_memory", "BUDGET_ENV", "DEFAULT_CAP"]

#: Environment variable holding the memory budget: bytes with an optional binary unit
#: ("4GiB", "512M") or a percentage of the machine's memory ("50%").
BUDGET_ENV = "GRASPSIM_MEMORY_BUDGET"
#: Default budget: half the machine's memory, at most DEFAULT_CAP. The cap keeps any one
#: command's peak resident memory under 4 GiB, so that every command runs on a machine with
#: 4 GiB to spare (a small CI runner, a laptop): the budget bounds the map
#: (its estimate exceeds the measured growth by 1.2-1.5x, bench_map_preflight), and the
#: process itself -- interpreter, numpy/scipy/numba and the compiled kernels -- holds
#: another ~0.25 GiB. The paper's largest FS map needs 0.5 GiB: seven times below it.
DEFAULT_FRACTION = 0.5
DEFAULT_CAP = 3584 << 20  # 3.5 GiB

BYTES_PER_LINE = 400  # closing-line scan: contacts, directions, ray marching
BYTES_PER_COLLISION_SAMPLE = 300  # fine level of the hierarchy + its float32 copy
BYTES_PER_GRASP = 256  # map columns + the copies made when sorting or writing them
_FIXED_BYTES = 16 << 20

_UNITS = {"": 1, "b": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def total_memory() -> int | None:
    """Physical memory [bytes], or the container's limit where that is lower; None
    when unknown."""
    total = None
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):  # pragma: no cover - not POSIX
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                limit = int(f.read().strip())
        except (OSError, ValueError):  # absent, or "max"
            continue
        if limit > 0 and (total is None or limit < total):
            total = limit
    return total


def parse_size(text: str) -> int:
    """Bytes of a size such as ``"4GiB"``, ``"512M"``, ``"1e9"`` or ``"50%"`` (of
    :func:`total_memory`)."""
    s = str(text).strip().lower()
    m = re.fullmatch(r"([0-9]*\.?[0-9]+(?:e[0-9]+)?)\s*(%|[kmgt]?)(?:i?b)?", s)
    value = float(m.group(1)) if m else math.nan
    if not (math.isfinite(value) and value > 0):
        raise InvalidParameterError(
            f"memory budget must be a positive size such as 4GiB, 512M or 50%, got {text!r}")
    if m.group(2) == "%":
        total = total_memory()
        if total is None:
            raise InvalidParameterError(f"memory budget {text!r}: this machine's memory is unknown; "
                                        "give bytes (e.g. 4GiB)")
        n = total * value / 100.0
    else:
        n = value * _UNITS[m.group(2)]
    if not 1 <= n < 2.0**62:  # "0.5" or "1e-9%": a fraction of a byte; "1e300T": no such memory
        raise InvalidParameterError(f"memory budget must be between one byte and 4 EiB, got {text!r}")
    return int(n)


def memory_budget(budget: int | float | str | None = None) -> int:
    """The memory an FS map (or a map read from a file) may use [bytes]: ``budget`` if
    given (bytes or a size string), else ``$GRASPSIM_MEMORY_BUDGET``, else half the
    machine's memory and at most :data:`DEFAULT_CAP` (3.5 GiB)."""
    if budget is not None:
        return parse_size(str(budget))
    env = os.environ.get(BUDGET_ENV)
    if env:
        try:
            return parse_size(env)
        except InvalidParameterError as err:
            raise InvalidParameterError(f"${BUDGET_ENV}: {err}") from None
    total = total_memory()
    return min(int(DEFAULT_FRACTION * total), DEFAULT_CAP) if total else DEFAULT_CAP


def check_graspable(shape, gripper) -> None:
    """Raise :class:`NoFeasibleGraspError` when the object's thinnest local width is
    wider than the gripper's maximum opening: then no part of it fits between the
    jaws and its map would be empty (after generating all of it)."""
    thinnest = float(shape.min_cross_section)
    if thinnest > gripper.max_opening:
        raise NoFeasibleGraspError(
            f"nothing of {shape} is graspable by {gripper.name}: its thinnest cross-section, "
            f"{_length(thinnest)}, is wider than the gripper's maximum opening "
            f"{_length(gripper.max_opening)} (valid: objects with some part at most that wide; "
            "were the dimensions meant in metres?)")


@dataclass(frozen=True)
class MapEstimate:
    """What the generator will allocate for one FS map. contacts: first contacts on
    the surface; directions: closing directions per contact; rolls x depths: poses
    per closing line; collision_samples: fine samples of the collision hierarchy."""

    contacts: int
    directions: int
    rolls: int
    depths: int
    collision_samples: int

    @property
    def lines(self) -> int:
        return self.contacts * self.directions

    @property
    def candidates(self) -> int:
        """Poses tested for collision (an upper bound on the map's grasps)."""
        return self.lines * self.rolls * self.depths

    @property
    def work_bytes(self) -> int:
        """Memory before any grasp is stored: the closing-line scan, the collision
        hierarchy and the sweep's flags [bytes]."""
        return int(_FIXED_BYTES + self.lines * (BYTES_PER_LINE + self.rolls * self.depths)
                   + self.collision_samples * BYTES_PER_COLLISION_SAMPLE)

    def bytes(self, grasps: int | None = None) -> int:
        """Peak memory with ``grasps`` collision-free poses (None: all candidates)."""
        n = self.candidates if grasps is None else int(grasps)
        return self.work_bytes + n * BYTES_PER_GRASP


def estimate_map_memory(shape, gripper, config) -> MapEstimate:
    """Counts of what :func:`~graspsim.maps.generate.generate_fs_map` allocates for
    ``shape`` (Primitive or Compound), from its surface area and the sampling steps
    (a few hundred coarse samples; nothing the size of the map)."""
    from graspsim.maps.map_config import closing_direction_count, roll_count

    parts = getattr(shape, "parts", (shape,))
    # sampling grids fit whole cells into each patch: up to ~15 % more samples than
    # area / step^2 (measured on the five primitives)
    step = config.surface_step
    contacts = _count(1.2 * _surface_area(shape) / step / step) + 16 * len(parts)  # (twice: no underflow)
    return MapEstimate(contacts, closing_direction_count(config.closing_cone, config.rotation_step),
                       roll_count(config), gripper.contact_depth_count(config.depth_step),
                       collision_sample_count(shape, config))


def collision_sample_count(shape, config) -> int:
    """Fine samples of the collision hierarchy of ``shape`` at ``config.collision_tolerance``
    (:func:`~graspsim.maps.hierarchy.build_levels`): its step is refined until the cover
    radius meets the tolerance (at most ~25 % more than area / (1.3 tolerance)^2)."""
    fstep = 1.3 * config.collision_tolerance
    return _count(1.25 * _surface_area(shape) / fstep / fstep) + 16 * len(getattr(shape, "parts", (shape,)))


def check_collision_samples(shape, config, budget: int | str | None = None) -> None:
    """Raise :class:`BudgetExceededError` before a collision hierarchy of ``shape`` is
    built whose samples would not fit the budget (the scaler and combiner build one for
    objects no FS map was generated for: a familiar object up to three times a stored
    map's size has up to nine times its surface)."""
    n = collision_sample_count(shape, config)
    check_bytes(n * BYTES_PER_COLLISION_SAMPLE, f"the collision samples of {shape}",
                "coarsen collision_tolerance", budget, detail=f"{n:.3g} samples x {BYTES_PER_COLLISION_SAMPLE} B")


def _surface_area(shape) -> float:
    """Surface area [m^2] from a few hundred coarse samples (inf for a shape too large
    for floats)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return sum(float(p.surface_samples(p.size_scale / 8).areas.sum()) for p in getattr(shape, "parts", (shape,)))


def _count(x: float) -> int:
    """ceil(x) as an int, saturating at 2^62 (an overflowed or absurd count is refused
    by the budget, never converted)."""
    return math.ceil(x) if x < 2.0**62 else 1 << 62


def check_memory(shape, estimate: MapEstimate, budget: int, *, grasps: int | None = None) -> None:
    """Raise :class:`BudgetExceededError` if the map would need more than ``budget``
    bytes: before generation (``grasps`` None) the work memory alone is checked, once
    the collision-free poses are counted their map too."""
    need = estimate.work_bytes if grasps is None else estimate.bytes(grasps)
    what = (f"{estimate.contacts:.3g} surface contacts x {estimate.directions} closing directions "
            f"and {estimate.collision_samples:.3g} collision samples" if grasps is None else
            f"{grasps:.4g} collision-free grasps x {BYTES_PER_GRASP} B and the scan")
    check_bytes(need, f"the FS map of {shape}", "coarsen the sampling (surface_step, collision_tolerance)",
                budget, detail=what)


def check_bytes(need: float, what: str, hint: str, budget: int | str | None = None, *,
                detail: str | None = None) -> None:
    """Raise :class:`BudgetExceededError` if ``what`` would need more than ``budget``
    bytes (None: :func:`memory_budget`); the message gives the need, the budget,
    ``hint`` (what to do instead) and how to raise the budget."""
    budget = budget if isinstance(budget, int) else memory_budget(budget)
    if need <= budget:
        return
    raise BudgetExceededError(
        f"{what} would need about {_gib(need)}" + (f" ({detail})" if detail else "") + ", more than the "
        f"memory budget of {_gib(budget)}; {hint} or raise the budget (${BUDGET_ENV}, e.g. "
        f"{BUDGET_ENV}=16GiB)")


def _gib(n: float) -> str:
    return f"{n / (1 << 30):.3g} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.3g} MiB"


def _length(x: float) -> str:
    return f"{x:.4g} m" if x >= 1.0 else f"{x * 1000:.4g} mm"
