"""Map-file corruptions: deleted or reshaped datasets, changed dtypes, NaN/inf injected,
a wrong schema_version, broken JSON metadata, datasets claiming many rows, truncated
files, flipped bytes, and files that are not maps at all under a ``.h5`` name.

:func:`corruptions` draws a list of operations (plain tuples); :func:`apply` performs
them on a copy of a valid map file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
from hypothesis import strategies as st

GRASP_DATASETS = ["grasps/transforms", "grasps/qualities/analytic/grade", "grasps/qualities/analytic/fc_angle",
                  "grasps/qualities/analytic/force_closure", "grasps/qualities/analytic/stability",
                  "grasps/qualities/analytic/stability_distance", "graspability/wrist_position",
                  "graspability/wrist_quat", "graspability/grasp_point", "graspability/contacts",
                  "graspability/normals", "graspability/width", "graspability/part", "graspability/accepted"]
OTHER_DATASETS = ["graspability/meta", "graspability/format", "graspability/schema_version",
                  "object/description", "object/primitive", "object/dims", "object/com", "object/mass",
                  "object/scale", "gripper/type", "gripper/configuration"]
JSON_DATASETS = ["graspability/meta", "object/description", "gripper/configuration"]
_VALUES = [float("nan"), float("inf"), -float("inf"), 1e30, -1e30, 0.0, -1.0, 1e-30]
_JSON_VALUES = [None, -1, 0, "x", float("nan"), [], {}, 1e308, True, [1, 2, 3]]
_JSON_TEXT = ["", "{", "[]", "null", "NaN", "1", '"text"', '{"a": 1}', "\x01", "{}" * 3]  # (HDF5 holds no NUL)


def _op(draw):
    kind = draw(st.sampled_from(["delete", "delete", "rows", "trailing", "scalar", "dtype", "inject", "inject",
                                 "inject", "inject", "group", "schema", "json", "json", "json_text", "truncate",
                                 "flip", "replace", "huge_rows", "transpose"]))
    ds = draw(st.sampled_from(GRASP_DATASETS + OTHER_DATASETS))
    grasp_ds = draw(st.sampled_from(GRASP_DATASETS))
    if kind == "delete":
        return ("delete", ds)
    if kind == "rows":
        return ("rows", grasp_ds, draw(st.sampled_from(["none", "one", "one less", "one more"])))
    if kind in ("trailing", "scalar", "group", "transpose"):
        return (kind, ds)
    if kind == "dtype":
        return ("dtype", ds, draw(st.sampled_from(["S8", "i8", "?", "c8", "f2", "f8", "u1", "str"])))
    if kind == "inject":
        return ("inject", grasp_ds, draw(st.sampled_from(_VALUES)), draw(st.floats(0, 1)))
    if kind == "schema":
        return ("schema", draw(st.sampled_from([0, -1, 2, 99, "1", 1.5, [1, 2], True, 2**62, -2**62])))
    if kind == "json":
        return ("json", draw(st.sampled_from(JSON_DATASETS)), draw(st.integers(0, 50)),
                draw(st.sampled_from(["delete", "set", "set", "nested"])), draw(st.sampled_from(_JSON_VALUES)))
    if kind == "json_text":
        return ("json_text", draw(st.sampled_from(JSON_DATASETS)), draw(st.sampled_from(_JSON_TEXT)))
    if kind == "truncate":
        return ("truncate", draw(st.floats(0, 1)))
    if kind == "flip":
        return ("flip", draw(st.integers(1, 16)), draw(st.integers(0, 2**32 - 1)))
    if kind == "huge_rows":
        return ("huge_rows", draw(st.sampled_from([10**4, 10**5, 10**6])))
    return ("replace", draw(st.sampled_from(["random", "empty", "text", "hdf5_empty", "hdf5_other", "directory"])))


@st.composite
def corruptions(draw) -> dict:
    base = draw(st.sampled_from(["hand", "hand", "real"]))
    ops = [_op(draw) for _ in range(draw(st.integers(1, 3)))]
    return {"label": f"{base}: " + "; ".join(str(o[:2]) for o in ops), "base": base, "ops": ops}


# ------------------------------------------------------------------ applying
def _rewrite(f, name: str, data) -> None:
    del f[name]
    f[name] = data


def _json_edit(f, name: str, pick: int, how: str, value) -> None:
    try:
        d = json.loads(f[name][()])
    except (ValueError, TypeError):
        return
    if not isinstance(d, dict) or not d:
        return
    key = sorted(d)[pick % len(d)]
    if how == "delete":
        del d[key]
    elif how == "set":
        d[key] = value
    elif isinstance(d[key], dict) and d[key]:  # nested: one level down
        sub = sorted(d[key])[pick % len(d[key])]
        d[key][sub] = value
    _rewrite(f, name, json.dumps(d))


def _h5_op(f, op) -> None:
    kind, name = op[0], op[1] if len(op) > 1 else None
    if kind in ("delete", "rows", "trailing", "scalar", "dtype", "inject", "group", "transpose",
                "json", "json_text") and (name not in f or not isinstance(f[name], h5py.Dataset)):
        return
    if kind == "delete":
        del f[name]
    elif kind == "rows":
        a = np.asarray(f[name][()])
        n = len(a) if a.ndim else 1
        k = {"none": 0, "one": 1, "one less": max(n - 1, 0), "one more": n + 1}[op[2]]
        _rewrite(f, name, np.resize(a, (k, *a.shape[1:])))
    elif kind == "trailing":
        a = np.asarray(f[name][()])
        _rewrite(f, name, np.stack([a, a], axis=-1) if a.ndim else np.array([a, a]))
    elif kind == "scalar":
        _rewrite(f, name, 1.0)
    elif kind == "transpose":
        a = f[name][()]
        _rewrite(f, name, a.T.copy() if np.ndim(a) >= 2 else a)
    elif kind == "dtype":
        a = f[name][()]
        if op[2] == "str":
            _rewrite(f, name, np.array([str(x) for x in np.ravel(a)], dtype=h5py.string_dtype()))
        else:
            with np.errstate(all="ignore"):
                try:
                    _rewrite(f, name, np.asarray(a).astype(op[2]))
                except (ValueError, TypeError):
                    pass
    elif kind == "inject":
        a = np.asarray(f[name][()])
        if a.size and a.dtype.kind == "f":
            a.reshape(-1)[int(op[3] * (a.size - 1))] = op[2]
            _rewrite(f, name, a)
    elif kind == "group":
        del f[name]
        f.create_group(name)
    elif kind == "schema":
        if "graspability/schema_version" in f:
            del f["graspability/schema_version"]
        f["graspability/schema_version"] = op[1]
    elif kind == "json":
        _json_edit(f, name, *op[2:])
    elif kind == "json_text":
        _rewrite(f, name, op[2])
    elif kind == "huge_rows":  # every per-grasp dataset claims n rows; nothing stored
        for ds in GRASP_DATASETS:
            if ds in f and isinstance(f[ds], h5py.Dataset):
                shape, dtype = f[ds].shape, f[ds].dtype
                del f[ds]
                f.create_dataset(ds, shape=(op[1], *shape[1:]), dtype=dtype, chunks=(1024, *shape[1:]))


def _bytes_op(path: Path, op) -> None:
    kind = op[0]
    if kind == "truncate" and path.is_file():
        data = path.read_bytes()
        path.write_bytes(data[: int(op[1] * len(data))])
    elif kind == "flip" and path.is_file():
        rng = np.random.default_rng(op[2])
        b = bytearray(path.read_bytes())
        if b:
            for i in rng.integers(0, len(b), op[1]):
                b[i] ^= int(rng.integers(1, 256))
            path.write_bytes(bytes(b))
    elif kind == "replace":
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
        what = op[1]
        if what == "random":
            path.write_bytes(np.random.default_rng(len(str(path))).bytes(3000))
        elif what == "empty":
            path.write_bytes(b"")
        elif what == "text":
            path.write_text("this is not a map\n")
        elif what == "directory":
            path.mkdir()
        else:
            with h5py.File(path, "w") as f:
                if what == "hdf5_other":
                    f["data"] = np.arange(10.0)
                    f.create_group("grasps")


def apply(base: Path, target: Path, ops) -> Path:
    """Copy ``base`` to ``target`` and damage it by ``ops``; returns ``target``."""
    shutil.copyfile(base, target)
    h5_ops = [o for o in ops if o[0] not in ("truncate", "flip", "replace")]
    if h5_ops:
        with h5py.File(target, "r+") as f:
            for op in h5_ops:
                _h5_op(f, op)
    for op in ops:
        if op[0] in ("truncate", "flip", "replace"):
            _bytes_op(target, op)
    return target
