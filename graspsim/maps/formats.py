"""Third-party grasp files read as maps: ACRONYM HDF5, GraspGen JSON, GraspNet-1Billion arrays.

:func:`read_grasp_file` turns one into a :class:`~graspsim.maps.GraspabilityMap` whose
poses are graspsim wrist poses (the map's gripper's wrist frame, ``graspsim.grippers.spec``:
z = approach, x = closing axis, origin at the flange) in the object's mesh frame, so
``graspsim trial``, ``info`` and ``view`` take it like a map of their own. What such a
file does not hold stays missing: the analytic grade and its terms, the contacts and
their normals are NaN (``meta.method`` = ``imported:<format>``, see
``maps/validate.py``); the file's own labels (ACRONYM's FleX ``object_in_gripper``,
GraspNet's score) are kept apart in :attr:`GraspFile.labels`. The width column is the
file's pre-grasp pad gap less the approach clearance on both sides, so the executor
(``executed_width`` -> ``GripperSpec.pregrasp_opening``) opens the jaws as the
dataset's simulator did.

Gripper frames, each converted with one transform T_grasp_wrist (the wrist frame in the
file's gripper frame; recorded in ``meta.extra["import"]``):

* ACRONYM and GraspGen, Franka ``panda``: the frame of the Franka hand's base link A,
  z = approach, fingers along x (ACRONYM's ``create_gripper_marker``: fingers at
  x = +-4.1 cm, tips at z = 11.2 cm). It is the URDF hand frame H turned +90 deg about z
  (:data:`R_ACRONYM_HAND`: ACRONYM's ``franka_gripper_collision_mesh.stl`` and GraspGen's
  ``assets/panda_gripper/hand.stl`` are the vendored hand's hull, whose extent
  y_H in [-104.0, 100.4] mm appears as x_A in [-100.4, 104.0] mm, z from -25.9 mm in
  both). With graspsim's mount of the hand (``grippers/franka.py``: H in W turned -90 deg,
  25.93 mm along z) that makes W = A turned 180 deg about z, its origin 25.93 mm behind
  A's along the approach axis: ``T_A_W = T_A_H inv(T_W_H)``.
* Files graspsim wrote (:mod:`graspsim.maps.export`) record their own T_grasp_wrist and
  gripper spec; for other grippers that frame is the wrist frame itself (GraspGen's
  convention: z = approach, x = closing, origin at the base link).
* GraspNet-1Billion (``graspnetAPI.GraspGroup``, 17 floats per grasp: score, width,
  height, depth, rotation (3 x 3, row-major), translation, object id) in the camera
  frame: its gripper frame G has x = approach, y = closing, origin at the grasp centre;
  the fingertips reach ``depth`` past it and the palm sits 2 cm behind it
  (``plot_gripper_pro_max``: ``depth_base = 0.02``). So the grasp point is graspsim's TCP
  at contact depth ``depth``: ``wrist = t - tcp_offset(depth) * x_G`` and
  R_W = R_G P^T with P = (e3, e1, e2) (:data:`GRASPNET_AXES`). Width: the pad gap.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graspsim.errors import MapFileError
from graspsim.grippers.spec import GripperSpec
from graspsim.maps.graspmap import GraspabilityMap, MapMeta
from graspsim.transforms import invert_transform, make_transform, matrix_to_quat

__all__ = ["GraspFile", "read_grasp_file", "detect_format", "grasp_frame", "FORMATS",
           "R_ACRONYM_HAND", "GRASPNET_AXES", "ACRONYM_GRIPPERS", "IMPORTED", "is_imported",
           "graspnet_to_wrist", "wrist_to_graspnet", "is_foreign"]

FORMATS = ("acronym", "graspgen", "graspnet")
IMPORTED = "imported:"  # meta.method prefix of a map read from a third-party file
#: ACRONYM's / GraspGen's Franka frame A in the URDF hand frame H: +90 deg about z.
R_ACRONYM_HAND = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: GraspNet's gripper axes in the wrist frame: x_G = z_W, y_G = x_W, z_G = y_W (R_G = R_W P).
GRASPNET_AXES = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
#: gripper type names of ACRONYM (``gripper/type``) and GraspGen -> graspsim's gripper
ACRONYM_GRIPPERS = {"panda": "franka_hand", "franka_panda": "franka_hand"}
GRASPNET_COLUMNS = 17


@dataclass(frozen=True, eq=False)
class GraspFile:
    """A third-party grasp file read as a map. labels: name -> (N,) the file's own
    per-grasp labels (``object_in_gripper``: 1 held, 0 not; ``score`` for GraspNet);
    label_source: which simulator (or method) produced them, as the file says."""

    format: str
    path: Path
    gmap: GraspabilityMap
    labels: dict[str, np.ndarray] = field(default_factory=dict)
    label_source: str = ""


def is_imported(gmap: GraspabilityMap) -> bool:
    """Whether ``gmap`` was read from a third-party file (its grades are missing)."""
    return str(gmap.meta.method).startswith(IMPORTED)


def is_foreign(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a third-party grasp file: a .json or .npy file, or an HDF5 file with
    ``grasps/transforms`` and no ``graspability`` group (anything else is left to ``load_map``)."""
    path = Path(path)
    try:
        if not path.is_file():
            return False
        if path.suffix.lower() in (".json", ".npy"):
            return True
        import h5py

        with h5py.File(path, "r") as f:
            return "grasps/transforms" in f and "graspability" not in f
    except (OSError, ValueError, KeyError, RuntimeError):
        return False


def detect_format(path: str | os.PathLike) -> str:
    """``"graspsim"`` (a graspsim map), ``"acronym"``, ``"graspgen"`` or ``"graspnet"``."""
    path = Path(path)
    if not path.is_file():
        raise MapFileError(f"grasp file {path} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return "graspnet"
    if suffix == ".json":
        return "graspgen" if "grasps" in _json(path) else "acronym"
    import h5py

    try:
        with h5py.File(path, "r") as f:
            if "graspability/meta" in f:
                return "graspsim"
            if "grasps/transforms" in f:
                return "acronym"
    except OSError as err:
        raise MapFileError(f"{path} is not a readable HDF5 file: {' '.join(str(err).split())}") from err
    raise MapFileError(f"{path} is neither a graspsim map nor an ACRONYM grasp file "
                       "(no graspability/meta, no grasps/transforms)")


def grasp_frame(gripper: GripperSpec) -> np.ndarray:
    """T_grasp_wrist (4, 4): graspsim's wrist frame in the ACRONYM / GraspGen gripper
    frame of ``gripper`` (the Franka hand: see the module doc; others: identity)."""
    if gripper.model != "franka_hand":
        return np.eye(4)
    from graspsim.grippers.franka import franka_hand_mount
    from graspsim.transforms import quat_to_matrix

    mount = franka_hand_mount()
    T_W_H = make_transform(quat_to_matrix(np.asarray(mount.quat, float)), np.asarray(mount.pos, float))
    return make_transform(R_ACRONYM_HAND, np.zeros(3)) @ invert_transform(T_W_H)


def read_grasp_file(path: str | os.PathLike, *, gripper: GripperSpec | str | None = None,
                    mesh: str | os.PathLike | None = None, mesh_scale: float | None = None,
                    T_camera_obj: np.ndarray | None = None, object_id: int | None = None) -> GraspFile:
    """Read a third-party grasp file (the format from :func:`detect_format`) as a map.

    gripper: the gripper the grasps are for (default: the file's: ACRONYM's
    ``gripper/type``, a graspsim export's spec, else the Franka hand). mesh, mesh_scale:
    the object's mesh (default: the file's ``object/file`` found beside it, at its
    ``object/scale``; GraspNet files need it). T_camera_obj: GraspNet only, the object's
    pose in the camera frame (default: the grasps are in the object frame already);
    object_id: GraspNet only, keep the rows of this object.
    """
    path = Path(path)
    fmt = detect_format(path)
    if fmt == "graspsim":
        raise MapFileError(f"{path} is a graspsim map; read it with load_map")
    raw = {"acronym": _read_acronym, "graspgen": _read_graspgen, "graspnet": _read_graspnet}[fmt](path)
    if fmt == "graspnet":
        raw = _graspnet_rows(raw, T_camera_obj, object_id, path)
    spec = _gripper(raw, gripper)
    return _assemble(fmt, path, _physics(raw), spec, mesh, mesh_scale)


# ---------------------------------------------------------------------- the formats
def _read_acronym(path: Path) -> dict:
    """The layout ``acronym_tools.load_grasps`` / ``load_mesh`` read (h5, or ACRONYM's JSON)."""
    if path.suffix.lower() == ".json":
        d = _json(path)
        return _checked(path, {"T": d.get("transforms"), "labels": {
            "object_in_gripper": d.get("quality_flex_object_in_gripper")},
            "file": d.get("object"), "scale": d.get("object_scale", 1.0),
            "source": "FleX (ACRONYM)", "attrs": d.get("graspsim", {})})
    import h5py

    with h5py.File(path, "r") as f:
        labels = {}
        if "grasps/qualities/flex/object_in_gripper" in f:
            labels["object_in_gripper"] = f["grasps/qualities/flex/object_in_gripper"][()]
        g = {k: f[k][()] for k in ("object/file", "object/scale", "object/mass", "object/com",
                                   "object/friction", "gripper/type", "gripper/configuration") if k in f}
        attrs = {k: _text(v) for k, v in f.attrs.items()}
        extra = {k[len("grasps/graspsim/"):]: f[k][()] for k in
                 ("grasps/graspsim/opening", "grasps/graspsim/width", "grasps/graspsim/grade",
                  "grasps/graspsim/wrist_position") if k in f}
        T = f["grasps/transforms"][()]
    source = json.loads(attrs["graspsim"]).get("label_source", "") if "graspsim" in attrs else "FleX (ACRONYM)"
    return _checked(path, {"T": T, "labels": labels, "file": _text(g.get("object/file")),
                           "scale": g.get("object/scale", 1.0), "mass": g.get("object/mass"),
                           "com": g.get("object/com"), "friction": g.get("object/friction"),
                           "type": _text(g.get("gripper/type")),
                           "configuration": g.get("gripper/configuration"), "source": source,
                           "attrs": json.loads(attrs["graspsim"]) if "graspsim" in attrs else {},
                           "extra": extra})


def _read_graspgen(path: Path) -> dict:
    """GraspGen's dataset JSON (its GRASP_DATASET_FORMAT.md, NVlabs/GraspGen): object.file/scale,
    grasps.transforms (the gripper's base link) and grasps.object_in_gripper."""
    d = _json(path)
    obj, grasps = d.get("object") or {}, d.get("grasps") or {}
    meta = d.get("graspsim", {})
    labels = meta.get("labels") or {"object_in_gripper": grasps.get("object_in_gripper")}
    return _checked(path, {"T": grasps.get("transforms"), "labels": labels,
                           "file": obj.get("file"), "scale": obj.get("scale", 1.0), "attrs": meta,
                           "source": meta.get("label_source", "GraspGen dataset"),
                           "extra": {k: np.asarray(v, float) for k, v in meta.get("columns", {}).items()}})


def _read_graspnet(path: Path) -> dict:
    """A ``GraspGroup.save_npy`` array (N, 17), with graspsim's sidecar ``<stem>.json``
    (frame, mesh, labels) when graspsim wrote it."""
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise MapFileError(f"{path} is not a numpy .npy array: {err}") from err
    if a.ndim != 2 or a.shape[1] != GRASPNET_COLUMNS or a.dtype.kind not in "fiu":
        raise MapFileError(f"{path} is not a GraspNet GraspGroup array: shape {a.shape} {a.dtype}, "
                           f"expected (N, {GRASPNET_COLUMNS}) numbers")
    side = path.with_suffix(".json")
    meta = _json(side).get("graspsim", {}) if side.is_file() else {}
    labels = {"score": a[:, 0].copy(), **{k: np.asarray(v) for k, v in meta.get("labels", {}).items()}}
    return {"array": np.asarray(a, float), "labels": labels, "attrs": meta,
            "file": meta.get("object", {}).get("file"), "scale": meta.get("object", {}).get("scale", 1.0),
            "source": meta.get("label_source", "GraspNet-1Billion score"),
            "extra": {k: np.asarray(v, float) for k, v in meta.get("columns", {}).items()}}


def _graspnet_rows(raw: dict, T_camera_obj, object_id, path: Path) -> dict:
    """GraspNet rows as base-link poses in the object frame (the wrist conversion needs
    the gripper: ``raw["graspnet"]``), the opening from the width column."""
    a = raw.pop("array")
    if object_id is not None:
        keep = a[:, 16] == object_id
        if not keep.any():
            have = sorted({int(v) for v in a[:, 16]})
            raise MapFileError(f"{path} holds no grasp of object {object_id}; its objects: {have[:20]}")
        a = a[keep]
        raw["labels"] = {k: np.asarray(v)[keep] for k, v in raw["labels"].items()}
        raw["extra"] = {k: v[keep] for k, v in raw["extra"].items()}
    T_cam_obj = np.eye(4) if T_camera_obj is None else np.asarray(T_camera_obj, float)
    if T_cam_obj.shape != (4, 4) or not np.isfinite(T_cam_obj).all():
        raise MapFileError(f"the object's camera pose must be a finite 4 x 4 transform, got {T_cam_obj.shape}")
    T_obj_cam = invert_transform(T_cam_obj)
    raw["graspnet"] = (T_obj_cam[:3, :3] @ a[:, 4:13].reshape(-1, 3, 3),
                       a[:, 13:16] @ T_obj_cam[:3, :3].T + T_obj_cam[:3, 3], a[:, 3])
    raw["opening"] = a[:, 1]
    return raw


def graspnet_to_wrist(R_G: np.ndarray, t: np.ndarray, depth: np.ndarray, gripper: GripperSpec) -> np.ndarray:
    """(N, 4, 4) wrist poses of GraspNet grasps (rotations (N, 3, 3), centres (N, 3),
    depths (N,)), all in one frame."""
    R_W = R_G @ GRASPNET_AXES.T
    T = np.zeros((len(t), 4, 4))
    T[:, :3, :3] = R_W
    T[:, :3, 3] = t - gripper.tcp_offset(np.asarray(depth, float))[:, None] * R_W[:, :, 2]
    T[:, 3, 3] = 1.0
    return T


def wrist_to_graspnet(T_wrist: np.ndarray, grasp_point: np.ndarray,
                      gripper: GripperSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The inverse of :func:`graspnet_to_wrist`: (R_G, centre, depth) of wrist poses
    holding ``grasp_point`` (N, 3) on their axis."""
    approach = T_wrist[:, :3, 2]
    depth = gripper.contact_depth(grasp_point, T_wrist[:, :3, 3], approach)
    return T_wrist[:, :3, :3] @ GRASPNET_AXES, np.asarray(grasp_point, float), depth


# ---------------------------------------------------------------------- assembling
def _physics(raw: dict) -> dict:
    """The object's mass, com, friction a graspsim export recorded where its format has none."""
    rec = raw.get("attrs", {}).get("physics") or {}
    for k in ("mass", "com", "friction"):
        v = rec.get(k)
        if raw.get(k) is None and v is not None and np.all(np.isfinite(v)):
            raw[k] = v
    return raw


def _gripper(raw: dict, asked) -> GripperSpec:
    from graspsim.grippers import get_gripper

    spec = raw.get("attrs", {}).get("gripper_spec")
    if asked is not None:
        return get_gripper(asked)
    if spec:
        return GripperSpec.from_dict(spec)
    kind = raw.get("type")
    if kind and kind not in ACRONYM_GRIPPERS:
        raise MapFileError(f"the file's gripper {kind!r} has no graspsim model; graspsim reads "
                           f"{sorted(ACRONYM_GRIPPERS)} (give another gripper with --gripper)")
    return get_gripper("franka_hand")


def _wrist_poses(raw: dict, spec: GripperSpec) -> np.ndarray:
    if "graspnet" in raw:
        return graspnet_to_wrist(*raw["graspnet"], spec)
    T_gw = np.asarray(raw["attrs"]["T_grasp_wrist"], float).reshape(4, 4) \
        if "T_grasp_wrist" in raw.get("attrs", {}) else grasp_frame(spec)
    return np.asarray(raw["T"], float) @ T_gw


def _assemble(fmt: str, path: Path, raw: dict, spec: GripperSpec, mesh, mesh_scale) -> GraspFile:
    T = _wrist_poses(raw, spec)
    n = len(T)
    extra = raw.get("extra", {})
    if "wrist_position" in extra:  # graspsim's own export: its float32 wrist positions, exact
        T[:, :3, 3] = _same_positions(T[:, :3, 3], extra["wrist_position"], path)
    opening = _opening(raw, spec, n)
    width = extra["width"] if "width" in extra else np.maximum(opening - 2 * spec.approach_clearance, 1e-4)
    grade = extra["grade"] if "grade" in extra else np.full(n, np.nan)
    grasp_point = spec.grasp_point_from_wrist(T[:, :3, 3], T[:, :3, 2], spec.nominal_depth)
    if "graspnet" in raw:  # the grasp centre is the point the file names
        grasp_point = raw["graspnet"][1]
    nan = np.full(n, np.nan)
    obj = _object(raw, path, mesh, mesh_scale)
    record = {"format": fmt, "file": str(path), "T_grasp_wrist": _frame_record(raw, spec),
              "label_source": raw.get("source", ""), "labels": sorted(raw["labels"])}
    meta = MapMeta(object=obj, gripper=spec.to_dict(),
                   quality={"friction": float(raw.get("friction") or 0.5), "threshold": 0.7},
                   resolution={}, method=IMPORTED + fmt, extra={"import": record})
    gmap = GraspabilityMap(
        wrist_position=T[:, :3, 3], wrist_quat=matrix_to_quat(T[:, :3, :3]), grasp_point=grasp_point,
        contacts=np.full((n, 2, 3), np.nan), normals=np.full((n, 2, 3), np.nan), width=width,
        fc_angle=nan, q_fc=nan, stability_distance=nan, q_st=nan, grade=grade,
        part=np.zeros(n, np.int16), meta=meta)
    labels = {k: np.asarray(v) for k, v in raw["labels"].items() if v is not None}
    return GraspFile(fmt, path, gmap, labels, raw.get("source", ""))


def _same_positions(converted: np.ndarray, stored, path: Path) -> np.ndarray:
    """The wrist positions a graspsim export stored beside its poses, once they agree
    with the converted poses (1 um): converting twice costs float32 rounding (~4 nm)."""
    stored = np.asarray(stored, float).reshape(converted.shape)
    if not np.all(np.abs(stored - converted) <= 1e-6):
        raise MapFileError(f"{path}: its grasp poses and its graspsim wrist positions disagree "
                           "(the file was edited, or its frame is not the one recorded)")
    return stored


def _frame_record(raw: dict, spec: GripperSpec) -> list | str:
    if "graspnet" in raw:
        return "graspnet: wrist = centre - tcp_offset(depth) x_G, R_W = R_G GRASPNET_AXES^T"
    if "T_grasp_wrist" in raw.get("attrs", {}):
        return list(map(float, raw["attrs"]["T_grasp_wrist"]))
    return grasp_frame(spec).ravel().round(12).tolist()


def _opening(raw: dict, spec: GripperSpec, n: int) -> np.ndarray:
    """(N,) the pre-grasp pad gap [m]: a graspsim export's per-grasp column, GraspNet's
    width, ACRONYM's ``gripper/configuration`` (one finger's joint value: half the gap),
    else the gripper's widest."""
    if "opening" in raw.get("extra", {}):
        return np.asarray(raw["extra"]["opening"], float)
    if "opening" in raw:
        return np.asarray(raw["opening"], float)
    conf = raw.get("configuration")
    if conf is not None and np.size(conf) >= 1 and np.isfinite(np.ravel(conf)[0]):
        return np.full(n, 2.0 * float(np.ravel(conf)[0]))
    return np.full(n, spec.max_opening)


def _object(raw: dict, path: Path, mesh, mesh_scale) -> dict:
    """The map's object record: the mesh (given, or the file's, found beside it)."""
    obj: dict = {"primitive": "mesh"}
    name = str(mesh) if mesh is not None else raw.get("file")
    if name:
        found = Path(name) if mesh is not None else _find_beside(path, name)
        obj["file"] = str(found.resolve()) if found is not None else name
        obj["scale"] = float(mesh_scale if mesh_scale is not None else
                             (1.0 if mesh is not None else raw.get("scale") or 1.0))
    mass = raw.get("mass")
    obj["mass"] = float(mass) if mass is not None else float("nan")
    com = raw.get("com")
    obj["com"] = [float(c) for c in np.ravel(com)] if com is not None else [0.0, 0.0, 0.0]
    return obj


def _find_beside(path: Path, name: str) -> Path | None:
    """``name`` beside the grasp file or in its two parent folders (ACRONYM's ``grasps/`` and
    ``meshes/`` side by side), or as given if absolute; None if not found."""
    p = Path(name)
    if p.is_absolute():
        return p if p.is_file() else None
    for folder in (path.parent, *list(path.parent.parents)[:2]):
        if (folder / p).is_file():
            return folder / p
    return None


def _checked(path: Path, raw: dict) -> dict:
    T = raw.get("T")
    try:
        T = np.asarray(T, float)
    except (TypeError, ValueError):
        T = np.zeros(0)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.isfinite(T).all():
        raise MapFileError(f"{path}: grasp transforms must be finite (N, 4, 4) matrices, got shape {T.shape}")
    raw["T"] = T
    raw["labels"] = {k: np.asarray(v) for k, v in raw["labels"].items() if v is not None}
    for k, v in raw["labels"].items():
        if len(v) != len(T):
            raise MapFileError(f"{path}: label {k!r} has {len(v)} rows, the file has {len(T)} grasps")
    raw.setdefault("extra", {})
    return raw


def _json(path: Path) -> dict:
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise MapFileError(f"{path} is not a readable JSON file: {err}") from err
    if not isinstance(d, dict):
        raise MapFileError(f"{path} is not a grasp file (its JSON is not an object)")
    return d


def _text(v) -> str | None:
    v = v.item() if isinstance(v, np.ndarray) and v.size == 1 else v
    return None if v is None else v.decode() if isinstance(v, bytes) else str(v)
