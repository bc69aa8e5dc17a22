"""The viewer's data model (no viser here): what a grasp can be coloured and filtered
by, and which grasps are drawn.

Colour columns: the paper grade and its terms, every per-grasp number stored under
``grasps/qualities/robust`` (robust scores, when the map has them), ``reachable`` (when
an arm's verdicts are recorded: ``graspsim reach``; reachable, first cut only,
unreachable, unchecked), and the outcome of each simulation group
(``grasps/qualities/mujoco``: lift_place, ``mujoco_tug``: tug).
Filters (min grade, outcome, top-K by the colour column) run on all N grasps; at most
``max_drawn`` of the selected grasps are drawn, chosen by a fixed random priority per
grasp (seeded), so a grasp that is drawn stays drawn when a filter is loosened.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.maps.graspmap import GraspabilityMap

__all__ = ["ViewData", "Selection", "OUTCOME_PREFIX", "REACH", "reach_label"]

OUTCOME_PREFIX = "outcome: "
#: the colour column of the map's ``reachable`` verdicts
REACH = "reachable"
_QUALITIES = "grasps/qualities"


def reach_label(value: float) -> str:
    """The words of a ``reachable`` value (:data:`graspsim.maps.graspmap.REACH_VALUES`)."""
    from graspsim.maps.graspmap import REACH_EXACT, REACH_FIRST_CUT, REACH_NONE

    return {REACH_EXACT: "reachable", REACH_FIRST_CUT: "first cut only", REACH_NONE: "unreachable"}.get(
        float(value), "unchecked")


@dataclass(frozen=True)
class Selection:
    """What the GUI asks for. colour: a :meth:`ViewData.colour_names` entry; min_grade:
    only grade > it; outcome: an outcome label (or "any"), of the colour column's
    simulation group if it is an outcome column, else of the first one; top_k: the K best
    by the colour column (0: all); max_drawn: drawn at most."""

    colour: str = "grade"
    min_grade: float = 0.0
    outcome: str = "any"
    top_k: int = 0
    max_drawn: int = 5000


@dataclass(frozen=True, eq=False)
class ViewData:
    """A map and the per-grasp columns the viewer offers. numbers: name -> (N,) float;
    outcomes: simulation group name -> (N,) int (-1: not simulated); info: group ->
    its JSON record (protocol, outcome codes); path: the map file, if read from one."""

    gmap: GraspabilityMap
    numbers: dict[str, np.ndarray] = field(default_factory=dict)
    outcomes: dict[str, np.ndarray] = field(default_factory=dict)
    info: dict[str, dict] = field(default_factory=dict)
    seed: int = 0
    path: Path | None = None

    @classmethod
    def from_map(cls, gmap: GraspabilityMap, path: str | os.PathLike | None = None) -> ViewData:
        """The map's own columns plus, when ``path`` (its file) is given, everything
        stored under ``grasps/qualities`` beside the analytic grade."""
        numbers = {"grade": gmap.grade, "q_fc": gmap.q_fc, "q_st": gmap.q_st, "width": gmap.width}
        if gmap.has_reach:
            numbers[REACH] = gmap.reachable.astype(np.float64)
        outcomes, info = {}, {}
        if path is not None:
            for group, arrays in _stored_groups(Path(path), len(gmap)).items():
                if group == f"{_QUALITIES}/reach":  # the map's own column (REACH)
                    continue
                info[group] = arrays.pop("info", {}) or {}
                if "outcome" in arrays:
                    outcomes[group] = np.asarray(arrays.pop("outcome")).astype(np.int64)
                    if "simulated" in arrays:
                        outcomes[group][~np.asarray(arrays.pop("simulated"), bool)] = -1
                for k, v in arrays.items():
                    if np.issubdtype(v.dtype, np.number) and v.ndim == 1:
                        numbers[f"{group}/{k}"] = v.astype(np.float64)
        return cls(gmap, numbers, outcomes, info, path=None if path is None else Path(path))

    @classmethod
    def from_grasp_file(cls, path: str | os.PathLike) -> ViewData:
        """A third-party grasp file (:func:`graspsim.maps.formats.read_grasp_file`): its
        poses, and its own labels as colour columns ``source/<label>``."""
        from graspsim.maps.formats import read_grasp_file

        gf = read_grasp_file(path)
        data = cls.from_map(gf.gmap)
        for k, v in gf.labels.items():
            if np.asarray(v).ndim == 1:
                data.numbers[f"source/{k}"] = np.asarray(v, np.float64)
        return data

    # ------------------------------------------------------------------ names
    def colour_names(self) -> list[str]:
        """Grade first, robust scores next, then outcomes, then the rest."""
        robust = [k for k in self.numbers if k.startswith(f"{_QUALITIES}/robust/")]
        source = [k for k in self.numbers if k.startswith(("source/", f"{_QUALITIES}/source/"))]
        return (["grade"] + robust + [REACH] * (REACH in self.numbers) + source
                + [OUTCOME_PREFIX + g for g in self.outcomes]
                + [k for k in ("q_fc", "q_st", "width") if k in self.numbers])

    def outcome_labels(self, group: str) -> dict[int, str]:
        """Outcome code -> label of a simulation group (from its stored record)."""
        codes = self.info.get(group, {}).get("outcome_codes")
        if not codes:
            from graspsim.sim.outcomes import TrialOutcome  # no mujoco import

            codes = {o.label: int(o) for o in TrialOutcome}
        return {int(v): k for k, v in codes.items()}

    def outcome_group(self, colour: str) -> str | None:
        if colour.startswith(OUTCOME_PREFIX):
            return colour[len(OUTCOME_PREFIX):]
        return next(iter(self.outcomes), None)

    # ------------------------------------------------------------------ selection
    def _check(self, sel: Selection) -> None:
        if sel.colour not in self.colour_names():
            raise InvalidParameterError(f"unknown colour column {sel.colour!r}; valid: {self.colour_names()}")
        if sel.top_k < 0 or sel.max_drawn < 1:
            raise InvalidParameterError(f"top_k must be >= 0 and max_drawn >= 1, got {sel.top_k}, {sel.max_drawn}")

    def score(self, colour: str) -> np.ndarray:
        """(N,) what top-K ranks by: the column (an outcome column ranks by grade)."""
        return self.gmap.grade if colour.startswith(OUTCOME_PREFIX) else self.numbers[colour]

    def selected(self, sel: Selection) -> np.ndarray:
        """Rows (all N considered) passing the filters, best first when ``top_k``."""
        self._check(sel)
        mask = (self.gmap.grade > sel.min_grade) | np.isnan(self.gmap.grade)  # no grade: not filtered by one
        group = self.outcome_group(sel.colour)
        if sel.outcome != "any" and group is not None:
            codes = {v: k for k, v in self.outcome_labels(group).items()}
            code = -1 if sel.outcome == "not simulated" else codes.get(sel.outcome)
            if code is None:
                raise InvalidParameterError(f"unknown outcome {sel.outcome!r}; valid: {sorted(codes)}")
            mask &= self.outcomes[group] == code
        rows = np.flatnonzero(mask)
        if sel.top_k and len(rows) > sel.top_k:
            s = np.nan_to_num(self.score(sel.colour)[rows], nan=-np.inf)
            part = np.argpartition(-s, sel.top_k - 1)[:sel.top_k]
            rows = rows[part[np.argsort(-s[part], kind="stable")]]
        return rows

    def drawn(self, rows: np.ndarray, max_drawn: int) -> np.ndarray:
        """At most ``max_drawn`` of ``rows``: those of lowest fixed random priority."""
        if len(rows) <= max_drawn:
            return rows
        pri = self._priority[rows]
        return np.sort(rows[np.argpartition(pri, max_drawn - 1)[:max_drawn]])

    @property
    def _priority(self) -> np.ndarray:
        p = self.__dict__.get("_pri")
        if p is None:  # one permutation per map, drawn once
            p = np.random.default_rng(self.seed).permutation(len(self.gmap)).astype(np.int64)
            object.__setattr__(self, "_pri", p)
        return p

    def colours(self, rows: np.ndarray, colour: str) -> tuple[np.ndarray, tuple[float, float]]:
        """(n, 3) uint8 colours of ``rows`` by ``colour`` and the value range used."""
        from graspsim.viewer.glyphs import NOT_SIMULATED_COLOUR, OUTCOME_COLOURS, colormap

        if colour.startswith(OUTCOME_PREFIX):
            group = colour[len(OUTCOME_PREFIX):]
            labels = self.outcome_labels(group)
            lut = np.array([OUTCOME_COLOURS.get(labels.get(c, ""), NOT_SIMULATED_COLOUR)
                            for c in range(max(labels) + 1)] + [NOT_SIMULATED_COLOUR], np.uint8)
            codes = self.outcomes[group][rows]
            return lut[np.where((codes >= 0) & (codes <= max(labels)), codes, -1)], (0.0, 0.0)
        if colour == REACH:
            from graspsim.viewer.glyphs import REACH_COLOURS

            lut = {**REACH_COLOURS, "unchecked": NOT_SIMULATED_COLOUR}
            return np.array([lut[reach_label(v)] for v in self.numbers[REACH][rows]], np.uint8).reshape(-1, 3), \
                (0.0, 0.0)
        v = self.numbers[colour]
        lo, hi = (0.0, 1.0) if colour == "grade" else _finite_range(v)
        return colormap(v[rows], lo, hi), (lo, hi)

    def details(self, row: int) -> dict:
        """Everything known about one grasp, for the click panel."""
        m = self.gmap
        out = {"row": int(row), "grade": float(m.grade[row]), "q_fc": float(m.q_fc[row]),
               "q_st": float(m.q_st[row]), "fc_angle_deg": float(np.degrees(m.fc_angle[row])),
               "stability_distance_mm": 1000 * float(m.stability_distance[row]),
               "width_mm": 1000 * float(m.width[row]), "part": int(m.part[row]),
               "contacts_mm": (1000 * m.contacts[row]).round(2).tolist()}
        for group, codes in self.outcomes.items():
            out[f"{group} outcome"] = self.outcome_labels(group).get(int(codes[row]), "not simulated")
        for k, v in self.numbers.items():
            if "/" in k and np.isfinite(v[row]):
                out[k] = float(v[row])
        if REACH in self.numbers:
            robot = m.meta.extra.get("reach", {}).get("robot", "the arm")
            out[f"reachable by {robot}"] = reach_label(self.numbers[REACH][row])
        return out


def _finite_range(v: np.ndarray) -> tuple[float, float]:
    f = v[np.isfinite(v)]
    return (float(f.min()), float(f.max())) if len(f) else (0.0, 1.0)


def _stored_groups(path: Path, n: int) -> dict[str, dict]:
    """Every group holding datasets under grasps/qualities, except the analytic grade:
    group path -> its per-grasp arrays of length ``n`` (and ``info``, decoded JSON)."""
    import json

    import h5py

    out: dict[str, dict] = {}

    def visit(name: str, obj) -> None:
        if not isinstance(obj, h5py.Dataset) or name.startswith("analytic/"):
            return
        group, _, key = f"{_QUALITIES}/{name}".rpartition("/")
        if key == "info":
            out.setdefault(group, {})["info"] = json.loads(obj.asstr()[()] if obj.dtype.kind in "OS" else "{}")
        elif obj.ndim == 1 and len(obj) == n:
            out.setdefault(group, {})[key] = obj[()]

    with h5py.File(path, "r") as f:
        if _QUALITIES in f:
            f[_QUALITIES].visititems(visit)
    return out
