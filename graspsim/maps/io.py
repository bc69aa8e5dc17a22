"""Map files: HDF5, ACRONYM-compatible (docs/design.md §6), written atomically.

Layout (datasets, not attributes; N grasps)::

    grasps/transforms                 (N, 4, 4) wrist pose in the object frame
    grasps/qualities/analytic/grade   (N,)  and fc_angle [rad], force_closure (q_fc),
                                      stability (q_st), stability_distance [m]
    grasps/qualities/robust/score     (N,) robust score (expected success under pose error),
                                      feasible_fraction, clearance [m], extra_opening
                                      [m per side]; NaN where not
                                      scored (graspsim.maps.robust); the group's attribute
                                      ``provenance`` (JSON) says how; optional on reading
    grasps/qualities/reach/reachable  (N,) whether an arm reaches the grasp (1 exact check,
                                      0.5 first cut only, 0 unreachable, NaN unchecked;
                                      graspsim.robots.mark_reach); attribute ``provenance``
                                      (JSON: the arm, its base, the object's pose); optional
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

Text (names, JSON) is stored as fixed-length UTF-8 strings; files that hold it as
variable-length strings (earlier versions) read the same.

Loading validates the file (:func:`load_map`): its layout here -- every dataset present
and numeric, one row count, the trailing shapes, transforms that match the wrist
positions, a schema version this code reads, rows that fit the memory budget -- and
the map it holds with :func:`~graspsim.maps.validate.map_problems` (finite columns in
range, unit quaternions, a valid object, gripper and quality model). A file that fails
raises :class:`MapFileError` naming the first problem.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from graspsim._atomic import atomic_path
from graspsim.errors import GraspsimError, MapFileError
from graspsim.maps.graspmap import COLUMNS, GraspabilityMap, MapMeta

__all__ = ["save_map", "load_map", "write_sim_results", "read_sim_results", "write_reach", "FORMAT",
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
_REACH_PATH = "grasps/qualities/reach/reachable"
# optional columns (robust scores, reachability) -> dataset path; absent in older files (read as NaN)
_OPTIONAL_PATHS = {
    "robust": "grasps/qualities/robust/score",
    "robust_feasible": "grasps/qualities/robust/feasible_fraction",
    "clearance": "grasps/qualities/robust/clearance",
    "robust_extra_opening": "grasps/qualities/robust/extra_opening",
    "reachable": _REACH_PATH,
}


def _h5py():
    import h5py

    return h5py


#: The extensions a map file may have (HDF5).
MAP_SUFFIXES = (".h5", ".hdf5")


def check_map_suffix(path: str | os.PathLike, error=None) -> Path:
    """``path`` as a Path, unless its extension is not a map file's (:data:`MAP_SUFFIXES`):
    then ``error`` (default :class:`~graspsim.errors.OutputPathError`) -- an HDF5 map
    written to ``cyl.txt`` or ``cyl.png`` is a mistake caught before the work."""
    from graspsim.errors import OutputPathError

    path = Path(path)
    if path.suffix.lower() not in MAP_SUFFIXES:
        raise (error or OutputPathError)(
            f"cannot write a map to {path}: a map file is HDF5, its name ends in "
            f"{' or '.join(MAP_SUFFIXES)} (got {path.suffix or 'no extension'!r})")
    return path


def check_map_output(path: str | os.PathLike, *, others: dict | None = None) -> Path:
    """The checks before a command writes a map to ``path``: a writable file
    (:func:`~graspsim._atomic.check_output`) with a map file's extension."""
    from graspsim._atomic import check_output

    return check_map_suffix(check_output(path, "map", others=others))


def save_map(gmap: GraspabilityMap, path: str | os.PathLike, *, compression: str | None = "lzf") -> Path:
    """Write ``gmap`` to ``path`` atomically (temp file + rename). Returns the path.

    The name must end in .h5 or .hdf5 (:func:`check_map_suffix`).
    compression: HDF5 filter for the grasp arrays: "lzf" (default; maps repeat each
    closing line's data over rolls and depths, so files shrink ~5x), "gzip", or None.
    Readers need nothing special: h5py decompresses transparently. (No byte shuffling:
    it made files 6 % smaller but writing 35 % and reading 30 % slower.)
    """
    h5py = _h5py()
    path = check_map_suffix(path, MapFileError)
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
                        if col != "reachable":
                            f.create_dataset(dpath, data=getattr(gmap, col), **opts)
                    f["grasps/qualities/robust"].attrs["provenance"] = json.dumps(
                        m.extra.get("robust", {}), sort_keys=True)
                if gmap.has_reach:
                    f.create_dataset(_REACH_PATH, data=gmap.reachable, **opts)
                    f["grasps/qualities/reach"].attrs["provenance"] = json.dumps(
                        m.extra.get("reach", {}), sort_keys=True)
                f["graspability/format"] = _fixed(FORMAT)
                f["graspability/schema_version"] = SCHEMA_VERSION
                f["graspability/meta"] = _fixed(json.dumps(
                    {"quality": m.quality, "resolution": m.resolution, "method": m.method,
                     "timing": m.timing, "version": m.version, "extra": m.extra},
                    sort_keys=True,
                ))
                obj = m.object
                f["object/description"] = _fixed(json.dumps(obj, sort_keys=True))
                f["object/primitive"] = _fixed(str(obj.get("primitive", "mesh")))
                f["object/dims"] = _fixed(json.dumps(obj.get("dims", {}), sort_keys=True))
                f["object/com"] = np.asarray(obj.get("com", [0.0, 0.0, 0.0]), float)
                f["object/mass"] = float(obj.get("mass", np.nan))
                f["object/scale"] = float(obj.get("scale", 1.0))
                if "file" in obj:
                    f["object/file"] = _fixed(str(obj["file"]))
                if "T_cloud_obj" in m.extra:  # adapted maps: object frame in the cloud's frame
                    f["object/T_cloud_obj"] = np.asarray(m.extra["T_cloud_obj"], float)
                f["gripper/type"] = _fixed(str(m.gripper.get("name", "unknown")))
                f["gripper/configuration"] = _fixed(json.dumps(m.gripper, sort_keys=True))
        except OSError as err:
            raise MapFileError(f"cannot write map {path}: {err}") from err
    return path


def _open(path: Path, mode: str = "r"):
    h5py = _h5py()
    try:
        if not path.exists():
            raise MapFileError(f"map file {path} does not exist")
        if not path.is_file():
            raise MapFileError(f"{path} is not a map file (it is a folder or a device)")
        return h5py.File(path, mode)
    except OSError as err:
        if isinstance(err, MapFileError):
            raise
        raise MapFileError(f"{path} is not a readable HDF5 map file (truncated or not HDF5): "
                           + " ".join(str(err).split())) from err  # h5py's messages span lines


@contextlib.contextmanager
def _damaged(path: Path):
    """Errors h5py raises on a damaged file (flipped bytes in its metadata surface as
    KeyError, RuntimeError, ValueError ...) as one :class:`MapFileError`."""
    try:
        yield
    except MapFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError, AttributeError) as err:
        raise MapFileError(f"{path} is damaged: {' '.join(str(err).split())}") from err


_REQUIRED = ("grasps/transforms", *_PATHS.values(), "graspability/meta", "object/description",
             "gripper/configuration")


def load_map(path: str | os.PathLike, rows: slice | None = None, *,
             verify_transforms: bool = True) -> GraspabilityMap:
    """Read and validate a map written by :func:`save_map` (only ``rows``, a slice, if
    given: a partial read, validated for those rows). The file's layout is checked here
    (datasets present and numeric, one row count, the trailing shapes, the schema
    version, transforms at the wrist positions, memory to hold the rows); the map's
    own invariants by :func:`~graspsim.maps.validate.map_problems`. A foreign, damaged
    or corrupted file raises :class:`MapFileError` naming the first problem.

    verify_transforms: read ``grasps/transforms`` (the ACRONYM view, which graspsim
    itself never uses) and check it against the wrist positions -- a third of the load
    time of a large map. The map database turns it off for its own maps, validated
    when stored; ``graspsim db check`` verifies them in full."""
    from graspsim.maps.validate import map_problems

    path = Path(path)
    with _open(path) as f, _damaged(path):
        n = _check_layout(f, path)
        sl = slice(None) if rows is None else rows
        _check_memory(f, len(range(n)[sl]), path)
        cols = {col: f[dpath][sl] for col, dpath in _PATHS.items()}
        cols.update({col: f[dpath][sl] for col, dpath in _OPTIONAL_PATHS.items()
                     if dpath in f and f[dpath].shape[:1] == (n,)})
        meta, obj, grip = (_json_dict(f, k, path) for k in
                           ("graspability/meta", "object/description", "gripper/configuration"))
        if verify_transforms:
            _check_transforms(f["grasps/transforms"], range(n)[sl], cols["wrist_position"], path)
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # values beyond float32: caught below
            gmap = GraspabilityMap(
                **cols,
                meta=MapMeta(object=obj, gripper=grip, quality=meta.get("quality"),
                             resolution=meta.get("resolution"), method=meta.get("method"),
                             timing=meta.get("timing", {}), version=meta.get("version", ""),
                             extra=meta.get("extra", {})))
    except (GraspsimError, ValueError, TypeError, OverflowError) as err:
        raise MapFileError(f"{path} is damaged: {err}") from err
    problems = map_problems(gmap, allow_empty=True)
    if problems:
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise MapFileError(f"{path} is corrupted: {problems[0]}{more}")
    return gmap


def _check_layout(f, path: Path) -> int:
    """Datasets present and numeric, schema version readable, one row count; returns it."""
    h5py = _h5py()
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
    ds = {p: f[p] for p in _REQUIRED}  # each object opened once (h5py opens it on every f[p])
    not_data = [p for p in _REQUIRED if not isinstance(ds[p], h5py.Dataset)]
    if not_data:
        raise MapFileError(f"{path} is damaged: {', '.join(not_data[:3])} is not a dataset")
    version = 1
    if "graspability/schema_version" in f:
        v = f["graspability/schema_version"][()] if isinstance(f["graspability/schema_version"], h5py.Dataset) else None
        if not (np.ndim(v) == 0 and np.issubdtype(np.asarray(v).dtype, np.integer) and v >= 1):
            raise MapFileError(f"{path} is damaged: schema_version {v!r} is not a positive integer")
        version = int(v)
    if version > SCHEMA_VERSION:
        raise MapFileError(f"{path} has map schema version {version}; this graspsim reads "
                           f"versions up to {SCHEMA_VERSION} (upgrade graspsim)")
    grasp_data = ("grasps/transforms", *_PATHS.values())
    shapes = {p: ds[p].shape for p in grasp_data}
    lengths = {p: shapes[p][0] if len(shapes[p]) else None for p in grasp_data}
    if len(set(lengths.values())) != 1 or None in lengths.values():
        raise MapFileError(f"{path} is damaged: datasets have different row counts "
                           + ", ".join(f"{k} {v}" for k, v in list(lengths.items())[:3]) + " ...")
    expected = {"grasps/transforms": (4, 4), **{d: COLUMNS[c][0] for c, d in _PATHS.items()}}
    for p in grasp_data:
        if shapes[p][1:] != expected[p]:
            want = "(N" + "".join(f", {k}" for k in expected[p]) + ")"
            raise MapFileError(f"{path} is damaged: {p} has shape {shapes[p]}, expected {want}")
        if ds[p].dtype.kind not in "biuf":
            raise MapFileError(f"{path} is damaged: {p} holds {ds[p].dtype} values, not real numbers")
    return int(lengths["grasps/transforms"])


def _check_memory(f, n: int, path: Path) -> None:
    """Refuse to read ``n`` rows whose columns (and their float32 copies) would not fit
    the memory budget: a small file can claim billions of rows (chunks never written)."""
    from graspsim.maps.preflight import check_bytes

    per_row = sum(f[d].dtype.itemsize * int(np.prod(f[d].shape[1:])) for d in _PATHS.values())
    check_bytes(2 * n * per_row, f"reading {n:,} grasps of {path}",
                "read part of it (load_map(path, rows=slice(...)))")


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
        wrist = wrist_position[i:i + _BLOCK]
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite rows: map_problems names them
            near = (np.abs(T[:, :3, 3] - wrist) <= 1e-5 + 1e-5 * np.abs(T[:, :3, 3])) | ~np.isfinite(wrist)
        if not (np.all(T[:, 3] == bottom) and np.all(near)):
            raise MapFileError(f"{path} is corrupted: grasps/transforms disagree with "
                               "graspability/wrist_position (or are not rigid transforms)")


def _fixed(text: str) -> np.bytes_:
    """``text`` as a fixed-length UTF-8 string dataset value. Variable-length strings live
    in HDF5's global heap, whose parser in libhdf5 can loop forever on one damaged byte
    (found by the fuzz suite); fixed-length ones are stored in the dataset itself."""
    return np.bytes_(text.encode("utf-8"))


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
                    g["info"] = _fixed(json.dumps(attrs_json, sort_keys=True))
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as err:  # h5py on a damaged file
        saved = _save_results_aside(path, results, group, attrs_json)
        raise MapFileError(f"cannot store the results in {path}: {err}; they were saved to "
                           f"{saved} instead (numpy .npz, group {group!r})") from err


def write_reach(path: str | os.PathLike, reachable: np.ndarray, record: dict) -> None:
    """Store the ``reachable`` column (N,) of the map file ``path`` and its provenance
    ``record`` (the arm, its base, the object's pose; also ``meta.extra["reach"]``),
    atomically: the file is copied, updated and renamed back, so a failure leaves it as
    it was, every other group (trial results) kept. A column of another length than the
    map's rows raises :class:`MapFileError` with nothing written."""
    path = Path(path)
    reachable = np.asarray(reachable, np.float32).reshape(-1)
    try:
        with _open(path) as f, _damaged(path):
            if _PATHS["grade"] not in f or "graspability/meta" not in f:
                raise MapFileError(f"{path} is not a graspsim map (no {_PATHS['grade']})")
            n = len(f[_PATHS["grade"]])
        if len(reachable) != n:
            raise MapFileError(f"reachable has {len(reachable)} rows, the map {path} has {n} grasps")
        with atomic_path(path) as tmp:
            shutil.copyfile(path, tmp)
            with _open(tmp, "r+") as f:
                meta = _json_dict(f, "graspability/meta", path)
                meta["extra"] = {**meta.get("extra", {}), "reach": record}
                del f["graspability/meta"]
                f["graspability/meta"] = _fixed(json.dumps(meta, sort_keys=True))
                if _REACH_PATH in f:
                    del f[_REACH_PATH]
                f.create_dataset(_REACH_PATH, data=reachable, **({"compression": "lzf"} if n else {}))
                f["grasps/qualities/reach"].attrs["provenance"] = json.dumps(record, sort_keys=True)
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as err:  # h5py on a damaged file
        raise MapFileError(f"cannot store the reachability in {path}: {' '.join(str(err).split())}") from err


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
    with _open(path) as f, _damaged(path):
        if group not in f:
            return {}
        out = {}
        for k, d in f[group].items():
            v = d[()]
            out[k] = json.loads(_text(v)) if k == "info" else v
        return out
