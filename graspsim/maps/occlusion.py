"""Occluded space of a single-view cloud: where a finger may meet what was not seen.

A cloud seen from one viewpoint shows the surfaces that face it. The space behind them,
along the sensor's rays, is unknown: a mug's handle turned away from the camera is
there, unobserved, and a finger put there may start in collision. The space a ray
passed through before it met a surface (or the table) is known to be free.

:class:`ViewDepth` turns a cloud and its viewpoint (both in one frame) into a depth
image in a pinhole projection about the direction from the viewpoint to the cloud's
centroid: per pixel the nearest observed range, eroded by a pixel (the minimum over
3 x 3) so the gaps between neighbouring points do not read as seen-through.
:meth:`ViewDepth.occluded` tells, for any points, whether they lie more than
``tolerance`` behind the observed surface along their ray. :func:`finger_occlusion`
is the fraction of a gripper's finger volume (fingers at a pad gap) in occluded space,
per wrist pose -- the robust score's occlusion term (:mod:`graspsim.maps.robust`).
:func:`unseen_clearance` is how near those unseen finger samples come to what is known
of the object (its observed points, its fitted primitives): the robust score's
unseen margin (``RobustConfig.unseen_margin``). :func:`felt_volume` is what a grasp that
started in collision tells of that space: the finger volume at its pose the camera did not
see, which something there filled (a scene's next plans keep clear of it).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.ndimage import minimum_filter

from graspsim.errors import InvalidParameterError
from graspsim.geometry.spacing import median_spacing
from graspsim.grippers.spec import GripperSpec

__all__ = ["ViewDepth", "finger_samples", "felt_volume", "finger_occlusion", "unseen_clearance", "shadow_depth",
           "check_viewpoint", "MAX_VIEWPOINT", "FELT_STEP"]

_MAX_PIXELS = 1024  # per image side (memory bound)
_PER_AXIS = (2, 3, 8)  # finger samples along the finger box's x, y, z


#: Farthest a viewpoint may lie from the cloud frame's origin [m]: a table-top camera is
#: within a few metres; beyond this the coordinates are not metres (or not a position).
MAX_VIEWPOINT = 100.0


def check_viewpoint(viewpoint) -> np.ndarray | None:
    """``viewpoint`` as a (3,) float array (None stays None), or an
    :class:`InvalidParameterError` naming what is valid: 3 finite coordinates [m] within
    :data:`MAX_VIEWPOINT` of the origin."""
    if viewpoint is None:
        return None
    try:
        v = np.asarray(viewpoint, float).reshape(-1)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidParameterError(f"viewpoint must be 3 finite coordinates [m] (x, y, z of the camera), "
                                    f"got {viewpoint!r}")
    if float(np.max(np.abs(v))) > MAX_VIEWPOINT:
        raise InvalidParameterError(f"viewpoint {v.tolist()} lies more than {MAX_VIEWPOINT:g} m from the cloud's "
                                    "origin: give the camera's position in metres, in the cloud's frame")
    return v


class ViewDepth:
    """The depth image of ``points`` (M, 3) seen from ``viewpoint`` (3,), one frame [m].
    tolerance [m]: how far behind the observed surface a point must lie to count as
    occluded (default: 2 point spacings, at least 2 mm: fingers touching the surface
    are not occluded). spacing [m]: the points' median spacing when the caller knows it
    (:func:`~graspsim.geometry.spacing.median_spacing` of these points, or of the same
    points in another frame: the same up to rounding); None: measured here. Its
    ``spacing`` attribute: the spacing used (at least 0.1 mm)."""

    def __init__(self, points: np.ndarray, viewpoint: np.ndarray, tolerance: float | None = None, *,
                 spacing: float | None = None):
        P = np.asarray(points, float).reshape(-1, 3)
        P = P[np.all(np.isfinite(P), axis=1)]
        v = check_viewpoint(viewpoint)
        if v is None:
            raise InvalidParameterError("a depth image needs a viewpoint")
        if len(P) < 3:
            raise InvalidParameterError(f"need >= 3 observed points for a depth image, got {len(P)}")
        self.viewpoint = v
        axis = P.mean(axis=0) - v
        if np.linalg.norm(axis) < 1e-9:
            raise InvalidParameterError("the viewpoint lies at the cloud's centroid")
        a = axis / np.linalg.norm(axis)
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        b1 = np.cross(a, helper)
        b1 /= np.linalg.norm(b1)
        self.basis = np.stack([b1, np.cross(a, b1), a])  # rows: image x, image y, optical axis
        self.spacing = spacing = max(median_spacing(P) if spacing is None else float(spacing), 1e-4)
        self.tolerance = max(2.0 * spacing, 0.002) if tolerance is None else float(tolerance)
        uv, r, front = self._project(P)
        if not front.all():
            raise InvalidParameterError("observed points lie behind the viewpoint")
        self.pixel = 1.5 * spacing / float(np.median(r))  # tangent-plane units per pixel
        lo = uv.min(axis=0) - 2 * self.pixel
        size = np.ceil((uv.max(axis=0) + 2 * self.pixel - lo) / self.pixel).astype(int) + 1
        if np.any(size > _MAX_PIXELS):
            self.pixel *= float(size.max()) / _MAX_PIXELS
            size = np.ceil((uv.max(axis=0) + 2 * self.pixel - lo) / self.pixel).astype(int) + 1
        self.origin, self.size = lo, size
        img = np.full(tuple(size), np.inf)
        ij = self._pixels(uv)
        np.minimum.at(img, (ij[:, 0], ij[:, 1]), r)
        self.depth = minimum_filter(img, size=3, mode="constant", cval=np.inf)

    def _project(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d = (X - self.viewpoint) @ self.basis.T  # (n, 3) in the view frame
        front = d[:, 2] > 1e-9
        z = np.where(front, d[:, 2], 1.0)
        return d[:, :2] / z[:, None], np.linalg.norm(d, axis=1), front

    def _pixels(self, uv: np.ndarray) -> np.ndarray:
        return np.floor((uv - self.origin) / self.pixel).astype(int)

    def occluded(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: points X (n, 3) more than ``tolerance`` behind the observed surface
        along their ray (outside the image or behind the viewpoint: not occluded)."""
        X = np.asarray(X, float).reshape(-1, 3)
        uv, r, front = self._project(X)
        ij = self._pixels(uv)
        inside = front & np.all((ij >= 0) & (ij < self.size), axis=1)
        out = np.zeros(len(X), bool)
        k = np.flatnonzero(inside)
        out[k] = r[k] > self.depth[ij[k, 0], ij[k, 1]] + self.tolerance
        return out


def finger_samples(gripper: GripperSpec, per_axis: tuple[int, int, int] = _PER_AXIS) -> tuple[np.ndarray, np.ndarray]:
    """(S, 3) sample points of the fingers' boxes in the wrist frame at zero pad gap, and
    their x signs (S,) (each moves by sign x gap / 2 with the opening)."""
    q, s = _finger_samples(gripper, tuple(per_axis))
    return q.copy(), s.copy()


@functools.lru_cache(maxsize=16)
def _finger_samples(gripper: GripperSpec, per_axis: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`finger_samples`, made once per gripper (read-only: the occlusion term asks
    for them in every scored batch, at every opening)."""
    b = gripper.collision_boxes()
    pts, signs = [], []
    for name, c, h, s in zip(b.names, b.centers, b.half_extents, b.x_sign):
        if not name.startswith("finger"):
            continue
        axes = [np.linspace(-hh, hh, n) if n > 1 else np.zeros(1) for hh, n in zip(h, per_axis)]
        g = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + c
        pts.append(g)
        signs.append(np.full(len(g), float(s)))
    q, s = np.concatenate(pts), np.concatenate(signs)
    q.setflags(write=False)
    s.setflags(write=False)
    return q, s


#: spacing [m] of :func:`felt_volume`'s samples: under the robust score's default margin
#: plus a finger's half thickness, so no finger fits between them
FELT_STEP = 0.003


def felt_volume(gripper: GripperSpec, T_wrist: np.ndarray, opening: float, view: ViewDepth,
                table: tuple[np.ndarray, float] | None = None, step: float = FELT_STEP) -> np.ndarray:
    """(K, 3) points [m, the view's frame] of the fingers' boxes at wrist pose ``T_wrist``
    (4, 4) with the pads ``opening`` [m] apart, a grid ``step`` apart through each box,
    that lie in ``view``'s occluded space (:meth:`ViewDepth.occluded`) and above the
    ``table`` (unit upward normal (3,), height along it; None: no table).

    What a grasp that started in collision with an object tells: the fingers met
    something there. Where the camera saw through, nothing was; the rest of the finger
    volume is where it may be -- a carton's depth behind the face the camera saw, a
    handle behind the body. A plan that keeps its fingers clear of these points does not
    try that space again, as a plan keeps clear of the neighbours' observed points."""
    T = np.asarray(T_wrist, float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InvalidParameterError(f"T_wrist must be a finite 4x4 transform, got shape {T.shape}")
    if not (np.isfinite(opening) and opening >= 0.0):
        raise InvalidParameterError(f"opening must be a finite pad gap >= 0 [m], got {opening!r}")
    if not (np.isfinite(step) and step > 0.0):
        raise InvalidParameterError(f"step must be > 0 [m], got {step!r}")
    q, x_sign = finger_samples(gripper, tuple(int(np.ceil(float(v) / step)) + 1 for v in gripper.finger_size))
    q[:, 0] += x_sign * 0.5 * float(opening)
    P = q @ T[:3, :3].T + T[:3, 3]
    keep = view.occluded(P)
    if table is not None:
        n, height = np.asarray(table[0], float), float(table[1])
        keep &= P @ n > height
    return P[keep]


def finger_occlusion(view: ViewDepth, R: np.ndarray, w: np.ndarray, opening: np.ndarray,
                     gripper: GripperSpec) -> np.ndarray:
    """(n,) the fraction of the finger samples of each wrist pose (R (n, 3, 3), w (n, 3),
    in the view's frame; pad gaps ``opening`` (n,) [m]) in occluded space (compiled:
    :mod:`graspsim.maps._occlusion_kernel`; :func:`finger_occlusion_numpy` is its reference)."""
    from graspsim.maps._occlusion_kernel import occluded_fraction

    q, s = _finger_samples(gripper, _PER_AXIS)
    n = len(R)
    out = np.zeros(n)
    if n:
        f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
        occluded_fraction(f64(R).reshape(n, 3, 3), f64(w).reshape(n, 3),
                          0.5 * f64(opening).reshape(-1), f64(q), f64(s), f64(view.viewpoint), f64(view.basis),
                          f64(view.origin), float(view.pixel), f64(view.depth), float(view.tolerance), out)
    return out


def finger_occlusion_numpy(view: ViewDepth, R: np.ndarray, w: np.ndarray, opening: np.ndarray,
                           gripper: GripperSpec) -> np.ndarray:
    """:func:`finger_occlusion` with numpy over every sample at once through
    :meth:`ViewDepth.occluded`: the reference the compiled kernel is tested against."""
    n = len(R)
    if not n:
        return np.zeros(0)
    X = _posed_finger_samples(R, w, opening, gripper)
    return view.occluded(X.reshape(-1, 3)).reshape(n, -1).mean(axis=1)


def _posed_finger_samples(R: np.ndarray, w: np.ndarray, opening: np.ndarray, gripper: GripperSpec) -> np.ndarray:
    """(n, S, 3) the finger samples of each wrist pose (R (n, 3, 3), w (n, 3); pad gaps
    ``opening`` (n,) [m]) in the poses' frame."""
    q, s = _finger_samples(gripper, _PER_AXIS)
    local = np.broadcast_to(q, (len(R), *q.shape)).copy()
    local[:, :, 0] += s[None] * 0.5 * np.asarray(opening, float).reshape(-1)[:, None]
    return np.einsum("nij,nsj->nsi", np.asarray(R, float), local) + np.asarray(w, float)[:, None]


def unseen_clearance(view: ViewDepth, known, R: np.ndarray, w: np.ndarray, opening: np.ndarray,
                     gripper: GripperSpec, upper: float = np.inf) -> np.ndarray:
    """(n,) per wrist pose (R (n, 3, 3), w (n, 3), the view's frame; pad gaps ``opening``
    (n,) [m]) the distance [m] from its finger samples in occluded space to the nearest
    point of ``known`` (a :class:`scipy.spatial.cKDTree` of what is known of the shapes:
    observed points, fitted primitives' surface samples); inf where no finger sample is
    occluded or none lies within ``upper``.

    A single view sees the front of an object; its back is the fitted primitive's
    extrapolation, and the true back may go on past it (a duck's back 10 to 17 mm beyond
    the cylinder fitted to its flank). A finger in unseen space close to the fitted
    surface may start inside the object; one that keeps its distance there does not."""
    n = len(R)
    out = np.full(n, np.inf)
    if not n:
        return out
    X = _posed_finger_samples(R, w, opening, gripper).reshape(-1, 3)
    occ = view.occluded(X)
    if not occ.any():
        return out
    d, _ = known.query(X[occ], k=1, distance_upper_bound=upper)
    per = np.full(len(X), np.inf)
    per[occ] = d
    return per.reshape(n, -1).min(axis=1)


def shadow_depth(viewpoint, points: np.ndarray, table: tuple[np.ndarray, float] | None) -> float:
    """How far [m], across the table, the space hidden behind ``points`` (an object's
    known shape, (M, 3)) reaches beyond them, seen from ``viewpoint`` (3,) (one frame;
    ``table``: (unit normal, height along it) or None: inf): h / tan(elevation), h the
    points' top above the table, the elevation the viewpoint's over the table seen from
    the points' centre. Past that the camera saw the table (or what stands on it), so an
    object resting there cannot go on further unseen: a domino lying flat hides a sliver
    a few mm wide behind its far edge, a duck 60 mm tall seen from 45 deg up its whole back."""
    P = np.asarray(points, float).reshape(-1, 3)
    if table is None or not len(P):
        return np.inf
    n, height = np.asarray(table[0], float), float(table[1])
    h = max(float(np.max(P @ n)) - height, 0.0)
    to_eye = np.asarray(viewpoint, float) - P.mean(axis=0)
    up = float(to_eye @ n) / max(float(np.linalg.norm(to_eye)), 1e-12)  # sin(elevation)
    if up <= 1e-6:
        return np.inf  # a camera at or below the table's level sees no table past the object
    return h * np.sqrt(max(1.0 - up * up, 0.0)) / up
