"""The pinhole depth-camera model: intrinsics, a pose, back-projection of a depth frame to
points and fusion of several views. Rendering the frames (MuJoCo) is
:mod:`graspsim.tabletop.depth_render`.

Frames. The camera frame is OpenCV's: x right, y down, z forward (the viewing
direction); a pixel (u, v) (column, row; pixel centres at integer coordinates) sees the
ray ``((u - cx) / fx, (v - cy) / fy, 1)``. ``T_world_camera`` (4, 4) places that frame in
the world. Depth images hold z-depth (the camera-frame z of the surface, not the distance
along the ray) in metres, 0 where nothing valid was seen, as a RealSense reports them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.transforms import make_transform, transform_points

__all__ = ["Intrinsics", "Camera", "DepthFrame", "CloudView", "look_at", "orbit", "rig", "backproject", "to_world",
           "fuse", "PRESETS"]

#: Named intrinsics: (width, height, horizontal field of view [deg]).
PRESETS = {"d435": (640, 480, 87.0)}
_MAX_PIXELS = 4096 * 4096


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics: image size [px], focal lengths fx, fy [px], principal point
    cx, cy [px] (OpenCV convention: pixel centres at integers)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        for k in ("width", "height"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise InvalidParameterError(f"Intrinsics.{k} must be a whole number of pixels >= 1, got {v!r}")
        if self.width * self.height > _MAX_PIXELS:
            raise InvalidParameterError(f"image {self.width}x{self.height} exceeds {_MAX_PIXELS} pixels")
        for k in ("fx", "fy", "cx", "cy"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v)):
                raise InvalidParameterError(f"Intrinsics.{k} must be a finite number, got {v!r}")
        if self.fx <= 0 or self.fy <= 0:
            raise InvalidParameterError(f"focal lengths must be > 0 px, got fx={self.fx!r}, fy={self.fy!r}")
        if not (-0.5 <= self.cx <= self.width - 0.5 and -0.5 <= self.cy <= self.height - 0.5):
            raise InvalidParameterError(
                f"principal point ({self.cx}, {self.cy}) lies outside the {self.width}x{self.height} image")

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> Intrinsics:
        """Square pixels, centred principal point, horizontal field of view [deg]."""
        if not (isinstance(hfov_deg, (int, float)) and 0 < hfov_deg < 180):
            raise InvalidParameterError(f"horizontal field of view must be in (0, 180) deg, got {hfov_deg!r}")
        f = 0.5 * width / math.tan(math.radians(0.5 * hfov_deg))
        return cls(width, height, f, f, 0.5 * (width - 1), 0.5 * (height - 1))

    @classmethod
    def preset(cls, name: str) -> Intrinsics:
        """A named camera (``d435``: 640 x 480, 87 deg horizontal, like a RealSense D435)."""
        if name not in PRESETS:
            raise InvalidParameterError(f"unknown camera preset {name!r}; valid: {sorted(PRESETS)}")
        return cls.from_fov(*PRESETS[name])

    @property
    def K(self) -> np.ndarray:
        """(3, 3) camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def hfov(self) -> float:
        """Horizontal field of view [deg] (of a centred principal point)."""
        return math.degrees(2 * math.atan(0.5 * self.width / self.fx))

    def rays(self) -> np.ndarray:
        """(H, W, 3) rays of the pixel centres with z = 1, camera frame (depth x ray = point)."""
        u = (np.arange(self.width) - self.cx) / self.fx
        v = (np.arange(self.height) - self.cy) / self.fy
        r = np.empty((self.height, self.width, 3))
        r[..., 0], r[..., 1], r[..., 2] = u[None, :], v[:, None], 1.0
        return r

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N, 2) (u, v) of camera-frame points (N, 3) with z > 0."""
        p = np.asarray(points, float)
        return np.stack([self.fx * p[:, 0] / p[:, 2] + self.cx, self.fy * p[:, 1] / p[:, 2] + self.cy], -1)

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("width", "height", "fx", "fy", "cx", "cy")}


def _as_pose(T, what: str = "T_world_camera") -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InvalidParameterError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    R = T[:3, :3]
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0) or np.any(T[3] != [0, 0, 0, 1]):
        raise InvalidParameterError(f"{what} must be a rigid transform (rotation + translation)")
    return T


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """T_world_camera (4, 4) of a camera at ``eye`` looking at ``target`` (world [m]), the
    image's up direction (-y) as close to ``up`` as the view allows."""
    eye, target, up = (np.asarray(a, float).reshape(3) for a in (eye, target, up))
    z = target - eye
    if not np.all(np.isfinite(z)) or np.linalg.norm(z) < 1e-9:
        raise InvalidParameterError(f"look_at needs distinct finite eye and target, got {eye} and {target}")
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-6:  # looking along up: any image x will do
        x = np.cross(z, [0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    return make_transform(np.stack([x, np.cross(z, x), z], axis=1), eye)


def orbit(target=(0.0, 0.0, 0.0), *, distance: float = 0.7, elevation: float = 55.0,
          azimuth: float = -90.0) -> np.ndarray:
    """T_world_camera (4, 4) looking at ``target`` from ``distance`` [m], ``elevation``
    [deg] above the horizontal and ``azimuth`` [deg] (from +x towards +y; -90: from -y)."""
    if not (np.isfinite(distance) and distance > 0 and -90 < elevation <= 90):
        raise InvalidParameterError(f"distance must be > 0 m and elevation in (-90, 90] deg, "
                                    f"got {distance!r}, {elevation!r}")
    e, a = math.radians(elevation), math.radians(azimuth)
    eye = np.asarray(target, float) + distance * np.array([math.cos(e) * math.cos(a),
                                                            math.cos(e) * math.sin(a), math.sin(e)])
    return look_at(eye, target)


def rig(n: int = 1, intrinsics: Intrinsics | None = None, *, target=(0.0, 0.0, 0.03), distance: float = 0.7,
        elevation: float = 55.0, azimuth: float = -90.0) -> list[Camera]:
    """``n`` cameras (default D435) around ``target``, evenly spaced in azimuth from
    ``azimuth``, all at ``distance`` and ``elevation`` (see :func:`orbit`): a table-top
    view for one, a fused all-round view for 2-3."""
    if not (isinstance(n, int) and 1 <= n <= 8):
        raise InvalidParameterError(f"a rig has 1 to 8 cameras, got {n!r}")
    k = intrinsics or Intrinsics.preset("d435")
    return [Camera(k, orbit(target, distance=distance, elevation=elevation, azimuth=azimuth + 360.0 * i / n))
            for i in range(n)]


@dataclass(frozen=True, eq=False)
class Camera:
    """Intrinsics and the pose ``T_world_camera`` (4, 4) of the OpenCV camera frame."""

    intrinsics: Intrinsics
    T_world_camera: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.intrinsics, Intrinsics):
            raise InvalidParameterError(f"Camera.intrinsics must be Intrinsics, got {type(self.intrinsics).__name__}")
        object.__setattr__(self, "T_world_camera", _as_pose(self.T_world_camera))

    def to_dict(self) -> dict:
        return {"intrinsics": self.intrinsics.to_dict(), "T_world_camera": self.T_world_camera.tolist(),
                "frame": "opencv (x right, y down, z forward)"}

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        try:
            return cls(Intrinsics(**d["intrinsics"]), np.asarray(d["T_world_camera"], float))
        except (KeyError, TypeError) as err:
            raise InvalidParameterError(f"not a camera record: {err}") from err


@dataclass(frozen=True, eq=False)
class DepthFrame:
    """One rendered view. depth: (H, W) float32 z-depth [m], 0 = invalid; segmentation:
    (H, W) int32 MuJoCo geom id per pixel (-1: background or not a geom), ground truth;
    labels: (H, W) int32 scene object id per pixel (-1: none; set by a scene that knows
    its objects); rgb: (H, W, 3) uint8 or None."""

    depth: np.ndarray
    camera: Camera
    segmentation: np.ndarray | None = None
    labels: np.ndarray | None = None
    rgb: np.ndarray | None = None
    noise: dict | None = field(default=None)


@dataclass(frozen=True, eq=False)
class CloudView:
    """Back-projected valid pixels. points (N, 3) camera frame [m]; uv (N, 2) int pixel
    (column, row); segmentation / labels (N,) int32 per point (or None)."""

    points: np.ndarray
    uv: np.ndarray
    camera: Camera
    segmentation: np.ndarray | None = None
    labels: np.ndarray | None = None

    def world(self) -> np.ndarray:
        """The points (N, 3) in the world frame [m]."""
        return to_world(self.points, self.camera.T_world_camera)


def backproject(frame: DepthFrame, *, stride: int = 1) -> CloudView:
    """The valid pixels of ``frame`` (every ``stride``-th row and column) as camera-frame points."""
    if not (isinstance(stride, int) and stride >= 1):
        raise InvalidParameterError(f"stride must be a whole number >= 1, got {stride!r}")
    k = frame.camera.intrinsics
    d = np.asarray(frame.depth)[::stride, ::stride]
    rows, cols = np.nonzero(d > 0)
    rows_f, cols_f = rows * stride, cols * stride
    z = d[rows, cols].astype(float)
    pts = np.stack([(cols_f - k.cx) / k.fx * z, (rows_f - k.cy) / k.fy * z, z], axis=-1)
    pick = lambda a: None if a is None else np.asarray(a)[rows_f, cols_f].astype(np.int32)  # noqa: E731
    return CloudView(pts, np.stack([cols_f, rows_f], -1), frame.camera, pick(frame.segmentation),
                     pick(frame.labels))


def to_world(points: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) in the world frame."""
    return transform_points(_as_pose(T_world_camera), np.asarray(points, float).reshape(-1, 3))


def fuse(frames, *, voxel: float = 0.0, stride: int = 1) -> tuple[np.ndarray, np.ndarray | None]:
    """World cloud (N, 3) of several views and its labels (N,) (None unless every frame
    has labels). voxel [m] > 0: keep one point (the mean) per voxel, label of the first."""
    views = [backproject(f, stride=stride) for f in frames]
    if not views:
        raise InvalidParameterError("fuse needs at least one frame")
    pts = np.concatenate([v.world() for v in views])
    labels = None if any(v.labels is None for v in views) else np.concatenate([v.labels for v in views])
    if voxel > 0 and len(pts):
        key = np.floor(pts / voxel).astype(np.int64)
        _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
        inv = inv.reshape(-1)
        sums = np.zeros((len(first), 3))
        np.add.at(sums, inv, pts)
        pts = sums / np.bincount(inv)[:, None]
        labels = None if labels is None else labels[first]
    return pts, labels
