"""Strategies generating the fuzz inputs: point clouds (arrays and files in every
format, well-formed and damaged), primitive dimensions and memory budgets, map-file
corruptions, output paths and command-line option values.

Every case is plain data (numbers, strings, bytes, arrays in a dict) with a ``label``
saying how it was made, so a failure's reproducer is its repr. Random arrays come
from a numpy Generator seeded by a drawn integer (deterministic under a fixed seed).
"""

from __future__ import annotations

import io
import math

import numpy as np
from hypothesis import strategies as st

from graspsim.grippers.spec import HGPL_25_60_A

OPENING = HGPL_25_60_A.max_opening
NAN, INF = float("nan"), float("inf")

#: Lengths [m] at the edges: degenerate, at the 1 mm floor, around the gripper's
#: opening, far beyond any object, overflowing, not a number.
EDGE_LENGTHS = [0.0, -0.0, -1.0, -1e-3, 5e-324, 1e-300, 1e-12, 1e-6, 9.99e-4, 1e-3, 1.001e-3, 0.5 * OPENING,
                0.5 * OPENING * 1.01, OPENING, OPENING * 1.01, 1.0, 10.0, 1e3, 1e6, 1e154, 1e300,
                1.7976931348623157e308, NAN, INF, -INF]

#: Option values as typed on a command line.
EDGE_TEXT = ["nan", "inf", "-inf", "-1", "0", "-0", "1e-9", "1e-300", "1e308", "1e400", "abc", "", " ", "0x10",
             "1_000", "1,5", "None", "0.05m", "--", "-x", "2", "3", "10", "1000", "1e6", "9" * 30, "0.5", "1.0"]


def edge_float() -> st.SearchStrategy:
    return st.one_of(st.sampled_from(EDGE_LENGTHS), st.floats(allow_nan=True, allow_infinity=True),
                     st.floats(1e-4, 0.3))


def option_text() -> st.SearchStrategy:
    return st.one_of(st.sampled_from(EDGE_TEXT), st.floats().map(repr), st.integers(-10**30, 10**30).map(str),
                     st.text(max_size=6))


def _rng(draw) -> np.random.Generator:
    return np.random.default_rng(draw(st.integers(0, 2**32 - 1)))


# ------------------------------------------------------------------ clouds
_SHAPES = {"box": ("x", "y", "z"), "cylinder": ("radius", "height"), "sphere": ("radius",),
           "cone": ("bottom_radius", "top_radius", "height"), "half_toroid": ("major_radius", "minor_radius")}


def _primitive_cloud(draw, rng, n: int) -> np.ndarray:
    from graspsim.primitives import make_primitive, synthetic_cloud
    from graspsim.transforms import make_transform, random_rotation

    kind = draw(st.sampled_from(sorted(_SHAPES)))
    dims = {k: float(rng.uniform(0.01, 0.08)) for k in _SHAPES[kind]}
    if kind == "cone":
        dims["top_radius"] = dims["bottom_radius"] * float(rng.uniform(0.0, 0.9))
    if kind == "half_toroid":
        dims["minor_radius"] = dims["major_radius"] * float(rng.uniform(0.1, 0.5))
    shape = make_primitive(kind, **dims)
    res = math.sqrt(shape.mesh(sections=32).area / max(n, 8))
    camera = rng.normal(size=3) * 0.5 if draw(st.booleans()) else None
    T = make_transform(random_rotation(rng), rng.uniform(-1, 1, 3))
    return synthetic_cloud(shape, rng, resolution=res, noise=float(rng.choice([0.0, 3e-4, 3e-3])),
                           outliers=float(rng.choice([0.0, 0.05])), camera=camera, T_world_obj=T).points


def _base_points(draw, base: str, n: int, rng) -> np.ndarray:
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    if base == "primitive":
        return _primitive_cloud(draw, rng, n)
    if base == "blob":
        return rng.normal(size=(n, 3)) * 0.03
    if base == "cube":
        return rng.uniform(-0.05, 0.05, (n, 3))
    if base == "collinear":
        return np.outer(rng.uniform(0, 0.1, n), d) + rng.normal(0, float(rng.choice([0, 1e-9, 1e-5])), (n, 3))
    if base == "planar":
        e = np.linalg.qr(np.column_stack([d, rng.normal(size=(3, 2))]))[0]
        uv = rng.uniform(-0.05, 0.05, (n, 2))
        return uv @ e[:, 1:].T + np.outer(rng.normal(0, float(rng.choice([0, 1e-9, 1e-5])), n), e[:, 0])
    if base == "one_point":
        return np.repeat(rng.normal(size=(1, 3)) * 0.1, n, axis=0)
    if base == "two_points":
        return rng.normal(size=(2, 3))[rng.integers(0, 2, n)] * 0.05
    if base == "duplicated":  # a real cloud with every point repeated
        return np.repeat(_primitive_cloud(draw, rng, max(n // 4, 10)), 4, axis=0)
    if base == "lattice":
        k = max(2, round(n ** (1 / 3)))
        g = np.linspace(0, 0.05, k)
        return np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
    raise ValueError(base)


_BASES = ["primitive", "primitive", "blob", "cube", "collinear", "planar", "one_point", "two_points",
          "duplicated", "lattice"]
_COUNTS = [0, 1, 2, 3, 5, 9, 10, 11, 29, 30, 31, 60, 150, 400]
_UNITS = [1.0, 1.0, 1.0, 1.0, 1e-3, 1e-2, 10.0, 100.0, 1000.0, 1e6, 1e-6, 1e-9]
_OFFSETS = [0.0, 0.0, 0.0, 0.5, 1e3, 1e6, 1e15, 1e300]
_DTYPES = ["f8", "f8", "f8", "f4", "f2", "i4", "u1", "c16", "?", "O"]
_MANGLES = [None, None, None, None, None, "flat", "3d", "transposed", "2 columns", "4 columns", "scalar",
            "list", "ragged"]


@st.composite
def cloud_arrays(draw) -> dict:
    """An (N, 3)-ish array: shape, count, degeneracy, units, NaN/inf, huge offsets, dtypes."""
    rng = _rng(draw)
    clean = draw(st.sampled_from([False, False, True]))  # a third: a plausible object cloud
    pick = lambda pool, good: draw(st.sampled_from(good if clean else pool))  # noqa: E731
    base, n = pick(_BASES, ["primitive"]), pick(_COUNTS, [60, 150, 400])
    pts = _base_points(draw, base, n, rng)
    unit, offset = pick(_UNITS, [1.0]), pick(_OFFSETS, [0.0, 0.5])
    with np.errstate(all="ignore"):
        pts = pts * unit + offset * rng.normal(size=3)
        for value in (NAN, INF, -INF):
            frac = pick([0.0, 0.0, 0.0, 0.02, 0.5, 1.0], [0.0, 0.0, 0.02])
            pts[rng.random(len(pts)) < frac, int(rng.integers(0, 3))] = value
        dtype = pick(_DTYPES, ["f8", "f4"])
        arr = pts.astype(dtype) if dtype != "O" else pts.astype(object)
    mangle = pick(_MANGLES, [None])
    arr = _mangle(arr, mangle)
    label = f"{base} n={n} unit={unit:g} offset={offset:g} dtype={dtype} mangle={mangle}"
    return {"label": label, "points": arr, "units": pick(["m", "m", "mm", "cm"], ["m"]), "clean": clean}


def _mangle(a: np.ndarray, how: str | None):
    if how is None:
        return a
    if how == "flat":
        return a.ravel()
    if how == "3d":
        return a[None]
    if how == "transposed":
        return a.T
    if how == "2 columns":
        return a[:, :2]
    if how == "4 columns":
        return np.column_stack([a, a[:, :1]]) if len(a) else np.zeros((0, 4))
    if how == "scalar":
        return np.float64(0.5)
    if how == "list":
        return a.tolist()
    return [list(r[: 1 + i % 3]) for i, r in enumerate(a.tolist())] or [[1.0], [1.0, 2.0]]  # ragged


# ------------------------------------------------------------------ cloud files
def _npy(pts: np.ndarray, draw, clean: bool) -> bytes:
    buf = io.BytesIO()
    how = draw(st.sampled_from(["plain"] if clean else ["plain", "plain", "fortran", "structured", "object", "1d",
                                                          "int"]))
    if how == "fortran":
        pts = np.asfortranarray(pts)
    elif how == "structured":
        pts = np.rec.fromarrays(pts.T, names="x,y,z") if pts.ndim == 2 and pts.shape[1] == 3 else pts
    elif how == "object":
        pts = pts.astype(object)
    elif how == "1d":
        pts = pts.ravel()
    elif how == "int":
        with np.errstate(all="ignore"):
            pts = np.nan_to_num(pts).astype(np.int16)
    np.save(buf, pts, allow_pickle=True)
    return buf.getvalue()


def _ply(pts: np.ndarray, draw, clean: bool) -> bytes:
    fmt = draw(st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian"]
                               + ([] if clean else ["binary_middle_endian"])))
    n_decl = _declared(draw, len(pts), clean)
    extra = draw(st.sampled_from(["", "face_after", "normals"] + ([] if clean else ["face_before", "list_vertex"])))
    typ = draw(st.sampled_from(["float", "double"] + ([] if clean else ["float", "int", "uchar", "float128"])))
    lines = ["ply", f"format {fmt} 1.0", "comment fuzz"]
    if extra == "face_before":
        lines += ["element face 1", "property list uchar int vertex_indices"]
    lines += [f"element vertex {n_decl}"] + [f"property {typ} {c}" for c in "xyz"]
    if extra == "normals":
        lines += [f"property float n{c}" for c in "xyz"]
    if extra == "list_vertex":
        lines += ["property list uchar int idx"]
    if extra == "face_after":
        lines += ["element face 1", "property list uchar int vertex_indices"]
    lines.append("end_header")
    head = ("\n".join(lines) + "\n").encode()
    cols = pts if extra != "normals" else np.column_stack([pts, pts])
    if fmt == "ascii":
        return head + "".join(" ".join(repr(float(v)) for v in r) + "\n" for r in cols).encode()
    code = {"float": "f4", "double": "f8", "int": "i4", "uchar": "u1", "float128": "f4"}[typ]
    order = ">" if fmt == "binary_big_endian" else "<"
    with np.errstate(all="ignore"):
        return head + np.ascontiguousarray(cols, dtype=order + code).tobytes()


def _pcd(pts: np.ndarray, draw, clean: bool) -> bytes:
    mode = draw(st.sampled_from(["ascii", "binary", "binary_compressed"] + ([] if clean else ["bogus"])))
    n_decl = _declared(draw, len(pts), clean)
    fields = draw(st.sampled_from(["x y z", "x y z rgb"] + ([] if clean else ["y z", "x y z x", "x x x"])))
    names = fields.split()
    size = draw(st.sampled_from(["4", "8"] + ([] if clean else ["2", "3", "x"])))
    typ = draw(st.sampled_from(["F"] if clean else ["F", "F", "I", "U", "Q"]))
    sizes, types = [size] * len(names), [typ] * len(names)
    if not clean and draw(st.booleans()) and len(names) > 1:  # a header whose lists disagree
        sizes = sizes[:-1]
    head = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS {fields}\nSIZE {' '.join(sizes)}\nTYPE {' '.join(types)}\n"
            f"COUNT {' '.join('1' for _ in names)}\nWIDTH {n_decl}\nHEIGHT 1\nPOINTS {n_decl}\nDATA {mode}\n").encode()
    cols = np.column_stack([pts[:, "xyz".index(c)] if c in "xyz" else np.zeros(len(pts)) for c in names]) \
        if len(pts) else np.zeros((0, len(names)))
    if mode == "ascii":
        return head + "".join(" ".join(repr(float(v)) for v in r) + "\n" for r in cols).encode()
    code = {("F", "4"): "<f4", ("F", "8"): "<f8", ("I", "4"): "<i4", ("U", "4"): "<u4"}.get((typ, size), "<f4")
    with np.errstate(all="ignore"):
        data = np.ascontiguousarray(cols, dtype=code)
    if mode != "binary_compressed":
        return head + data.tobytes()
    soa = data.T.copy().tobytes()  # column-major, as PCL stores it
    comp = _lzf(soa, draw, clean)
    usize = draw(st.sampled_from([len(soa)] if clean else [len(soa), len(soa), len(soa) + 1, 0, 2**32 - 1]))
    return head + np.array([len(comp), usize], "<u4").tobytes() + comp


def _lzf(data: bytes, draw, clean: bool) -> bytes:
    """A valid LZF stream (literal runs, and back-references when asked), or a damaged one."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    how = draw(st.sampled_from(["ok"] if clean else ["ok", "ok", "ok", "backref", "bad_ref", "cut"]))
    if how == "backref" and len(out) > 4:  # repeat the last 8 bytes, many times (expansion)
        out += bytes([0xE0, 255 - 9, 7]) * draw(st.integers(1, 50))
    elif how == "bad_ref":
        out += bytes([0x40, 0xFF])
    elif how == "cut":
        out = out[: max(0, len(out) - 5)]
    return bytes(out)


def _text(pts: np.ndarray, draw, clean: bool) -> bytes:
    sep = draw(st.sampled_from([" ", ",", "\t", ";", " , "]))
    head = draw(st.sampled_from(["", "", "# x y z\n", "// c\n"] + ([] if clean else ["x y z\n"])))
    rows = [sep.join(repr(float(v)) for v in r) for r in pts]
    if rows and not clean and draw(st.booleans()):
        k = draw(st.integers(0, len(rows) - 1))
        rows[k] = draw(st.sampled_from(["1 2", "a b c", "1 2 3 4 5", "nan nan nan", "", "1e999 0 0"]))
    return (head + "\n".join(rows) + "\n").encode()


def _declared(draw, n: int, clean: bool):
    return n if clean else draw(st.sampled_from([n, n, n, n, 0, max(n - 1, 0), n + 1, 10**12, -5, "abc", "1.5"]))


_WRITERS = {".npy": _npy, ".ply": _ply, ".pcd": _pcd, ".xyz": _text, ".txt": _text, ".csv": _text}


@st.composite
def cloud_files(draw) -> dict:
    """A cloud written in one of the supported formats (from a good or bad array), with
    malformed headers, truncation, flipped bytes, a wrong extension or random bytes."""
    case = draw(cloud_arrays())
    ext = draw(st.sampled_from(sorted(_WRITERS) + [".pcd", ".ply", ".npy"]))
    pts = case["points"]
    try:
        with np.errstate(all="ignore"):
            pts = np.real(np.asarray(pts)).astype(float).reshape(-1, 3)
    except (ValueError, TypeError):
        pts = np.zeros((0, 3))
    clean = case["clean"]
    data = _WRITERS[ext](pts, draw, clean)
    rng = _rng(draw)
    damage = None if clean else draw(st.sampled_from([None, None, "truncate", "flip", "random", "empty", "wrong_ext"]))
    if damage == "truncate" and data:
        data = data[: int(rng.integers(0, len(data)))]
    elif damage == "flip" and data:
        b = bytearray(data)
        for i in rng.integers(0, len(b), int(rng.integers(1, 8))):
            b[i] = int(rng.integers(0, 256))
        data = bytes(b)
    elif damage == "random":
        data = rng.bytes(int(rng.integers(1, 4000)))
    elif damage == "empty":
        data = b""
    elif damage == "wrong_ext":
        ext = draw(st.sampled_from([e for e in _WRITERS if e != ext] + [".obj", ".PCD", ""]))
    return {"label": f"{ext} from [{case['label']}] damage={damage}", "name": "cloud" + ext, "data": data,
            "units": case["units"]}


# ------------------------------------------------------------------ dimensions and budgets
_KINDS = sorted(_SHAPES) + ["half-toroid", "torus", "frustum", "BOX", "cube", "", "sphere "]
_GOOD_BUDGETS = ["1MiB", "16MiB", "64MiB", "256MiB", "1GiB", "4GiB", "50%", None, 1]
_BAD_BUDGETS = ["0", "-1", "1e400", "nan", "abc", "", "0.5", "1e-3G", "200%", "1e12T", 2**70]


def _dim_value(draw):
    return draw(st.one_of(edge_float(), edge_float(), st.sampled_from(["0.02", "abc", None, True, "nan"]),
                          st.integers(-3, 3), st.floats(0.3, 3.0).map(lambda f: f * OPENING)))


@st.composite
def primitive_specs(draw) -> dict:
    """A primitive name and its dimensions (sometimes one missing or one extra), and a
    memory budget (bytes, a size string, a percentage, or nonsense)."""
    kind = draw(st.sampled_from(_KINDS))
    names = list(_SHAPES.get(kind.strip().lower().replace("-", "_"), ("radius",)))
    if kind in ("torus", "half-toroid"):
        names = list(_SHAPES["half_toroid"])
    if kind == "frustum":
        names = list(_SHAPES["cone"])
    plausible = draw(st.booleans())  # half: object-sized dims (one of them perhaps at an edge)
    if plausible:
        dims = {k: draw(st.floats(0.002, 0.15)) for k in names}
        if names and draw(st.booleans()):
            dims[draw(st.sampled_from(names))] = _dim_value(draw)
    else:
        dims = {k: _dim_value(draw) for k in names}
    edit = draw(st.sampled_from([None, None, None, None, "drop", "extra"]))
    if edit == "drop" and dims:
        dims.pop(draw(st.sampled_from(sorted(dims))))
    elif edit == "extra":
        dims["depth"] = 0.1
    return {"label": f"{kind} {edit}{' plausible' if plausible else ''}", "kind": kind, "dims": dims,
            "budget": draw(st.sampled_from(_GOOD_BUDGETS * 2 + _BAD_BUDGETS))}
