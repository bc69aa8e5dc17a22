"""The graspability map: one row per grasp, columnar arrays plus metadata (docs/design.md §6).

Poses are wrist poses in the object frame (origin at the centre of mass). Geometry is
stored as float32 (sub-micrometre at object scale), which halves the memory of the
million-grasp maps the surface-to-voxel method produces.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from graspsim.errors import InvalidMapError, InvalidParameterError
from graspsim.grades.paper import QualityModel
from graspsim.grippers.spec import GripperSpec
from graspsim.transforms import quat_to_matrix

if TYPE_CHECKING:
    from graspsim.maps.map_config import MapConfig

__all__ = ["GraspabilityMap", "MapMeta", "Placement", "COLUMNS", "OPTIONAL_COLUMNS", "REACH_EXACT",
           "REACH_FIRST_CUT", "REACH_NONE", "REACH_VALUES"]

# column name -> (trailing shape, dtype)
COLUMNS: dict[str, tuple[tuple[int, ...], type]] = {
    "wrist_position": ((3,), np.float32),
    "wrist_quat": ((4,), np.float32),
    "grasp_point": ((3,), np.float32),
    "contacts": ((2, 3), np.float32),
    "normals": ((2, 3), np.float32),
    "width": ((), np.float32),
    "fc_angle": ((), np.float32),
    "q_fc": ((), np.float32),
    "stability_distance": ((), np.float32),
    "q_st": ((), np.float32),
    "grade": ((), np.float32),
    "part": ((), np.int16),
}
#: Columns a map may lack (NaN: not computed): the robust scores of
#: :mod:`graspsim.maps.robust` -- clearance to the observed points [m], the fraction of
#: pose perturbations that stay feasible, the robust score (expected success) and the
#: extra pad gap per side it assumes [m] (0 unless ``RobustConfig.openings`` says more);
#: and ``reachable``, whether an arm at a base reaches the grasp (:data:`REACH_VALUES`;
#: computed by :func:`graspsim.robots.mark_reach`, the arm and base in
#: ``meta.extra["reach"]``; here it is plain data).
OPTIONAL_COLUMNS: dict[str, tuple[tuple[int, ...], type]] = {
    "clearance": ((), np.float32),
    "robust_feasible": ((), np.float32),
    "robust": ((), np.float32),
    "robust_extra_opening": ((), np.float32),
    "reachable": ((), np.float32),
}
#: ``reachable`` values: the arm's exact check planned the grasp (IK of the grasp, its
#: pre-grasp, the approach line, the lift, the move from home, all collision-free);
#: only the first cut (the arm's capability map) let it through; unreachable (refused by
#: either). NaN: not checked.
REACH_EXACT, REACH_FIRST_CUT, REACH_NONE = 1.0, 0.5, 0.0
REACH_VALUES = (REACH_EXACT, REACH_FIRST_CUT, REACH_NONE)


@dataclass(frozen=True)
class MapMeta:
    """What a map is of and how it was made.

    object: description dict -- ``{"primitive": kind, "dims": {...}}``, a compound
        (``"parts"``, ``"poses"``) or a mesh (``"file"``, ``"scale"``) -- plus
        ``"com"`` (3,) and ``"mass"`` [kg].
    gripper: ``GripperSpec.to_dict()``.
    quality: ``QualityModel.to_dict()`` plus ``"d_ref"`` [m], the stability reference used.
    resolution: surface_step [m], rotation_step [rad], depth_step [m], closing_cone [rad].
    method: ``"surface_to_voxel"``, ``"scaled/quality"``, ``"combined"``, ...
    timing: seconds per stage; extra: anything else (source cloud, T_cloud_obj, ...).
    """

    object: dict
    gripper: dict
    quality: dict
    resolution: dict
    method: str
    timing: dict = field(default_factory=dict)
    version: str = ""
    extra: dict = field(default_factory=dict)

    # Typed views of the records, each parsed once (the dicts are what the file holds).
    @cached_property
    def gripper_spec(self) -> GripperSpec:
        """The gripper the map was made for."""
        if not self.gripper:
            raise InvalidMapError("the map records no gripper (meta.gripper is empty)")
        return GripperSpec.from_dict(self.gripper)

    @cached_property
    def quality_model(self) -> QualityModel:
        """The paper-grade model behind ``quality`` (see :meth:`QualityModel.from_meta`)."""
        return QualityModel.from_meta(self.quality)

    @cached_property
    def map_config(self) -> MapConfig:
        """The generation settings recorded in ``resolution`` (defaults for missing ones)."""
        from graspsim.maps.map_config import MapConfig

        return MapConfig(**{k: v for k, v in self.resolution.items() if k in MapConfig.__dataclass_fields__})

    @cached_property
    def shape(self):
        """The object as a :class:`~graspsim.primitives.Primitive` or
        :class:`~graspsim.primitives.Compound` (PrimitiveError for a mesh object)."""
        from graspsim.primitives import shape_from_dict

        return shape_from_dict(self.object)

    @property
    def threshold(self) -> float:
        """Grade above which a grasp is accepted (the quality model's default if unrecorded)."""
        return float(self.quality.get("threshold", QualityModel.threshold))

    @property
    def surface_step(self) -> float:
        """[m] (the map settings' default if unrecorded)."""
        from graspsim.maps.map_config import MapConfig

        return float(self.resolution.get("surface_step", MapConfig.surface_step))

    @property
    def rotation_step(self) -> float:
        """[rad] (the map settings' default if unrecorded)."""
        from graspsim.maps.map_config import MapConfig

        return float(self.resolution.get("rotation_step", MapConfig.rotation_step))

    @cached_property
    def placement(self) -> Placement | None:
        """Where an adapted map's object was seen (None for other maps)."""
        return Placement.from_extra(self.extra)

    @cached_property
    def gripper_adaptation(self) -> GripperAdaptation | None:
        """How a map carried to another gripper was made (None for other maps)."""
        return GripperAdaptation.from_extra(self.extra)


@dataclass(frozen=True, eq=False)
class Placement:
    """An adapted map's object in the sensor's frame: what the planner hands the
    simulation. T_cloud_obj: (4, 4) the object frame in the cloud's frame; table: the
    planner's support-plane record (``TablePlane.to_dict()`` with the resolved height
    [m], and ``dropped``: the poses it removed) or None. Stored in ``MapMeta.extra``."""

    T_cloud_obj: np.ndarray
    table: dict | None = None

    def to_extra(self) -> dict:
        """The ``MapMeta.extra`` entries that record it."""
        out = {"T_cloud_obj": np.asarray(self.T_cloud_obj, float).tolist()}
        if self.table is not None:
            out["table"] = self.table
        return out

    @classmethod
    def from_extra(cls, extra: dict) -> Placement | None:
        T = extra.get("T_cloud_obj")
        if T is None:
            return None
        return cls(np.asarray(T, float).reshape(4, 4), extra.get("table") or None)

    @property
    def up(self) -> np.ndarray | None:
        """(3,) the table's normal in the object frame, or None without a table."""
        if self.table is None:
            return None
        return self.T_cloud_obj[:3, :3].T @ np.asarray(self.table["normal"], float)


@dataclass(frozen=True)
class GripperAdaptation:
    """A map carried to another gripper (:func:`graspsim.maps.regrip.adapt_to_gripper`):
    source_grasps: the source map's grasps above ``source_min_grade``; fit_opening: those
    the new gripper's opening spans; quality_pose: carried at the same pad place;
    feasibility_pose: carried with the wrist kept. Stored in ``MapMeta.extra``."""

    source_grasps: int
    fit_opening: int
    quality_pose: int
    feasibility_pose: int
    source_min_grade: float

    def to_dict(self) -> dict:
        return {"source_grasps": self.source_grasps, "fit_opening": self.fit_opening,
                "quality_pose": self.quality_pose, "feasibility_pose": self.feasibility_pose,
                "source_min_grade": self.source_min_grade}

    def to_extra(self) -> dict:
        """The ``MapMeta.extra`` entry that records it."""
        return {"gripper_adaptation": self.to_dict()}

    @classmethod
    def from_extra(cls, extra: dict) -> GripperAdaptation | None:
        d = extra.get("gripper_adaptation")
        return None if d is None else cls(**{k: d[k] for k in cls.__dataclass_fields__})


@dataclass(frozen=True, eq=False)
class GraspabilityMap:
    """Columnar grasp table. Shapes: wrist_position (N, 3), wrist_quat (N, 4) w,x,y,z,
    grasp_point (N, 3), contacts (N, 2, 3), normals (N, 2, 3) outward, width (N,) contact
    distance [m], fc_angle (N,) [rad], q_fc, stability_distance [m], q_st, grade (N,),
    part (N,) part id (0 for single primitives). All object frame, metres."""

    wrist_position: np.ndarray
    wrist_quat: np.ndarray
    grasp_point: np.ndarray
    contacts: np.ndarray
    normals: np.ndarray
    width: np.ndarray
    fc_angle: np.ndarray
    q_fc: np.ndarray
    stability_distance: np.ndarray
    q_st: np.ndarray
    grade: np.ndarray
    part: np.ndarray
    meta: MapMeta
    clearance: np.ndarray | None = None
    robust_feasible: np.ndarray | None = None
    robust: np.ndarray | None = None
    robust_extra_opening: np.ndarray | None = None
    reachable: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(np.asarray(self.wrist_position))  # the first column sets the row count
        for name, (shape, dtype) in {**COLUMNS, **OPTIONAL_COLUMNS}.items():
            v = getattr(self, name)
            a = np.full((n, *shape), np.nan, dtype) if v is None else np.ascontiguousarray(v, dtype=dtype)
            if a.shape != (n, *shape):
                raise InvalidParameterError(
                    f"map column {name} has shape {a.shape}, expected {(n, *shape)}"
                )
            object.__setattr__(self, name, a)

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return len(self.grade)

    @classmethod
    def empty(cls, meta: MapMeta) -> GraspabilityMap:
        cols = {k: np.zeros((0, *s), dtype=d) for k, (s, d) in COLUMNS.items()}
        return cls(**cols, meta=meta)

    def columns(self) -> dict[str, np.ndarray]:
        """Every column, the optional (robust) ones included."""
        return {k: getattr(self, k) for k in (*COLUMNS, *OPTIONAL_COLUMNS)}

    @property
    def threshold(self) -> float:
        return self.meta.threshold

    @property
    def accepted(self) -> np.ndarray:
        """(N,) bool: grade above the quality model's threshold (paper: 0.7)."""
        return self.grade > self.threshold

    @property
    def T_obj_wrist(self) -> np.ndarray:
        """(N, 4, 4) wrist poses in the object frame (float64)."""
        return self.wrist_transforms()

    def wrist_transforms(self, dtype=np.float64) -> np.ndarray:
        """(N, 4, 4) wrist poses in the object frame, built in ``dtype`` (float32 for
        files: no float64 (N, 4, 4) detour)."""
        T = np.zeros((len(self), 4, 4), dtype)
        T[:, :3, :3] = quat_to_matrix(self.wrist_quat)
        T[:, :3, 3] = self.wrist_position
        T[:, 3, 3] = 1.0
        return T

    @property
    def approach(self) -> np.ndarray:
        """(N, 3) approach directions (wrist z axes) in the object frame."""
        return quat_to_matrix(self.wrist_quat)[:, :, 2]

    # ------------------------------------------------------------------ selection
    def select(self, index) -> GraspabilityMap:
        """Rows by boolean mask or integer indices (order kept)."""
        index = np.asarray(index)
        if index.ndim == 1 and index.dtype == bool and len(index) == len(self):
            index = np.flatnonzero(index)  # once, not once per column
        if index.ndim == 1 and index.dtype.kind in "iu":  # np.take: fancy indexing's rows, faster
            return replace(self, **{k: np.take(v, index, axis=0) for k, v in self.columns().items()})
        return replace(self, **{k: v[index] for k, v in self.columns().items()})

    def above(self, min_grade: float) -> np.ndarray:
        """(N,) bool: grade > ``min_grade`` (any float: one beyond float32's range, e.g. a
        user's 1e308, compares as the edge of the grades' [0, 1] range, not as an overflow)."""
        return self.grade > np.float32(np.clip(float(min_grade), -2.0, 2.0))

    def filter(self, *, min_grade: float | None = None, part: int | None = None,
               accepted: bool | None = None) -> GraspabilityMap:
        m = np.ones(len(self), bool)
        if min_grade is not None:
            m &= self.above(min_grade)
        if part is not None:
            m &= self.part == part
        if accepted is not None:
            m &= self.accepted == accepted
        return self.select(m)

    @property
    def has_robust(self) -> bool:
        """Whether any row has a robust score (:mod:`graspsim.maps.robust`)."""
        return bool(np.isfinite(self.robust).any())

    @property
    def has_reach(self) -> bool:
        """Whether any row has a reachability verdict (the ``reachable`` column)."""
        return bool(np.isfinite(self.reachable).any())

    def reach_groups(self) -> np.ndarray | None:
        """(N,) int the rank the ``reachable`` column gives each row, lower first: 0 the
        arm's exact check planned it, 1 only its first cut let it through, 2 unchecked,
        3 unreachable; None for a map without the column (all NaN)."""
        if not self.has_reach:
            return None
        r = self.reachable
        return np.select([r == REACH_EXACT, r == REACH_FIRST_CUT, r == REACH_NONE], [0, 1, 3], default=2)

    def ranked(self, rank: str = "robust") -> GraspabilityMap:
        """The map ordered best first: ``"robust"`` (default): rows with a robust score by
        it, then the others by grade -- the grade alone for a map without robust scores;
        ``"paper"``: by the paper's grade (stable order among ties)."""
        from graspsim.maps.robust import ranking

        return self.select(ranking(self, rank))

    def top_k(self, k: int, rank: str = "robust", *,
              separation: tuple[float, float] | None = None) -> GraspabilityMap:
        """The k best grasps, best first, by ``rank`` (see :meth:`ranked`); with
        ``separation`` = (distance [m], angle [rad]), each at least that far from every
        better one kept (non-maximum suppression: :mod:`graspsim.maps.separation`)."""
        if k < 0:
            raise InvalidParameterError(f"k must be >= 0, got {k}")
        from graspsim.maps.robust import ranking

        order = ranking(self, rank)
        if separation is None:
            return self.select(order[:k])
        from graspsim.maps.separation import separated_rows

        return self.select(separated_rows(self.grasp_point, self.wrist_quat, order, k,
                                          distance=separation[0], angle=separation[1]))

    def sample_uniform_surface(
        self, n: int, rng: np.random.Generator, *, cell: float | None = None
    ) -> GraspabilityMap:
        """``n`` grasps spread uniformly over the object (see :meth:`uniform_surface_rows`)."""
        return self.select(self.uniform_surface_rows(n, rng, cell=cell))

    def uniform_surface_rows(self, n: int, rng: np.random.Generator, *,
                             cell: float | None = None) -> np.ndarray:
        """Row indices of ``n`` grasps spread uniformly over the object: grasp contacts
        are binned into surface cells of size ``cell`` (default: the map's surface
        step), cells drawn without replacement, then one grasp per cell (as the paper
        drew its 15 test grasps "uniformly distributed about the object")."""
        if n <= 0 or len(self) == 0:
            return np.zeros(0, int)
        cell = float(cell or self.meta.surface_step)
        c = self.contacts[:, 0]
        where = np.where(np.isfinite(c).all(axis=1)[:, None], c, self.grasp_point)  # no contacts: the TCP
        key = np.floor(where / cell).astype(np.int64)
        _, inverse = np.unique(key, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        n_cells = inverse.max() + 1
        chosen_cells = rng.permutation(n_cells)[: min(n, n_cells)]
        perm = rng.permutation(len(self))
        first = np.full(n_cells, -1)
        first[inverse[perm[::-1]]] = perm[::-1]  # a random member of each cell
        picks = first[chosen_cells]
        if len(picks) < n:  # fewer cells than asked: fill with other random grasps
            rest = np.setdiff1d(np.arange(len(self)), picks)
            picks = np.concatenate([picks, rng.choice(rest, min(n - len(picks), len(rest)), replace=False)])
        return picks

    @staticmethod
    def concat(maps: list[GraspabilityMap], meta: MapMeta | None = None) -> GraspabilityMap:
        """Rows of several maps (of the same object frame) in one map."""
        if not maps:
            raise InvalidParameterError("concat needs at least one map")
        cols = {k: np.concatenate([getattr(m, k) for m in maps]) for k in (*COLUMNS, *OPTIONAL_COLUMNS)}
        return GraspabilityMap(**cols, meta=meta or maps[0].meta)

    def with_meta(self, **changes: Any) -> GraspabilityMap:
        return replace(self, meta=replace(self.meta, **changes))

    def summary(self) -> dict:
        """Counts and grade statistics; a map without grades (imported from a third-party
        grasp file: NaN grades) has ``graded`` 0 and no grade mean / max."""
        g = self.grade[np.isfinite(self.grade)]
        return {
            "object": self.meta.object,
            "method": self.meta.method,
            "grasps": int(len(self)),
            "graded": int(len(g)),
            "accepted": int(self.accepted.sum()),
            "threshold": self.threshold,
            "grade_mean": float(g.mean()) if len(g) else None,
            "grade_max": float(g.max()) if len(g) else None,
            "parts": int(self.part.max() + 1) if len(self) else 0,
        }

    def __repr__(self) -> str:
        return (f"GraspabilityMap({len(self)} grasps, {int(self.accepted.sum())} accepted, "
                f"method={self.meta.method!r}, object={self.meta.object.get('primitive')})")
