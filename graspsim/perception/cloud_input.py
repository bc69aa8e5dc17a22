"""Reading point clouds from disk: PCL ``.pcd``, ``.ply``, ``.npy`` and ``.xyz``/``.txt``.

Only the x, y, z coordinates are kept, in metres (``units`` converts millimetres or
centimetres; a cloud too wide for metres is refused, naming the likely unit). Points
with a NaN or infinite coordinate (organised RGB-D clouds mark missing depth that way)
are dropped and counted. :func:`check_cloud` rejects clouds no model can be fitted to.

Supported encodings: PCD ``DATA ascii | binary | binary_compressed`` (LZF, decoded here
in pure Python); PLY ``ascii | binary_little_endian | binary_big_endian`` (the vertex
element; elements before it may not contain list properties); ``.npy`` arrays of shape
(N, 3); text files with at least three whitespace- or comma-separated columns.
"""

from __future__ import annotations

import json
import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graspsim.errors import PointCloudError
from graspsim.geometry.camera import Camera
from graspsim.perception.prepare import MAX_EXTENT, as_coordinates, canonical_points, check_extent, to_metres

__all__ = ["LoadedCloud", "read_point_cloud", "read_camera", "check_cloud", "lzf_decompress", "MIN_POINTS"]

log = logging.getLogger(__name__)

#: Fewest points any primitive model needs to be fitted and judged.
MIN_POINTS = 10

_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
              ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


@dataclass(frozen=True)
class LoadedCloud:
    """points: (N, 3) float64, finite, file frame [m], canonical
    (:func:`~graspsim.perception.prepare.canonical_points`: float32, 1 µm grid); n_dropped: points removed for a
    NaN/inf coordinate; n_read: points in the file; fmt: e.g. ``pcd/binary``; units:
    of the file's coordinates (converted to metres); viewpoint: (3,) where the cloud was
    seen from, file frame [m], when a camera record (``<file>.json``, written by
    :func:`graspsim.tabletop.cloud_io.save_cloud`) or a PCD file's ``VIEWPOINT`` header
    (its translation; the default ``0 0 0 1 0 0 0`` that PCL writes for every cloud,
    merged ones too, says nothing) says so, else None (unknown: the planner's
    robust score then adds no occlusion term); rows: (N,) the file row of each point
    (None: every row, in order).
    """

    points: np.ndarray
    n_dropped: int
    n_read: int
    path: str
    fmt: str
    units: str = "m"
    viewpoint: np.ndarray | None = None
    rows: np.ndarray | None = None


def read_point_cloud(path: str | Path, *, min_points: int = MIN_POINTS, units: str = "m",
                     max_extent: float = MAX_EXTENT, what: str = "one graspable object") -> LoadedCloud:
    """Read a cloud file whose coordinates are in ``units`` ("m", "cm", "mm"), drop
    non-finite points, convert to metres and validate with :func:`check_cloud` (a
    cloud wider than ``max_extent`` metres is refused as ``what`` in other units)."""
    path = Path(path)
    to_metres(np.zeros((0, 3)), units)  # an unknown unit fails before reading
    try:
        is_file = path.is_file()
    except OSError as err:  # e.g. a name too long
        raise PointCloudError(f"cannot read point cloud file {str(path)!r}: {err.strerror or err}") from err
    if not is_file:
        raise PointCloudError(f"point cloud file {str(path)!r} does not exist or is not a file")
    suffix = path.suffix.lower()
    readers = {".pcd": _read_pcd, ".ply": _read_ply, ".npy": _read_npy, ".xyz": _read_text,
               ".txt": _read_text, ".csv": _read_text}
    if suffix not in readers:
        raise PointCloudError(
            f"{path.name}: unknown point cloud format {suffix!r}; valid: {sorted(readers)}"
        )
    try:
        xyz, fmt, *header_view = readers[suffix](path)
    except PointCloudError as err:
        raise PointCloudError(f"{path.name}: {err}") from None
    except (OSError, ValueError, EOFError, UnicodeDecodeError) as err:  # EOFError: np.load of an empty file
        raise PointCloudError(f"{path.name}: cannot read {suffix} file: {err}") from err
    except (IndexError, KeyError) as err:  # a header line cut short or garbled
        raise PointCloudError(f"{path.name}: malformed {suffix} header ({type(err).__name__}: {err})") from err
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    finite = np.all(np.isfinite(xyz), axis=1)
    n_drop = int(len(xyz) - finite.sum())
    if n_drop:
        log.info("%s: dropped %d of %d points with NaN/inf coordinates", path.name, n_drop, len(xyz))
    pts = np.ascontiguousarray(canonical_points(to_metres(xyz[finite], units)))
    try:
        check_cloud(pts, min_points=min_points, max_extent=max_extent, what=what)
    except PointCloudError as err:
        extra = f" ({n_drop} of {len(xyz)} points were NaN/inf)" if n_drop else ""
        raise PointCloudError(f"{path.name}: {err}{extra}") from None
    view = _viewpoint(path)
    if view is None and header_view and header_view[0] is not None:
        view = to_metres(header_view[0][None], units)[0]
    return LoadedCloud(pts, n_drop, len(xyz), str(path), fmt, str(units).lower(), view,
                       np.flatnonzero(finite) if n_drop else None)


def _viewpoint(path: Path) -> np.ndarray | None:
    """The camera's position in the cloud's frame from the record beside ``path`` (metres,
    as ``save_cloud`` writes it): the origin for points in the camera frame, the camera's
    position for world points."""
    if not Path(str(path) + ".json").is_file():
        return None
    camera, frame = read_camera(path)
    return np.zeros(3) if frame == "camera" else np.array(camera.T_world_camera[:3, 3], float)


def read_camera(path: str | os.PathLike):
    """(camera, points frame) recorded beside the cloud at ``path`` (its ``<path>.json``)."""
    side = Path(str(path) + ".json")
    try:
        record = json.loads(side.read_text())
        return Camera.from_dict(record["camera"]), record["points_frame"]
    except FileNotFoundError:
        raise PointCloudError(f"no camera record {side} beside the cloud") from None
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise PointCloudError(f"unreadable camera record {side}: {err}") from err


def check_cloud(points: np.ndarray, *, min_points: int = MIN_POINTS, max_extent: float = MAX_EXTENT,
                what: str = "one graspable object") -> np.ndarray:
    """Validate a cloud: (N, 3), finite, at least ``min_points`` points, not all identical
    (spread above 1 µm), plausible in metres for ``what`` (at most ``max_extent`` wide;
    :func:`~graspsim.perception.prepare.check_extent`). Returns it as a float64 array;
    raises :class:`PointCloudError`."""
    p = as_coordinates(points)
    if p.ndim != 2 or p.shape[1] != 3:
        raise PointCloudError(f"points must have shape (N, 3), got {p.shape}")
    if len(p) == 0:
        raise PointCloudError("the cloud is empty (0 points)")
    if not np.all(np.isfinite(p)):
        raise PointCloudError(f"{int(np.sum(~np.isfinite(p).all(1)))} points have NaN/inf coordinates")
    if len(p) < min_points:
        raise PointCloudError(f"the cloud has {len(p)} points; at least {min_points} are needed")
    if float(np.max(np.ptp(p, axis=0))) < 1e-6:
        raise PointCloudError(f"all {len(p)} points are identical (spread < 1 µm)")
    check_extent(p, max_extent=max_extent, what=what)
    return p


# ---------------------------------------------------------------------------- PCD
def _pcd_viewpoint(vals: list[str] | None) -> np.ndarray | None:
    """The translation of a PCD ``VIEWPOINT tx ty tz qw qx qy qz`` line (the sensor's
    position in the cloud's frame), None for none or PCL's default (the origin with no
    rotation: written for every cloud, so it says nothing)."""
    if not vals:
        return None
    try:
        v = np.array([float(x) for x in vals], float)
    except ValueError:
        raise PointCloudError(f"bad PCD VIEWPOINT line {' '.join(vals)!r}: 7 numbers tx ty tz qw qx qy qz "
                              "expected") from None
    if v.shape != (7,) or not np.all(np.isfinite(v)):
        raise PointCloudError(f"bad PCD VIEWPOINT line {' '.join(vals)!r}: 7 finite numbers tx ty tz qw qx qy qz "
                              "expected")
    if np.array_equal(v, [0, 0, 0, 1, 0, 0, 0]):
        return None
    return v[:3]


def _read_pcd(path: Path) -> tuple[np.ndarray, str, np.ndarray | None]:
    raw = path.read_bytes()
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise PointCloudError("PCD header has no DATA line (truncated or not a PCD file)")
        line = raw[pos:end].decode("ascii", errors="replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        header[key.upper()] = vals
        if key.upper() == "DATA":
            break
    for key in ("FIELDS", "SIZE", "TYPE"):
        if key not in header:
            raise PointCloudError(f"PCD header lacks the {key} line")
    names = header["FIELDS"]
    sizes, types = header["SIZE"], header["TYPE"]
    counts = header.get("COUNT", ["1"] * len(names))
    if not (len(names) == len(sizes) == len(types) == len(counts)):
        raise PointCloudError(
            f"PCD header lists {len(names)} FIELDS but {len(sizes)} SIZE, {len(types)} TYPE "
            f"and {len(counts)} COUNT entries"
        )
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise PointCloudError(f"PCD fields {names} lack {missing}; x, y and z are needed")
    try:
        n = _count(header["POINTS"][0], "POINTS") if "POINTS" in header else (
            _count(header["WIDTH"][0], "WIDTH") * _count(header.get("HEIGHT", ["1"])[0], "HEIGHT"))
        fields = []
        for nm, sz, ty, ct in zip(names, sizes, types, counts):
            code = _PCD_TYPES[(ty.upper(), int(sz))]
            fields.append((nm, code, int(ct)))
    except (KeyError, ValueError, IndexError) as err:
        raise PointCloudError(f"bad PCD header (POINTS/SIZE/TYPE/COUNT): {err}") from None
    view = _pcd_viewpoint(header.get("VIEWPOINT"))
    mode = header["DATA"][0].lower() if header["DATA"] else ""
    body = raw[pos:]
    if mode == "ascii":
        cols = sum(c for _, _, c in fields)
        xyz = _text_columns(body.decode("ascii", errors="replace"), cols, n, _column_index(fields))
        return xyz, "pcd/ascii", view
    if mode == "binary":
        dt = np.dtype([(f"f{i}", "<" + c, (k,) if k > 1 else ()) for i, (_, c, k) in enumerate(fields)])
        if len(body) < n * dt.itemsize:
            raise PointCloudError(
                f"truncated binary PCD: {len(body)} data bytes for {n} points of "
                f"{dt.itemsize} bytes (need {n * dt.itemsize})"
            )
        rec = np.frombuffer(body, dtype=dt, count=n)
        return _xyz_from_records(rec, names), "pcd/binary", view
    if mode == "binary_compressed":
        if len(body) < 8:
            raise PointCloudError("truncated binary_compressed PCD: no size words")
        csize, usize = np.frombuffer(body[:8], "<u4")
        if len(body) < 8 + int(csize):
            raise PointCloudError(
                f"truncated binary_compressed PCD: {len(body) - 8} of {int(csize)} compressed bytes"
            )
        data = lzf_decompress(body[8 : 8 + int(csize)], int(usize))
        cols, off = {}, 0
        for nm, c, k in fields:  # column-major: every field's n values together
            nbytes = n * k * np.dtype(c).itemsize
            if off + nbytes > len(data):
                raise PointCloudError("binary_compressed PCD data are shorter than the header says")
            cols[nm] = np.frombuffer(data, "<" + c, count=n * k, offset=off).reshape(n, k)[:, 0]
            off += nbytes
        return np.column_stack([cols["x"], cols["y"], cols["z"]]), "pcd/binary_compressed", view
    raise PointCloudError(f"unsupported PCD DATA {mode!r}; valid: ascii, binary, binary_compressed")


def _count(text: str, what: str) -> int:
    """A header's count: a whole number >= 0 (numpy reads a negative count as 'all')."""
    n = int(text)
    if n < 0:
        raise PointCloudError(f"header {what} count is {n}, not a number of points")
    return n


def _column_index(fields) -> list[int]:
    starts, col = {}, 0
    for nm, _, k in fields:
        starts[nm] = col
        col += k
    return [starts["x"], starts["y"], starts["z"]]


def _xyz_from_records(rec: np.ndarray, names: list[str]) -> np.ndarray:
    out = [rec[f"f{names.index(c)}"] for c in "xyz"]
    return np.column_stack([o.reshape(len(rec), -1)[:, 0] for o in out])


def lzf_decompress(data: bytes, expected: int) -> bytes:
    """Decode LZF (liblzf, as used by PCL's binary_compressed) to ``expected`` bytes."""
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        ctrl = data[i]
        i += 1
        if ctrl < 32:  # literal run of ctrl + 1 bytes
            length = ctrl + 1
            if i + length > n:
                raise PointCloudError("corrupt LZF stream: literal run past the end")
            out += data[i : i + length]
            i += length
            continue
        length = ctrl >> 5
        if length == 7:
            if i >= n:
                raise PointCloudError("corrupt LZF stream: missing length byte")
            length += data[i]
            i += 1
        if i >= n:
            raise PointCloudError("corrupt LZF stream: missing offset byte")
        ref = len(out) - ((ctrl & 0x1F) << 8) - data[i] - 1
        i += 1
        length += 2
        if ref < 0:
            raise PointCloudError("corrupt LZF stream: back-reference before the start")
        if ref + length <= len(out):
            out += out[ref : ref + length]
        else:  # overlapping copy: repeat byte by byte
            for k in range(length):
                out.append(out[ref + k])
    if len(out) != expected:
        raise PointCloudError(f"LZF data decode to {len(out)} bytes, header says {expected}")
    return bytes(out)


# ---------------------------------------------------------------------------- PLY
def _read_ply(path: Path) -> tuple[np.ndarray, str]:
    raw = path.read_bytes()
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise PointCloudError("not a PLY file (no 'ply' magic or no end_header)")
    nl = raw.find(b"\n", end)
    body = raw[nl + 1 :] if nl >= 0 else b""
    lines = raw[:end].decode("ascii", errors="replace").splitlines()
    fmt, elements = None, []  # elements: [name, count, [(prop, type | ('list', ...))]]
    for line in lines[1:]:
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elements.append([tok[1], _count(tok[2], f"element {tok[1]}"), []])
        elif tok[0] == "property" and elements:
            if tok[1] == "list":
                elements[-1][2].append((tok[-1], "list"))
            else:
                if tok[1] not in _PLY_TYPES:
                    raise PointCloudError(f"unknown PLY property type {tok[1]!r}")
                elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise PointCloudError(f"unsupported PLY format {fmt!r}")
    names = [e[0] for e in elements]
    if "vertex" not in names:
        raise PointCloudError(f"PLY has no vertex element (elements: {names})")
    vi = names.index("vertex")
    _, n, props = elements[vi]
    pnames = [p for p, _ in props]
    missing = [c for c in "xyz" if c not in pnames]
    if missing:
        raise PointCloudError(f"PLY vertex properties {pnames} lack {missing}")
    if any(t == "list" for e in elements[: vi + 1] for _, t in e[2]):
        raise PointCloudError("PLY list properties before or in the vertex element are not supported")
    if fmt == "ascii":
        text = body.decode("ascii", errors="replace").splitlines()
        skip = sum(e[1] for e in elements[:vi])
        rows = "\n".join(text[skip : skip + n])
        return _text_columns(rows, len(props), n, [pnames.index(c) for c in "xyz"]), "ply/ascii"
    order = "<" if fmt == "binary_little_endian" else ">"
    skip = sum(e[1] * int(np.dtype([(p, order + t) for p, t in e[2]]).itemsize) for e in elements[:vi])
    dt = np.dtype([(p, order + t) for p, t in props])
    if len(body) < skip + n * dt.itemsize:
        raise PointCloudError(
            f"truncated binary PLY: {len(body)} data bytes, need {skip + n * dt.itemsize} "
            f"for {n} vertices"
        )
    rec = np.frombuffer(body, dtype=dt, count=n, offset=skip)
    return np.column_stack([rec["x"], rec["y"], rec["z"]]), f"ply/{fmt}"


# ----------------------------------------------------------------------- npy, text
def _read_npy(path: Path) -> tuple[np.ndarray, str]:
    """The (N, 3) array of a .npy file; its header is checked against the file's size
    first (np.load allocates what a header claims: 24 GB for a 100-byte file)."""
    import tokenize

    fmt = np.lib.format
    try:
        with open(path, "rb") as f:
            version = fmt.read_magic(f)
            shape, _, dtype = (fmt.read_array_header_1_0(f) if version == (1, 0)
                               else fmt.read_array_header_2_0(f))
            data_bytes = path.stat().st_size - f.tell()
    except (SyntaxError, tokenize.TokenError, TypeError) as err:  # a garbled header dict
        raise PointCloudError(f"not a .npy file (garbled header: {err})") from None
    if len(shape) != 2 or shape[1] != 3 or dtype.kind not in "iuf":
        raise PointCloudError(f"expected a numeric (N, 3) array, got {dtype} {shape}")
    if shape[0] * 3 * dtype.itemsize > data_bytes:
        raise PointCloudError(f"truncated .npy: the header says {shape[0]} points, the file holds "
                              f"{data_bytes} bytes of data")
    return np.load(path, allow_pickle=False), "npy"


def _read_text(path: Path) -> tuple[np.ndarray, str]:
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith(("#", "//"))]
    if not lines:
        raise PointCloudError("the file contains no points")
    cols = len(re.split(r"[,\s]+", lines[0].strip()))
    if cols < 3:
        raise PointCloudError(f"need at least 3 columns (x y z), the first row has {cols}")
    return _text_columns("\n".join(lines), cols, None, [0, 1, 2]), "xyz"


def _text_columns(text: str, cols: int, n: int | None, xyz_cols: list[int]) -> np.ndarray:
    """Parse rows of ``cols`` numbers; ``n`` rows expected when given."""
    rows = [r for r in text.splitlines() if r.strip()]
    if n is not None and len(rows) < n:
        raise PointCloudError(f"truncated data: {len(rows)} rows, the header says {n} points")
    rows = rows[:n] if n is not None else rows
    flat = re.split(r"[,\s]+", " ".join(r.strip() for r in rows).strip()) if rows else []
    if len(flat) != cols * len(rows):
        for i, r in enumerate(rows):
            k = len(re.split(r"[,\s]+", r.strip()))
            if k != cols:
                raise PointCloudError(f"data row {i + 1} has {k} values, expected {cols}: {r[:60]!r}")
    try:
        vals = np.array(flat, dtype=np.float64).reshape(len(rows), cols)
    except ValueError as err:
        raise PointCloudError(f"non-numeric value in the data: {err}") from None
    return vals[:, xyz_cols]
