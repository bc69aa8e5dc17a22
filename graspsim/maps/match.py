"""Which stored FS map serves a primitive (paper 2.4): known / familiar / build.

The one rule, used by :meth:`MapDatabase.match <graspsim.maps.database.MapDatabase.match>`
and through it by the planner and the CLI:

* the stored maps of the same primitive kind are ranked by the size change scaling would
  need -- the largest per-dimension ratio ``max(v / w, w / v)`` (1 for equal dims), each
  value taken as at least ``MIN_DIM`` (1 mm, the thinnest a primitive is: a cone's top
  radius below it is a point, and a pointed cone's 0 is as near a stored 0.4 mm top as
  to another 0; :func:`size_ratio`);
* *known*: a stored map lies within the relative tolerance ``tol`` (:data:`KNOWN_TOL`,
  3 %) on every dimension -- its ratio is at most ``1 + tol`` -- and the nearest of those
  (by the ratio) serves the primitive as is. The paper's 1 cm on every dimension took a
  can of r 32.9 mm as a stored r 24 mm one and gave it grasps sized for a 48 mm chord,
  every one of them failing; a relative tolerance cannot: see :data:`KNOWN_TOL` for its
  bound;
* *familiar*: otherwise the nearest map, if its ratio is at most ``max_ratio`` (the
  scaling range), is scaled to the primitive;
* *build*: no stored map of that kind within the scaling range.

A stored map can only serve a primitive it can be grasped like (``max_width``: the widest
chord the gripper closes across): scaling moves the grasps a map has, keeping their
orientations, so a direction the primitive can be approached from (along a box edge, a
cylinder's axis) but the stored one could not -- every chord across it too wide -- would
have no grasp at all: a 2 x 12 x 12 cm plate's map has no grasp approaching its faces,
so a flat 4.5 x 9.3 x 17.6 cm box scaled from it could only be grasped from the sides,
and on a table not at all. Such a stored map is passed over; with none left the
primitive's own map is built.

Every primitive, boxes included, is compared dimension by dimension *by name*, the way
the stored map is then used: a known map serves in its own frame and scaling carries each
named dimension to the same name (``scaling.scale_factors``). Sorting a box's edges here
would call a stored 10 x 6 x 4 cm box the same as the query's 4 x 6 x 10 cm one, and its
map would then be scaled 2.5-fold per edge (or used as is, every grasp in the wrong place).
The planner queries boxes with ascending edges (x <= y <= z), and the maps it builds keep
that order, so its own boxes pair edge for edge; a stored box in another order is only as
near as its named edges are.
Pure: takes the database's index records, reads no file.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum
from typing import Any

from graspsim.errors import InvalidParameterError
from graspsim.primitives import make_primitive
from graspsim.primitives.base import MIN_DIM

__all__ = ["MatchKind", "MatchDecision", "match_entries", "classify_match", "covers", "size_ratio", "KNOWN_TOL"]

#: The relative tolerance of *known* (3 %): a stored map serves a primitive unscaled
#: only when no dimension differs by more than this fraction. Its bound is what scaling
#: would correct that an unscaled map cannot absorb: scaling recentres every grasp on
#: the new chord, the unscaled map keeps the old contacts, so a chord larger by d
#: eats d / 2 of the jaws' approach clearance on each side (5 mm on the HGPL-25:
#: ``GripperSpec.approach_clearance``) -- and a smaller one leaves the contacts d / 2
#: off the surface. At 3 % the widest chord the gripper closes across (110 mm) moves
#: each contact by at most 1.65 mm, a third of that clearance and of the FS maps'
#: 5 mm surface step; the bound ``approach_clearance / widest chord`` is 4.5 %.
#: Anything further is *familiar*: scaled.
KNOWN_TOL = 0.03


class MatchKind(str, Enum):
    KNOWN = "known"  # a stored map within tol on every dimension: used as is
    FAMILIAR = "familiar"  # the nearest stored map of the kind, scaled
    BUILD = "build"  # no stored map of the kind within the scaling range


@dataclass(frozen=True)
class MatchDecision:
    """match: the decision; entry: the stored record serving the primitive (the nearest
    of its kind for BUILD, None when no map of the kind is stored); max_diff: the entry's
    largest per-dimension difference [m] (inf without entry); ratio: its largest
    per-dimension size ratio (>= 1; inf without entry)."""

    match: MatchKind
    entry: dict[str, Any] | None
    max_diff: float
    ratio: float


def size_ratio(v: float, w: float) -> float:
    """The size change (>= 1) between two values [m] of one dimension: ``max(v / w, w /
    v)`` with each value taken as at least :data:`~graspsim.primitives.base.MIN_DIM`.
    Only a cone's radii may be thinner than that (one of them, a pointed top), and below
    it a radius is a point: a cone identified with a top of 0 and a stored one with a
    0.4 mm top differ by less than the primitives resolve, not by an infinite factor
    (which sent every pointed cone to a map build of its own)."""
    a, b = max(float(v), MIN_DIM), max(float(w), MIN_DIM)
    return max(a / b, b / a)


def _dims_of(entry: dict, dims: dict[str, float], kind: str) -> dict[str, float]:
    other = entry.get("dims")
    if not isinstance(other, dict):
        raise InvalidParameterError(f"stored map entry without a dims dict: {entry!r}")
    if set(other) != set(dims):
        raise InvalidParameterError(f"stored {kind} map has dims {sorted(other)}, the query {sorted(dims)}")
    return other


def _pairs(dims: dict[str, float], other: dict[str, float]) -> list[tuple[float, float]]:
    """(query, stored) value pairs, by name (as scaling pairs them)."""
    return [(float(dims[n]), float(other[n])) for n in dims]


def _chords(kind: str, d: dict[str, float]) -> dict[str, float]:
    """The chord widths [m] a grasp of a primitive closes across, by name."""
    if kind == "box":  # by name: scaling keeps a grasp's approach along the same edge
        return {"x": d["x"], "y": d["y"], "z": d["z"]}
    if kind == "sphere":
        return {"d": 2 * d["radius"]}
    if kind == "cylinder":
        return {"d": 2 * d["radius"], "h": d["height"]}
    if kind == "cone":
        return {"d": 2 * min(d["bottom_radius"], d["top_radius"]), "h": d["height"]}
    return {"tube": 2 * d["minor_radius"], "ring": 2 * (d["major_radius"] + d["minor_radius"])}


#: per kind, the families of approach directions, each with the chords a grasp from
#: them may close across (any one will do)
_APPROACHES: dict[str, tuple[tuple[str, ...], ...]] = {
    "box": (("y", "z"), ("x", "z"), ("x", "y")),  # along x, y, z
    "sphere": (("d",),),
    "cylinder": (("d",), ("d", "h")),  # along the axis; from the side
    "cone": (("d",), ("d", "h")),
    "half_toroid": (("tube",), ("tube", "ring")),
}


def covers(kind: str, dims: dict[str, float], stored: dict[str, float], max_width: float) -> bool:
    """Whether a stored primitive's map can serve ``dims``: from every family of
    approach directions the query can be grasped from (some chord <= ``max_width``
    [m]), the stored primitive could be grasped too."""
    q, s = _chords(kind, dims), _chords(kind, stored)
    return all(any(s[c] <= max_width for c in fam) for fam in _APPROACHES[kind]
               if any(q[c] <= max_width for c in fam))


def match_entries(kind: str, dims: dict[str, float], entries: Iterable[dict], *, tol: float,
                  max_ratio: float = math.inf, max_width: float | None = None) -> MatchDecision:
    """The decision for a primitive ``kind`` (normalised name, e.g. ``"half_toroid"``)
    with ``dims`` [m] against index ``entries``; ``tol``: the relative tolerance of
    *known* (a fraction, :data:`KNOWN_TOL`; a known map is never further than
    ``max_ratio`` either) (``{"primitive": kind, "dims": {...}}``;
    other keys are kept in the returned entry). ``max_width`` [m]: the gripper's widest
    chord; stored maps that do not :func:`cover <covers>` the query are passed over
    (None: no check)."""
    if not 0 <= tol < 1:
        raise InvalidParameterError(f"tol is a relative tolerance in [0, 1), got {tol!r}")
    if not max_ratio >= 1:
        raise InvalidParameterError(f"max_ratio must be >= 1, got {max_ratio!r}")
    best = best_known = None  # (ratio, max_diff, entry)
    for e in entries:
        if e.get("primitive") != kind:
            continue
        stored = _dims_of(e, dims, kind)
        if max_width is not None and not covers(kind, dims, stored, max_width):
            continue
        pairs = _pairs(dims, stored)
        r = max([1.0, *(size_ratio(v, w) for v, w in pairs)])
        d = max(abs(v - w) for v, w in pairs)
        if best is None or r < best[0]:
            best = (r, d, e)
        if r <= min(1.0 + tol, max_ratio) and (best_known is None or r < best_known[0]):
            best_known = (r, d, e)
    if best_known is not None:
        r, d, e = best_known
        return MatchDecision(MatchKind.KNOWN, e, d, r)
    if best is None:
        return MatchDecision(MatchKind.BUILD, None, math.inf, math.inf)
    r, d, e = best
    return MatchDecision(MatchKind.FAMILIAR if r <= max_ratio else MatchKind.BUILD, e, d, r)


def classify_match(kind: str, dims: dict[str, float], stored: list[dict], *,
                   tol: float = KNOWN_TOL) -> MatchDecision:
    """:func:`match_entries` for primitive ``kind`` with ``dims`` [m] (validated) against
    index records ``stored``, with no scaling limit: FAMILIAR whenever a map of the kind
    is stored, BUILD when none is."""
    return match_entries(make_primitive(kind, **dims).kind, dims, stored, tol=tol)
