"""Known / familiar decision against stored FS maps (paper 2.4).

An identified primitive is *known* when a stored map of the same primitive kind lies
within ``tol`` (1 cm in the paper) on every dimension, *familiar* when maps of that
kind exist only at other sizes, and unmatched (None) when no map of that kind exists.
Pure: the map database passes the dims of its stored maps and can call this itself.

Boxes are compared on their sorted edge lengths (a box is the same box whichever
edge is called x); the caller maps axes if the stored map's edges are ordered
differently.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from graspsim.errors import InvalidParameterError

__all__ = ["MatchKind", "MatchDecision", "classify_match"]


class MatchKind(str, Enum):
    KNOWN = "known"
    FAMILIAR = "familiar"


@dataclass(frozen=True)
class MatchDecision:
    """match: KNOWN, FAMILIAR or None; entry: the nearest stored entry of that kind (as
    passed in) or None; max_diff: its largest per-dimension difference [m]."""

    match: MatchKind | None
    entry: dict[str, Any] | None
    max_diff: float


def _kind_of(entry: dict) -> str:
    return str(entry.get("primitive", entry.get("kind", ""))).lower().replace("-", "_")


def _dims_of(entry: dict) -> dict[str, float]:
    dims = entry.get("dims")
    if not isinstance(dims, dict):
        raise InvalidParameterError(f"stored map entry without a dims dict: {entry!r}")
    return dims


def classify_match(kind: str, dims: dict[str, float], stored: list[dict], *,
                   tol: float = 0.01) -> MatchDecision:
    """Decide known / familiar / None for primitive ``kind`` with ``dims`` [m].

    stored: entries ``{"primitive": kind, "dims": {name: metres}, ...}`` (extra keys
    are kept and returned in ``entry``)."""
    if not tol >= 0:
        raise InvalidParameterError(f"tol must be >= 0 m, got {tol!r}")
    kind = kind.lower().replace("-", "_")
    same = [e for e in stored if _kind_of(e) == kind]
    if not same:
        return MatchDecision(None, None, float("inf"))

    def diff(entry: dict) -> float:
        other = _dims_of(entry)
        if set(other) != set(dims):
            raise InvalidParameterError(
                f"stored {kind} map has dims {sorted(other)}, the query {sorted(dims)}"
            )
        if kind == "box":
            a, b = sorted(dims.values()), sorted(other.values())
            return max(abs(x - y) for x, y in zip(a, b))
        return max(abs(float(dims[n]) - float(other[n])) for n in dims)

    diffs = [diff(e) for e in same]
    i = min(range(len(same)), key=diffs.__getitem__)
    kind_of_match = MatchKind.KNOWN if diffs[i] <= tol else MatchKind.FAMILIAR
    return MatchDecision(kind_of_match, same[i], float(diffs[i]))
