"""Map files: HDF5, ACRONYM-compatible (DESIGN.md §6), written atomically.

Layout (datasets, not attributes; N grasps)::

    grasps/transforms                 (N, 4, 4) wrist pose in the object frame
    grasps/qualities/analytic/grade   (N,)  and fc_angle [rad], force_closure (q_fc),
                                      stability (q_st), stability_distance [m]
    grasps/qualities/robust/score     (N,) robust score (expected success under pose error),
                                      feasible_fraction, clearance [m], extra_opening
                                      [m per side]; NaN where not
                                      scored (graspsim.maps.robust); the group's attribute
                                      ``provenance`` (JSON) says how; optional on reading
    grasps/qualities/mujoco/...       simulation results, once simulated
    graspability/wrist_position (N,3), wrist_quat (N,4) wxyz, grasp_point (N,3),
                 contacts (N,2,3), normals (N,2,3), width (N,), part (N,), accepted (N,)
    graspability/meta                 JSON: quality model, resolution, method, timing
    graspability/format               "graspsim-map-1"
    graspability/schema_version       1 (int; files without it are read as version 1)
    object/primitive (name), object/dims (JSON of named dims [m]), object/com (3,),
    object/mass, object/description (JSON), object/file + object/scale for meshes,
    object/T_cloud_obj (4, 4) for adapted maps (the object frame in the cloud's frame)
    gripper/type, gripper/configuration (JSON GripperSpec)

Loading validates the file (:func:`load_map`): every dataset present, one row count,
the trailing shapes, finite geometry and grades, unit quaternions, transforms that match
the wrist positions, and a schema version this code reads. A file that fails raises
:class:`MapFileError` naming the first problem.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim.errors import MapFileError
from graspsim.maps.graspmap import COLUMNS, GraspabilityMap, MapMeta

__all__ = ["save_map", "load_map", "write_sim_results", "read_sim_results", "FORMAT",
           "SCHEMA_VERSION"]

FORMAT = "graspsim-map-1"
SCHEMA_VERSION = 1  # written into every file; files without one are version 1
_BLOCK = 1 << 16  # rows per block when checking grasps/transforms (bounded memory)

# map column -> dataset path
_PATHS = {
    "grade": "grasps/qualities/analytic/grade",
    "fc_angle": "grasps/qualities/analytic/fc_angle",
    "q_fc": "grasps/qualities/analytic/force_closure",
    "q_st": "grasps/qualities/analytic/stability",
    "stability_distance": "grasps/qualities/analytic/stability_distance",
    "wrist_position": "graspability/wrist_position",
    "wrist_quat": "graspability/wrist_quat",
    "grasp_point": "graspability/grasp_point",
    "contacts": "graspability/contacts",
    "normals": "graspability/normals",
    "width": "graspability/width",
    "part": "graspability/part",
}
# optional columns (robust scores) -> dataset path; absent in older files (read as NaN)
_OPTIONAL_PATHS = {
    "robust": "grasps/qualities/robust/score",
    "robust_feasible": "grasps/qualities/robust/feasible_fraction",
    "clearance": "grasps/qualities/robust/clearance",
    "robust_extra_opening": "grasps/qualities/robust/extra_opening",
}


def _h5py():
    import h5py

    return h5py


def save_map(gmap: GraspabilityMap, path: str | os.PathLike, *, compression: str | None = "lzf") -> Path:
    """Write ``gmap`` to ``path`` atomically (temp file + rename). Returns the path.

    compression: HDF5 filter for the grasp arrays: "lzf" (default; maps repeat each
    closing line's data over rolls and depths, so files shrink ~5x), "gzip", or None.
    Readers need nothing special: h5py decompresses transparently. (No byte shuffling:
    it made files 6 % smaller but writing 35 % and reading 30 % slower.)
    """
    h5py = _h5py()
    path = Path(path)
    m = gmap.meta
    opts = {"compression": compression} if compression and len(gmap) else {}
    with atomic_path(path) as tmp:
        try:
            with h5py.File(tmp, "w") as f:
                f.create_dataset("grasps/transforms", data=gmap.wrist_transforms(np.float32), **opts)
                for col, dpath in _PATHS.items():
                    f.create_dataset(dpath, data=getattr(gmap, col), **opts)
                f.create_dataset("graspability/accepted", data=gmap.accepted, **opts)
                if gmap.has_robust:
                    for col, dpath in _OPTIONAL_PATHS.items():
                        f.create_dataset(dpath, data=getattr(gmap, col), **opts)
                    f["grasps/qualities/robust"].attrs["provenance"] = json.dumps(
                        m.extra.get("robust", {}), sort_keys=True)
                f["graspability/format"] = FORMAT
                f["graspability/schema_version"] = SCHEMA_VERSION
                f["graspability/meta"] = json.dumps(
                    {"quality": m.quality, "resolution": m.resolution, "method": m.method,
                     "timing": m.timing, "version": m.version, "extra": m.extra},
                    sort_keys=True,
                )
                obj = m.object
                f["object/description"] = json.dumps(obj, sort_keys=True)
                f["object/primitive"] = str(obj.get("primitive", "mesh"))
                f["object/dims"] = json.dumps(obj.get("dims", {}), sort_keys=True)
                f["object/com"] = np.asarray(obj.get("com", [0.0, 0.0, 0.0]), float)
                f["object/mass"] = float(obj.get("mass", np.nan))
                f["object/scale"] = float(obj.get("scale", 1.0))
                if "file" in obj:
                    f["object/file"] = str(obj["file"])
                if "T_cloud_obj" in m.extra:  # adapted maps: object frame in the cloud's frame
                    f["object/T_cloud_obj"] = np.asarray(m.extra["T_cloud_obj"], float)
                f["gripper/type"] = str(m.gripper.get("name", "unknown"))
                f["gripper/configuration"] = json.dumps(m.gripper, sort_keys=True)
        except OSError as err:
            raise MapFileError(f"cannot write map {path}: {err}") from err
    return path


def _open(path: Path, mode: str = "r"):
    h5py = _h5py()
    if not path.exists():
        raise MapFileError(f"map file {path} does not exist")
    try:
        return h5py.File(path, mode)
    except OSError as err:
        raise MapFileError(
            f"{path} is not a readable HDF5 map file (truncated or not HDF5): {err}"
        ) from err


_REQUIRED = ("grasps/transforms", *_PATHS.values(), "graspability/meta", "object/description",
             "gripper/configuration")


def load_map(path: str | os.PathLike, rows: slice | None = None) -> GraspabilityMap:
    """Read and validate a map written by :func:`save_map` (only ``rows``, a slice, if
    given: a partial read, validated for those rows); a foreign, damaged or corrupted
    file raises :class:`MapFileError` naming the problem."""
    path = Path(path)
    with _open(path) as f:
        n = _check_layout(f, path)
        sl = slice(None) if rows is None else rows
        try:
            cols = {col: f[dpath][sl] for col, dpath in _PATHS.items()}
            cols.update({col: f[dpath][sl] for col, dpath in _OPTIONAL_PATHS.items()
                         if dpath in f and f[dpath].shape[:1] == (n,)})
            meta, obj, grip = (_json_dict(f, k, path) for k in
                               ("graspability/meta", "object/description", "gripper/configuration"))
            _check_columns(cols, path)
            _check_transforms(f["grasps/transforms"], range(n)[sl], cols["wrist_position"], path)
        except MapFileError:
            raise
        except (OSError, KeyError, ValueError) as err:
            raise MapFileError(f"{path} is damaged: {err}") from err
    for k, kind in (("quality", dict), ("resolution", dict), ("method", str)):
        if not isinstance(meta.get(k), kind):
            raise MapFileError(f"{path} is damaged: graspability/meta has no {kind.__name__} {k!r}")
    return GraspabilityMap(
        **cols,
        meta=MapMeta(object=obj, gripper=grip, quality=meta["quality"],
                     resolution=meta["resolution"], method=meta["method"],
                     timing=meta.get("timing", {}), version=meta.get("version", ""),
                     extra=meta.get("extra", {})),
    )


def _check_layout(f, path: Path) -> int:
    """Datasets present, schema version readable, one row count; returns it."""
    missing = [p for p in _REQUIRED if p not in f]
    if missing:
        if "graspability/meta" in f:
            kind = "a damaged graspsim map"
        elif "grasps/transforms" in f:
            kind = "an ACRONYM-style grasp file without graspsim's map data"
        else:
            kind = "not a graspsim map"
        raise MapFileError(f"{path} is {kind}: missing {', '.join(missing[:4])}"
                           + (" ..." if len(missing) > 4 else ""))
    version = 1
    if "graspability/schema_version" in f:
        v = f["graspability/schema_version"][()]
        if not (np.ndim(v) == 0 and np.issubdtype(np.asarray(v).dtype, np.integer) and v >= 1):
            raise MapFileError(f"{path} is damaged: schema_version {v!r} is not a positive integer")
        version = int(v)
    if version > SCHEMA_VERSION:
        raise MapFileError(f"{path} has map schema version {version}; this graspsim reads "
                           f"versions up to {SCHEMA_VERSION} (upgrade graspsim)")
    lengths = {p: f[p].shape[0] if f[p].ndim else None for p in ("grasps/transforms", *_PATHS.values())}
    if len(set(lengths.values())) != 1:
        raise MapFileError(f"{path} is damaged: datasets have different row counts "
                           + ", ".join(f"{k} {v}" for k, v in list(lengths.items())[:3]) + " ...")
    if f["grasps/transforms"].shape[1:] != (4, 4):
        raise MapFileError(f"{path} is damaged: grasps/transforms has shape "
                           f"{f['grasps/transforms'].shape}, expected (N, 4, 4)")
    return int(lengths["grasps/transforms"])


def _json_dict(f, key: str, path: Path) -> dict:
    v = json.loads(_text(f[key][()]))
    if not isinstance(v, dict):
        raise MapFileError(f"{path} is damaged: {key} is not a JSON object")
    return v


def _check_transforms(dset, rows: range, wrist_position: np.ndarray, path: Path) -> None:
    """grasps/transforms (the ACRONYM view) finite, rigid-looking, and at the wrist
    positions; read in blocks so a million-grasp map needs no (N, 4, 4) copy."""
    bottom = np.array([0.0, 0.0, 0.0, 1.0], np.float32)
    step = rows.step
    for i in range(0, len(rows), _BLOCK):
        r = rows[i:i + _BLOCK]
        T = dset[r.start:r.stop:step] if len(r) else np.zeros((0, 4, 4), np.float32)
        if not np.isfinite(T).all():
            bad = i + int(np.flatnonzero(~np.isfinite(T).all(axis=(1, 2)))[0])
            raise MapFileError(f"{path} is corrupted: grasps/transforms has non-finite values "
                               f"(first at row {rows[bad]})")
        if not (np.all(T[:, 3] == bottom) and np.allclose(T[:, :3, 3], wrist_position[i:i + _BLOCK],
                                                          atol=1e-5)):
            raise MapFileError(f"{path} is corrupted: grasps/transforms disagree with "
                               "graspability/wrist_position (or are not rigid transforms)")


def _check_columns(cols: dict[str, np.ndarray], path: Path) -> None:
    for col, (shape, _) in COLUMNS.items():
        a = cols[col]
        if a.shape[1:] != shape:
            raise MapFileError(f"{path}: column {col} has shape {a.shape}, expected (N, *{shape})")
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            row = int(np.flatnonzero(~np.isfinite(a.reshape(len(a), -1)).all(axis=1))[0])
            raise MapFileError(f"{path} is corrupted: {_PATHS[col]} has non-finite values "
                               f"(first at row {row})")
    q = cols["wrist_quat"]
    if len(q) and np.abs(np.einsum("ij,ij->i", q, q) - 1.0).max() > 1e-3:
        raise MapFileError(f"{path} is corrupted: graspability/wrist_quat holds non-unit quaternions")


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def write_sim_results(path: str | os.PathLike, results: dict[str, np.ndarray],
                      group: str = "grasps/qualities/mujoco", attrs_json: dict | None = None) -> None:
    """Store per-grasp simulation results (arrays of length N) in a map file, atomically
    (the file is copied, extended and renamed back). ``attrs_json`` (protocol, params,
    MuJoCo version) is stored as the JSON dataset ``<group>/info``.

    Results are never lost: when the map cannot take them (it vanished, was damaged or
    replaced by another map during the simulation, the disk is full) they are saved to
    a ``.npz`` beside it (or in the temp folder) and the :class:`MapFileError` names it.
    """
    path = Path(path)
    try:
        with _open(path) as f:
            if _PATHS["grade"] not in f:
                raise MapFileError(f"{path} is no longer a graspsim map (no {_PATHS['grade']})")
            n = len(f[_PATHS["grade"]])
        for k, v in results.items():
            if len(v) != n:
                raise MapFileError(f"result {k!r} has {len(v)} rows, the map has {n} grasps")
        with atomic_path(path) as tmp:
            shutil.copyfile(path, tmp)
            with _open(tmp, "r+") as f:
                if group in f:
                    del f[group]
                g = f.create_group(group)
                for k, v in results.items():
                    g.create_dataset(k, data=np.asarray(v))
                if attrs_json is not None:
                    g["info"] = json.dumps(attrs_json, sort_keys=True)
    except (OSError, KeyError, ValueError) as err:
        saved = _save_results_aside(path, results, group, attrs_json)
        raise MapFileError(f"cannot store the results in {path}: {err}; they were saved to "
                           f"{saved} instead (numpy .npz, group {group!r})") from err


def _save_results_aside(path: Path, results: dict, group: str, attrs_json: dict | None) -> Path:
    """Write results that the map could not take to ``<map stem>.<group leaf>-<time>.npz``
    beside it, else in the temp folder; returns where."""
    import tempfile
    import time

    name = f"{path.stem}.{group.rsplit('/', 1)[-1]}-{time.strftime('%Y%m%d-%H%M%S')}.npz"
    extra = {"__group__": np.array(group), "__map__": np.array(str(path)),
             "__info__": np.array(json.dumps(attrs_json, sort_keys=True, default=str))}
    errors = []
    for folder in (path.parent, Path(tempfile.gettempdir())):
        target = folder / name
        try:
            with atomic_path(target) as tmp, open(tmp, "wb") as fh:
                np.savez(fh, **{k: np.asarray(v) for k, v in results.items()}, **extra)
            return target
        except OSError as err:
            errors.append(f"{target}: {err}")
    raise MapFileError(f"cannot store the results of {path} anywhere ({'; '.join(errors)})")


def read_sim_results(path: str | os.PathLike, group: str = "grasps/qualities/mujoco") -> dict:
    """Arrays stored by :func:`write_sim_results` (and ``info`` decoded); {} if none."""
    path = Path(path)
    with _open(path) as f:
        if group not in f:
            return {}
        out = {}
        for k, d in f[group].items():
            v = d[()]
            out[k] = json.loads(_text(v)) if k == "info" else v
        return out
