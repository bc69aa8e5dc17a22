"""A cloud made ready for identification: units, plausibility, degeneracy, density.

* :func:`to_metres` converts a cloud given in millimetres or centimetres;
* :func:`check_extent` refuses a cloud too large to be one graspable object in
  metres -- almost always a cloud in millimetres or centimetres -- and names the
  likely unit (used by :func:`~graspsim.perception.cloud_input.check_cloud`, so by the file
  reader, :func:`~graspsim.perception.identify.identify`, the planner and the CLI);
* :func:`check_solid` refuses a collinear or planar cloud: no solid primitive has a
  shape to fit there (it would come out as a zero-radius cylinder or a flat box);
* :func:`canonical_points` makes a cloud's coordinates canonical (float32, then the
  1 µm grid), so the same points saved as float32 PLY or float64 NPY read the same;
* :func:`voxel_downsample` thins a dense cloud to the resolution identification
  needs: one input point per voxel, the voxel chosen from the cloud's extent so that
  at most ``max_points`` remain.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from graspsim.errors import IdentificationError, InvalidParameterError, PointCloudError
from graspsim.primitives.base import MIN_DIM

__all__ = ["UNITS", "MAX_EXTENT", "QUANTUM", "canonical_points", "Downsampling", "as_coordinates", "to_metres",
           "check_extent",
           "check_solid", "voxel_downsample", "voxel_keep", "distinct_rows", "first_of_each_row"]

#: Length of one coordinate unit in metres.
UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}

#: Largest extent of a cloud taken as one object in metres [m]: the default gripper
#: spans 12 cm; nothing this wide is one graspable object.
MAX_EXTENT = 2.0


#: The grid [m] :func:`canonical_points` puts coordinates on: far below any sensor's
#: noise (0.1 mm and more), far above float32's rounding of an object's coordinates.
QUANTUM = 1e-6


def canonical_points(points: np.ndarray) -> np.ndarray:
    """(N, 3) float64: the coordinates rounded to float32 and then to the nearest
    :data:`QUANTUM` (1 µm). The same points stored in float32 (a PLY, a PCD) and in
    float64 (an NPY) come out bit for bit equal, so they plan the same: identification
    fits models by random samples and thresholds, and a coordinate one float32 ulp
    away can tip a threshold and with it the whole decomposition. Idempotent; the
    change is at most 0.5 µm + float32 rounding per coordinate."""
    p = np.asarray(points)
    return np.round(p.astype(np.float32).astype(np.float64) / QUANTUM) * QUANTUM


def distinct_rows(a: np.ndarray) -> np.ndarray:
    """The distinct rows of a (N, 3) float array in ascending lexicographic order, rows
    equal as numbers counted once: ``np.unique(a, axis=0)`` of a finite array, without
    its sort of structured rows (a few times slower)."""
    s = a[np.lexsort((a[:, 2], a[:, 1], a[:, 0]))]
    keep = np.ones(len(s), bool)
    keep[1:] = np.any(s[1:] != s[:-1], axis=1)
    return s[keep]


def first_of_each_row(keys: np.ndarray) -> np.ndarray:
    """Ascending indices (M,) of the first occurrence of each distinct row of integer
    keys (N, 3) (e.g. voxel coordinates): ``np.sort(np.unique(keys, axis=0,
    return_index=True)[1])``, on one packed integer per row where the ranges allow."""
    if not len(keys):
        return np.zeros(0, np.int64)
    k = keys - keys.min(axis=0)
    n = k.max(axis=0) + 1
    if float(n[0]) * float(n[1]) * float(n[2]) >= 2.0**62:  # would not pack: the slow way
        return np.sort(np.unique(keys, axis=0, return_index=True)[1])
    return np.sort(np.unique((k[:, 0] * n[1] + k[:, 1]) * n[2] + k[:, 2], return_index=True)[1])


def as_coordinates(points) -> np.ndarray:
    """``points`` as a float64 array, or :class:`PointCloudError` when they are not
    real numbers (complex, boolean, ragged, text that is no number, overflowing)."""
    try:
        a = np.asarray(points)
        if a.dtype.kind in "bcmMV":  # booleans, complex, times, raw or structured records
            raise TypeError(f"{a.dtype} values are not coordinates")
        return a.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError) as err:
        raise PointCloudError(f"points must be a real-valued (N, 3) array: {err}") from err


def to_metres(points: np.ndarray, units: str = "m") -> np.ndarray:
    """``points`` (N, 3) in ``units`` ("m", "cm" or "mm") as metres (float64)."""
    scale = UNITS.get(str(units).lower())
    if scale is None:
        raise InvalidParameterError(f"unknown length unit {units!r}; valid: {sorted(UNITS)}")
    p = as_coordinates(points)
    return p * scale if scale != 1.0 else p


def _robust_ranges(points: np.ndarray, axes: np.ndarray | None = None) -> np.ndarray:
    """(3,) extent of the points along each axis (rows of ``axes``; default x, y, z),
    between the 0.5 % and 99.5 % quantiles (a few stray points do not count)."""
    q = points if axes is None else points @ axes.T
    lo, hi = np.quantile(q, [0.005, 0.995], axis=0)
    return hi - lo


def check_extent(points: np.ndarray, *, max_extent: float = MAX_EXTENT, what: str = "one graspable object"
                 ) -> None:
    """Raise :class:`PointCloudError` when the cloud (N, 3) is wider than
    ``max_extent`` metres: coordinates in millimetres or centimetres read as metres
    (``what`` the cloud should be, for the message)."""
    width = float(np.max(_robust_ranges(points)))
    if width <= max_extent:
        return
    names = {"mm": "millimetres", "cm": "centimetres"}
    units = [u for u in ("mm", "cm") if width * UNITS[u] <= max_extent]
    if units:
        hint = (f"is it in {' or '.join(f'{names[u]} ({width:.4g} {u})' for u in units)}? convert with "
                f"--units {'|'.join(units)} (Python: read_point_cloud(..., units=...) or "
                "graspsim.perception.to_metres)")
    else:
        hint = "is it several objects, or in another unit? segment or convert it first"
    raise PointCloudError(
        f"the cloud is {width:.4g} units across, implausible in metres ({what} is at most "
        f"{max_extent:g} m); {hint}")


def check_solid(points: np.ndarray, *, floor: float = MIN_DIM) -> None:
    """Raise :class:`IdentificationError` when the cloud (N, 3) [m] is thinner than
    ``floor`` across its principal axes: tiny (three thin directions: probably not in
    metres), collinear (two) or planar (one). No solid primitive of at least ``floor``
    in every dimension fits it."""
    c = points - points.mean(axis=0)
    _, vecs = np.linalg.eigh(c.T @ c)
    ext = _robust_ranges(c, vecs[:, ::-1].T)  # largest principal direction first
    mm = lambda x: f"{x * 1000:.3g} mm" if x >= 1e-5 else "0 mm"  # noqa: E731
    if ext[0] < floor:
        raise IdentificationError(
            f"the cloud is only {mm(ext[0])} across, smaller than any solid primitive (every dimension >= "
            f"{mm(floor)}); are its coordinates in metres? (--units m|cm|mm, Python: to_metres)")
    if ext[1] < floor:
        raise IdentificationError(
            f"the cloud is collinear: its points lie within {mm(ext[1])} of a line {mm(ext[0])} long; no "
            f"solid primitive (every dimension >= {mm(floor)}) can be identified from it")
    if ext[2] < floor:
        raise IdentificationError(
            f"the cloud is planar: its points lie within {mm(ext[2])} of a plane ({mm(ext[0])} x "
            f"{mm(ext[1])}); no solid primitive (every dimension >= {mm(floor)}) can be identified "
            "from it (one flat face seen head-on has no depth)")


@dataclass(frozen=True)
class Downsampling:
    """input_points: points given; used_points: points identification ran on; voxel:
    the voxel edge [m] (one input point kept per occupied voxel)."""

    input_points: int
    used_points: int
    voxel: float

    def to_dict(self) -> dict:
        return asdict(self)


def _voxel_keys(points: np.ndarray, lo: np.ndarray, voxel: float) -> np.ndarray:
    q = np.floor((points - lo) / voxel).astype(np.int64)
    n = q.max(axis=0) + 1
    return (q[:, 0] * n[1] + q[:, 1]) * n[2] + q[:, 2]


def voxel_keep(points: np.ndarray, voxel: float) -> np.ndarray:
    """Indices (M,) into ``points`` (N, 3) [m] of one point per occupied voxel of edge
    ``voxel`` [m] (the first in input order), ascending."""
    if not (math.isfinite(voxel) and voxel > 0):
        raise InvalidParameterError(f"voxel must be > 0 m, got {voxel!r}")
    if not len(points):
        return np.zeros(0, np.int64)
    _, kept = np.unique(_voxel_keys(points, points.min(axis=0), voxel), return_index=True)
    return np.sort(kept)


def voxel_downsample(points: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray, Downsampling]:
    """Thin ``points`` (N, 3) [m] to at most ``max_points``: one point per voxel (the
    first in input order), the voxel edge chosen from the cloud's extent and refined on
    the occupied-voxel count (a surface's count falls as the voxel edge squared).

    Returns (kept (M,) indices into ``points`` in voxel order, voxel (N,) index into
    ``kept`` of each input point's voxel, the :class:`Downsampling` record)."""
    if max_points < 1:
        raise InvalidParameterError(f"max_points must be >= 1, got {max_points!r}")
    lo = points.min(axis=0)
    a, b, c = np.maximum(np.ptp(points, axis=0), 1e-9)
    voxel = max(math.sqrt(2.0 * (a * b + b * c + c * a) / max_points), float(max(a, b, c)) / 1e6)
    count = lambda v: len(np.unique(_voxel_keys(points, lo, v)))  # noqa: E731
    n = count(voxel)
    for _ in range(4):  # towards 80 % of the cap (a surface: n ~ voxel^-2)
        if 0.6 * max_points <= n <= max_points:
            break
        voxel *= math.sqrt(n / (0.8 * max_points))
        n = count(voxel)
    while n > max_points:
        voxel *= 1.1
        n = count(voxel)
    _, kept, inverse = np.unique(_voxel_keys(points, lo, voxel), return_index=True, return_inverse=True)
    return kept, inverse.ravel(), Downsampling(len(points), len(kept), float(voxel))
