"""Writing a camera's point cloud: ``.pcd`` (binary), ``.ply`` (binary) or ``.npy``, with
the camera recorded beside it.

The points stay in the frame they are given in (a back-projected view: the camera frame).
The camera (intrinsics, ``T_world_camera``, frame convention) and the points' frame go into
a sidecar ``<file>.json``; a PCD also carries the pose in its ``VIEWPOINT`` line
(tx ty tz qw qx qy qz, the camera in the world) when its points are in the camera frame,
as PCL defines it. PCD and PLY carry per-point ``label`` s when given (the ``.npy`` stays
an (N, 3) array: its labels go into ``<file>.labels.npy``). Every file is written
atomically, all of them together. :func:`graspsim.perception.cloud_input.read_point_cloud` reads
the points back; :func:`graspsim.perception.cloud_input.read_camera` the sidecar.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_paths
from graspsim.errors import InvalidParameterError, OutputPathError, PointCloudError
from graspsim.transforms import matrix_to_quat

__all__ = ["save_cloud", "save_view", "FORMATS"]

FORMATS = (".pcd", ".ply", ".npy")


def _pcd(points: np.ndarray, labels: np.ndarray | None, viewpoint: np.ndarray | None) -> bytes:
    n = len(points)
    fields = "x y z" + (" label" if labels is not None else "")
    size = "4 4 4" + (" 4" if labels is not None else "")
    typ = "F F F" + (" I" if labels is not None else "")
    vp = "0 0 0 1 0 0 0" if viewpoint is None else " ".join(f"{v:.9g}" for v in viewpoint)
    head = (f"# .PCD v0.7 - written by graspsim\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\nTYPE {typ}\n"
            f"COUNT {' '.join(['1'] * len(fields.split()))}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT {vp}\n"
            f"POINTS {n}\nDATA binary\n")
    return head.encode() + _records(points, labels).tobytes()


def _records(points: np.ndarray, labels: np.ndarray | None) -> np.ndarray:
    dt = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")] + ([("label", "<i4")] if labels is not None else [])
    rec = np.empty(len(points), dtype=dt)
    rec["x"], rec["y"], rec["z"] = points.T
    if labels is not None:
        rec["label"] = labels
    return rec


def _ply(points: np.ndarray, labels: np.ndarray | None, comment: str) -> bytes:
    head = (f"ply\nformat binary_little_endian 1.0\ncomment {comment}\nelement vertex {len(points)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            + ("property int label\n" if labels is not None else "") + "end_header\n")
    return head.encode() + _records(points, labels).tobytes()


def save_cloud(path: str | os.PathLike, points: np.ndarray, *, camera=None, frame: str = "camera",
               labels: np.ndarray | None = None) -> list[Path]:
    """Write ``points`` (N, 3) [m] (in ``frame``: "camera" or "world") to ``path``
    (.pcd/.ply/.npy) and, when ``camera`` (a :class:`~graspsim.geometry.camera.Camera`) is
    given, its record to ``<path>.json``. labels: (N,) int per point. Returns the paths."""
    path = Path(path)
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise PointCloudError(f"points must be a finite (N, 3) array, got shape {pts.shape}")
    if frame not in ("camera", "world"):
        raise InvalidParameterError(f"frame must be 'camera' or 'world', got {frame!r}")
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise OutputPathError(f"cannot write a cloud as {path.name!r}: the suffix must be one of {FORMATS}")
    if labels is not None:
        labels = np.asarray(labels).reshape(-1)
        if len(labels) != len(pts):
            raise InvalidParameterError(f"labels ({len(labels)}) and points ({len(pts)}) differ in number")
    T = None if camera is None else camera.T_world_camera
    vp = None if T is None or frame != "camera" else np.concatenate([T[:3, 3], matrix_to_quat(T[:3, :3])])
    blobs: dict[Path, bytes] = {}
    if suffix == ".pcd":
        blobs[path] = _pcd(pts, labels, vp)
    elif suffix == ".ply":
        blobs[path] = _ply(pts, labels, f"graspsim cloud, {frame} frame")
    else:
        buf = io.BytesIO()
        np.save(buf, pts.astype(np.float32))
        blobs[path] = buf.getvalue()
        if labels is not None:
            lb = io.BytesIO()
            np.save(lb, labels.astype(np.int32))
            blobs[path.with_name(path.name[:-4] + ".labels.npy")] = lb.getvalue()
    if camera is not None:
        record = {"points_frame": frame, "points": len(pts), "camera": camera.to_dict()}
        blobs[Path(str(path) + ".json")] = (json.dumps(record, indent=1) + "\n").encode()
    with atomic_paths(list(blobs), OutputPathError) as tmps:
        for tmp, data in zip(tmps, blobs.values()):
            Path(tmp).write_bytes(data)
    return list(blobs)


def save_view(path: str | os.PathLike, view, *, frame: str = "camera") -> list[Path]:
    """Write a :class:`~graspsim.geometry.camera.CloudView` (its labels, else its geom ids)."""
    pts = view.points if frame == "camera" else view.world()
    labels = view.labels if view.labels is not None else view.segmentation
    return save_cloud(path, pts, camera=view.camera, frame=frame, labels=labels)
