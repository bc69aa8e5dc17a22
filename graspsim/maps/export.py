"""A map written in third-party grasp formats: ACRONYM HDF5, GraspGen JSON, GraspNet arrays.

:func:`export_map` writes what each format's own reader loads, with graspsim's frame
conversion (:mod:`graspsim.maps.formats`) applied in reverse and recorded:

* ``acronym``: the layout ``acronym_tools.load_grasps`` reads (``grasps/transforms``,
  the hand's base-link poses in ACRONYM's Franka frame for the Franka hand, and
  ``grasps/qualities/flex/object_in_gripper``) and ``load_mesh`` reads (``object/file``,
  ``object/scale``). ``load_grasps`` hard-codes the ``flex`` path, so the labels go there
  whatever produced them; the root attribute ``graspsim`` (JSON) says which simulator
  (or method) did (``label_source``), with the frame and the gripper spec.
* ``graspgen``: GraspGen's dataset JSON (its GRASP_DATASET_FORMAT.md, NVlabs/GraspGen): object.file /
  scale, grasps.transforms (base link) and grasps.object_in_gripper (booleans: the mask
  its loader indexes with), plus a ``graspsim`` block.
* ``graspnet``: a ``GraspGroup.save_npy`` array (N, 17) in the object frame (the camera
  is the object frame: T_camera_obj = I), score = the label, width = the pre-grasp pad
  gap, height 2 cm (graspnetAPI's default), depth = the grasp's contact depth; a
  ``<stem>.json`` sidecar holds what the array cannot (mesh, labels, frame).

Labels (:func:`map_labels`): the MuJoCo lift-and-place outcome ``object_in_gripper`` when
the map file holds simulation results (rows not simulated: -1), else the dataset's own
labels of an imported map, else the analytic grade above the map's threshold. Each
exported file also carries graspsim's width, grade, opening and (float32) wrist position
per grasp, so reading it back restores them exactly. A primitive object is written as a mesh ``<stem>.obj`` beside
the output (the formats name their object by a mesh file).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_paths
from graspsim.errors import InvalidParameterError, MapFileError
from graspsim.maps.formats import FORMATS, grasp_frame, wrist_to_graspnet
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.imported import SOURCE_GROUP
from graspsim.maps.robust import executed_width
from graspsim.transforms import invert_transform

__all__ = ["export_map", "map_labels", "LABEL_CHOICES"]

LABEL_CHOICES = ("auto", "mujoco", "tug", "source", "grade")
_GRASPNET_HEIGHT = 0.02  # graspnetAPI's default Grasp height [m]


def map_labels(gmap: GraspabilityMap, path: str | os.PathLike | None, label: str = "auto") -> tuple[np.ndarray, str]:
    """((N,) int labels: 1 held / accepted, 0 not, -1 not simulated; where they came from)."""
    from graspsim.maps.io import read_sim_results

    if label not in LABEL_CHOICES:
        raise InvalidParameterError(f"label must be one of {list(LABEL_CHOICES)}, got {label!r}")
    groups = {"mujoco": "grasps/qualities/mujoco", "tug": "grasps/qualities/mujoco_tug", "source": SOURCE_GROUP}
    order = [label] if label != "auto" else ["mujoco", "source", "grade"]
    for name in order:
        if name == "grade":
            if not np.isfinite(gmap.grade).any():
                raise InvalidParameterError("the map has no grades (imported): label with mujoco, tug or source")
            return (gmap.grade > gmap.threshold).astype(np.int64), \
                f"graspsim analytic grade > {gmap.threshold:g} ({gmap.meta.quality.get('name', 'paper grade')})"
        res = read_sim_results(path, groups[name]) if path is not None else {}
        if "object_in_gripper" not in res:
            if label != "auto":
                raise InvalidParameterError(f"the map holds no {groups[name]}/object_in_gripper to label with")
            continue
        y = np.asarray(res["object_in_gripper"]).astype(np.int64)
        info = res.get("info", {}) or {}
        if "simulated" in res:
            y[~np.asarray(res["simulated"], bool)] = -1
        if name == "source":
            return y, str(info.get("label_source", "the imported dataset"))
        return y, _sim_source(info)
    raise InvalidParameterError("no labels")  # unreachable: grade ends the auto order


def _sim_source(info: dict) -> str:
    proto = (info.get("protocol") or {}).get("name", "?")
    scene = info.get("scene") or {}
    ver = scene.get("mujoco_version") or info.get("mujoco_version") or ""
    return f"MuJoCo {ver} via graspsim ({proto} protocol)".replace("  ", " ")


def export_map(gmap: GraspabilityMap, fmt: str, out: str | os.PathLike, *,
               map_path: str | os.PathLike | None = None, label: str = "auto",
               labels: tuple[np.ndarray, str] | None = None) -> list[Path]:
    """Write ``gmap`` (read from ``map_path``, whose simulation results give the labels)
    as ``fmt`` (``"acronym"``, ``"graspgen"``, ``"graspnet"``) to ``out``; returns the
    files written (the grasp file, then a sidecar or a primitive's mesh), all atomically.
    ``labels``: (N,) labels and their source, given (a dataset file's own)."""
    if fmt not in FORMATS:
        raise InvalidParameterError(f"format must be one of {list(FORMATS)}, got {fmt!r}")
    out = Path(out)
    labels, source = map_labels(gmap, map_path, label) if labels is None else \
        (np.asarray(labels[0]).astype(np.int64), labels[1])
    spec = gmap.meta.gripper_spec
    T_gw = grasp_frame(spec)
    opening = spec.pregrasp_opening(executed_width(gmap))
    obj = gmap.meta.object
    record = {"producer": _producer(), "label_source": source, "gripper_spec": spec.to_dict(),
              "physics": {"mass": float(obj.get("mass", np.nan)), "com": list(map(float, obj.get("com", [0, 0, 0]))),
                          "friction": float(gmap.meta.quality.get("friction", np.nan))},
              "T_grasp_wrist": T_gw.ravel().tolist(), "map_method": gmap.meta.method,
              "note": ("labels: 1 held, 0 not held, -1 not simulated; poses: the gripper's base link "
                       "(T_obj_grasp = T_obj_wrist inv(T_grasp_wrist))")}
    mesh_file, scale, mesh = _object_mesh(gmap, out)
    files = [out] + ([Path(mesh_file)] if mesh is not None else [])
    if fmt == "graspnet":
        files.insert(1, out.with_suffix(".json"))
    with atomic_paths(files, MapFileError) as tmps:
        rel = os.path.relpath(files[-1], out.parent) if mesh is not None else mesh_file
        cols = {"width": gmap.width, "grade": gmap.grade, "opening": opening,
                "wrist_position": gmap.wrist_position}
        if fmt == "acronym":
            _write_acronym(tmps[0], gmap, T_gw, labels, record, rel, scale, cols)
        elif fmt == "graspgen":
            _write_graspgen(tmps[0], gmap, T_gw, labels, record, rel, scale, cols)
        else:
            _write_graspnet(tmps[0], tmps[1], gmap, labels, record, rel, scale, cols)
        if mesh is not None:
            mesh.export(tmps[-1], file_type="obj")
    return files


def _producer() -> str:
    from graspsim._version import __version__

    return f"graspsim {__version__}"


def _object_mesh(gmap: GraspabilityMap, out: Path):
    """(the object's mesh file name for the grasp file, its scale, a mesh to write
    beside the output or None): a mesh object keeps its file (relative to the output's
    folder when it can be); a primitive is written as ``<out stem>.obj``."""
    obj = gmap.meta.object
    if obj.get("file"):
        f = Path(obj["file"])
        name = os.path.relpath(f, out.parent.resolve()) if f.is_absolute() else str(f)
        return name, float(obj.get("scale", 1.0)), None
    return str(out.with_suffix(".obj")), 1.0, gmap.meta.shape.mesh(sections=64)


def _base_link(gmap: GraspabilityMap, T_gw: np.ndarray) -> np.ndarray:
    return gmap.T_obj_wrist @ invert_transform(T_gw)


def _write_acronym(tmp: Path, gmap, T_gw, labels, record, mesh_file, scale, cols) -> None:
    # acronym_tools.load_grasps(filename) for .h5 reads exactly:
    #   T = np.array(data["grasps/transforms"]); success = np.array(data["grasps/qualities/flex/object_in_gripper"])
    # and load_mesh reads data["object/file"][()].decode('utf-8') and data["object/scale"][()]
    import h5py

    obj = gmap.meta.object
    spec = gmap.meta.gripper_spec
    with h5py.File(tmp, "w") as f:
        f["grasps/transforms"] = _base_link(gmap, T_gw)
        f["grasps/qualities/flex/object_in_gripper"] = labels
        for k, v in cols.items():
            f[f"grasps/graspsim/{k}"] = np.asarray(v, np.float64)
        f["object/file"] = np.bytes_(mesh_file.encode("utf-8"))
        f["object/scale"] = float(scale)
        f["object/com"] = np.asarray(obj.get("com", [0.0, 0.0, 0.0]), float)
        f["object/mass"] = float(obj.get("mass", np.nan))
        f["object/friction"] = float(gmap.meta.quality.get("friction", np.nan))
        f["gripper/type"] = np.bytes_(("panda" if spec.model == "franka_hand" else spec.name).encode())
        f["gripper/configuration"] = np.array([spec.max_opening / 2.0])
        f.attrs["graspsim"] = json.dumps(record, sort_keys=True)


def _write_graspgen(tmp: Path, gmap, T_gw, labels, record, mesh_file, scale, cols) -> None:
    doc = {"object": {"file": mesh_file, "scale": float(scale)},
           "grasps": {"transforms": _base_link(gmap, T_gw).tolist(),
                      "object_in_gripper": (labels == 1).tolist()},
           "graspsim": {**record, "labels": {"object_in_gripper": labels.tolist()},
                        "columns": {k: np.asarray(v, float).tolist() for k, v in cols.items()}}}
    tmp.write_text(json.dumps(doc))


def _write_graspnet(tmp: Path, side: Path, gmap, labels, record, mesh_file, scale, cols) -> None:
    spec = gmap.meta.gripper_spec
    gp = gmap.grasp_point.astype(float)
    R_G, centre, depth = wrist_to_graspnet(gmap.T_obj_wrist, gp, spec)
    a = np.zeros((len(gmap), 17))
    a[:, 0] = labels
    a[:, 1] = cols["opening"]
    a[:, 2] = _GRASPNET_HEIGHT
    a[:, 3] = depth
    a[:, 4:13] = R_G.reshape(-1, 9)
    a[:, 13:16] = centre
    a[:, 16] = 0
    with open(tmp, "wb") as fh:
        np.save(fh, a)
    meta = {**record, "frame": "object (T_camera_obj = identity)", "object": {"file": mesh_file, "scale": scale},
            "labels": {"object_in_gripper": labels.tolist()},
            "columns": {k: np.asarray(v, float).tolist() for k, v in cols.items()},
            "T_grasp_wrist": None}
    meta.pop("T_grasp_wrist")
    side.write_text(json.dumps({"graspsim": meta}))
