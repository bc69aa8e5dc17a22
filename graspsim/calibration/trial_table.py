"""The trial table: one row per simulated grasp, columnar, with its provenance.

Columns (all (N,)): ``case`` (str, object + map), ``group`` (str, the object: the unit
held out in cross-validation), ``kind`` (str, map kind: fs / scaled / adapted),
``condition`` (str), ``row`` (map row), ``weight`` (inverse inclusion probability),
``outcome`` (int8 :class:`graspsim.sim.TrialOutcome` code), ``success`` (bool), the map's
quality columns (``grade``, ``fc_angle`` [rad], ``q_fc``, ``stability_distance`` [m],
``q_st``, ``width`` [m]), ``in_default_cone`` (bool: the grasp is also in a default
22 deg map), grade-model features (``f_<name>``), other grades (``grade_<name>``) and
the trials' motion metrics (``m_<name>``). Stored as .npz plus a JSON ``meta``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim.errors import GraspsimError, InvalidParameterError

__all__ = ["TrialTable"]


@dataclass(frozen=True, eq=False)
class TrialTable:
    """Columns {name: (N,) array} and ``meta`` (JSON-able: config, versions)."""

    columns: dict
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        lens = {k: len(v) for k, v in self.columns.items()}
        if len(set(lens.values())) > 1:
            raise InvalidParameterError(f"trial table columns differ in length: {lens}")

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise InvalidParameterError(
                f"trial table has no column {name!r}; it has {sorted(self.columns)}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    @property
    def feasible(self) -> np.ndarray:
        """(N,) bool: the trial started without collision (START_COLLISION excluded)."""
        from graspsim.sim.outcomes import TrialOutcome

        return self["outcome"] != TrialOutcome.START_COLLISION

    def select(self, mask) -> TrialTable:
        m = np.asarray(mask)
        return TrialTable({k: v[m] for k, v in self.columns.items()}, self.meta)

    def with_columns(self, **cols) -> TrialTable:
        return TrialTable({**self.columns, **{k: np.asarray(v) for k, v in cols.items()}}, self.meta)

    @staticmethod
    def concat(tables: list[TrialTable], meta: dict | None = None) -> TrialTable:
        """Rows of several tables (columns missing in some are filled with NaN / "")."""
        tables = [t for t in tables if len(t)]
        if not tables:
            return TrialTable({}, meta or {})
        names = list(dict.fromkeys(k for t in tables for k in t.columns))
        cols = {}
        for k in names:
            parts = []
            for t in tables:
                if k in t.columns:
                    parts.append(t.columns[k])
                else:
                    ref = next(tt.columns[k] for tt in tables if k in tt.columns)
                    fill = "" if ref.dtype.kind in "US" else np.nan
                    parts.append(np.full(len(t), fill, dtype=ref.dtype if ref.dtype.kind in "USf" else float))
            cols[k] = np.concatenate(parts)
        return TrialTable(cols, meta if meta is not None else tables[0].meta)

    def save(self, path: str | os.PathLike) -> Path:
        """Write ``path`` (.npz) atomically; meta as JSON inside."""
        import io

        path = Path(path)
        buf = io.BytesIO()
        np.savez_compressed(buf, __meta__=np.array(json.dumps(self.meta, default=_json_default)),
                            **self.columns)
        with atomic_path(path, GraspsimError) as tmp:
            tmp.write_bytes(buf.getvalue())
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> TrialTable:
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["__meta__"])) if "__meta__" in z else {}
                cols = {k: z[k] for k in z.files if k != "__meta__"}
        except (OSError, ValueError) as err:
            raise InvalidParameterError(f"cannot read trial table {path}: {err}") from err
        return cls(cols, meta)


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
