"""Ids of a map's repeated rows: a closing line's contacts recur in every roll and
depth of it (tens of rows), so per-line work is done once per distinct line."""

from __future__ import annotations

import numpy as np

__all__ = ["row_ids", "first_rows"]


def row_ids(*arrays: np.ndarray) -> np.ndarray:
    """(N,) int id of each row's combination of values in ``arrays`` (each (N, ...)),
    compared as float32 bytes; ids number the distinct rows in sorted order. Runs of
    equal consecutive rows are found first (a map's rows come grouped by line, roll and
    depth), then equal runs merged, so the sort is over runs, not rows."""
    if len(arrays[0]) == 0:
        return np.zeros(0, np.int64)
    c = np.concatenate([np.ascontiguousarray(a, np.float32).reshape(len(a), -1) for a in arrays], axis=1)
    new = np.ones(len(c), bool)
    np.any(c[1:] != c[:-1], axis=1, out=new[1:])
    reps = np.ascontiguousarray(c[new])
    inv = np.unique(reps.view(np.dtype((np.void, 4 * c.shape[1]))).ravel(), return_inverse=True)[1].ravel()
    return inv[np.cumsum(new) - 1]


def first_rows(ids: np.ndarray) -> np.ndarray:
    """(K,) the first row of each id 0 .. K - 1 of ``ids`` (N,) (as :func:`row_ids`
    numbers them: every id below the largest occurs)."""
    ids = np.asarray(ids, np.int64)
    first = np.full(int(ids.max()) + 1 if len(ids) else 0, len(ids), np.int64)
    np.minimum.at(first, ids, np.arange(len(ids)))
    return first
