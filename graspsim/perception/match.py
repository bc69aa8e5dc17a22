"""The known / familiar decision, kept here for its older import path.

Matching against stored maps is decided in one place, :mod:`graspsim.maps.match`
(through :meth:`graspsim.maps.database.MapDatabase.match`); this module re-exports its
types and offers :func:`classify_match` over plain index records.
"""

from __future__ import annotations

from graspsim.maps.match import KNOWN_TOL, MatchDecision, MatchKind, match_entries
from graspsim.primitives import make_primitive

__all__ = ["MatchKind", "MatchDecision", "classify_match"]


def classify_match(kind: str, dims: dict[str, float], stored: list[dict], *,
                   tol: float = KNOWN_TOL) -> MatchDecision:
    """:func:`graspsim.maps.match.match_entries` for primitive ``kind`` with ``dims``
    [m] (validated) against index records ``stored`` (``tol`` relative), with no scaling limit: FAMILIAR
    whenever a map of the kind is stored, BUILD when none is."""
    return match_entries(make_primitive(kind, **dims).kind, dims, stored, tol=tol)
