"""Properties of the commands and Python entry points added since issue 13 (issue 35):
``plan-scene``, ``scene``, ``view``, ``adapt-gripper``, ``design``, ``trial --mesh``
(its options; the mesh's own preparation is fuzzed with the mesh files), ``db check``,
``--gripper SPEC.json``, and their API (``plan_scene``, ``read_depth_image``,
``adapt_to_gripper``, ``load_gripper_json``).

The same properties as the older commands': a clean outcome (exit 0, or one error
line; a GraspsimError from the API), files unchanged by a failure, valid maps only,
no leaked warning, bounded time and address space (``harness``).
"""

from __future__ import annotations

import io
import json
import math
import shutil

import numpy as np
from hypothesis import strategies as st

from . import options
from .assets import assets
from .harness import api_call, count, snapshot
from .props_cli import materialise, run_checked
from .registry import register


# ------------------------------------------------------------------ option values of the newer commands
@register("newer_options", "option values (CLI: newer commands)",
          lambda: options.command_lines(tuple(options.NEWER_COMMANDS), options.NEWER_COMMANDS), 70)
def check_newer_options(case: dict) -> str:
    """Edge option values of plan-scene, scene, view, adapt-gripper, design, trial --mesh,
    db check and reach: a clean outcome; failures change nothing; maps written are valid."""
    count("option values (CLI: newer commands)")
    folder = assets().fresh()
    try:
        argv = materialise(case["argv"], folder)
        inputs = tuple(x for x in ("cloud.npy", "scene.npy", "map.h5", "cyl.obj") if (folder / x).exists()
                       and not (x == "map.h5" and case["command"] in ("trial --mesh", "reach")))  # trial stores
        # its results, reach its reachable column (the hand-made map's Festo now mounts on the arm)
        label, run = run_checked(argv, folder, inputs=inputs)
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ gripper spec files
_SPEC_VALUES = [0.0, -0.01, 1e-9, 0.001, 0.02, 0.06, 1.0, 1e300, float("nan"), float("inf"), "0.02", None, [],
                [0.01, 0.02, 0.03], [0, 1], {"a": 1}, True, 1e308]


@st.composite
def gripper_specs(draw) -> dict:
    """A spec file's text: the Festo's fields with one to three of them changed (a value
    at the edge, of the wrong kind, removed, or a field unknown), the name missing or a
    registered one, or text that is not a spec at all."""
    from graspsim.grippers.spec import HGPL_25_60_A

    kind = draw(st.sampled_from(["fields", "fields", "fields", "name", "text"]))
    d = {**HGPL_25_60_A.to_dict(), "name": "fuzz_gripper"}
    if kind == "text":
        text = draw(st.sampled_from(["", "{", "[]", "null", "5", '"festo"', '{"name": "x"}', "\x00" * 8,
                                     json.dumps({"name": "x", "stroke_per_jaw": 0.03})]))
        return {"label": f"text {text[:20]!r}", "text": text}
    if kind == "name":
        name = draw(st.sampled_from([None, "", " ", HGPL_25_60_A.name, "franka_hand", 5, "ok_name"]))
        if name is None:
            d.pop("name")
        else:
            d["name"] = name
        return {"label": f"name {name!r}", "text": json.dumps(d)}
    changed = draw(st.lists(st.sampled_from(sorted(d) + ["unknown_field"]), min_size=1, max_size=3, unique=True))
    for k in changed:
        if draw(st.integers(0, 5)) == 0:
            d.pop(k, None)
        else:
            d[k] = draw(st.sampled_from(_SPEC_VALUES))
    return {"label": f"fields {changed}", "text": json.dumps(d, allow_nan=True)}


@register("gripper_specs", "gripper spec files (API + CLI: --gripper SPEC.json)", gripper_specs, 40, per_case=2)
def check_gripper_spec(case: dict) -> str:
    """load_gripper_json() of a damaged spec: a spec with a name of its own or a
    GripperError; then ``map sphere --gripper SPEC.json``: a clean outcome whose map
    records that gripper."""
    from graspsim.grippers import load_gripper_json
    from graspsim.maps.io import load_map

    count("gripper spec files (API + CLI: --gripper SPEC.json)", 2)
    folder = assets().fresh()
    try:
        path = folder / "spec.json"
        path.write_text(case["text"])
        spec, err = api_call(load_gripper_json, path)
        if spec is not None:
            assert isinstance(spec.name, str) and spec.name.strip(), spec
        argv = ["map", "sphere", "--radius", "0.02", "-o", str(folder / "s.h5"), "--gripper", str(path),
                "--threads", "1", "--surface-step", "0.01", "--rotation-step-deg", "22"]
        label, run = run_checked(argv, folder, inputs=("spec.json",))
        if run.code == 0:
            assert spec is not None and load_map(folder / "s.h5").meta.gripper_spec == spec
        else:
            assert not (folder / "s.h5").exists()
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ depth images
_MODES = ["I;16", "I;16", "I", "F", "L", "RGB", "LA", "1"]
_SIZES = [(1, 1), (2, 2), (1, 500), (64, 48), (320, 240), (20000, 20000), (5000, 4000)]


def _claim_size(png: bytes, w: int, h: int) -> bytes:
    """A PNG whose header claims ``w`` x ``h`` pixels (the IHDR chunk and its CRC rewritten)."""
    import struct
    import zlib

    ihdr = bytearray(png[12:29])  # chunk type + 13 bytes of data
    ihdr[4:12] = struct.pack(">II", w, h)
    return png[:12] + bytes(ihdr) + struct.pack(">I", zlib.crc32(bytes(ihdr))) + png[33:]


@st.composite
def depth_images(draw) -> dict:
    """A depth image file: a PNG or TIFF of some mode and size (values zero, millimetres,
    metres, huge or NaN), a .npy of some dtype and shape, or such a file truncated."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    fmt = draw(st.sampled_from([".png", ".png", ".tif", ".npy", ".npy"]))
    values = draw(st.sampled_from(["zeros", "mm", "mm", "metres", "huge", "nan"]))
    claimed = w, h = draw(st.sampled_from(_SIZES))
    if w * h > 320 * 240:
        w, h = 2, 2
    base = {"zeros": np.zeros((h, w)), "mm": rng.uniform(400, 900, (h, w)), "metres": rng.uniform(0.4, 0.9, (h, w)),
            "huge": np.full((h, w), 6e4), "nan": np.where(rng.random((h, w)) < 0.5, np.nan, 0.5)}[values]
    buf = io.BytesIO()
    if fmt == ".npy":
        dtype = draw(st.sampled_from(["u2", "f4", "f8", "i4", "c8", "?", "U3"]))
        shape = draw(st.sampled_from(["2d", "2d", "3d", "1d"]))
        a = base if shape == "2d" else base[..., None].repeat(3, -1) if shape == "3d" else base.ravel()
        with np.errstate(invalid="ignore", over="ignore"):
            np.save(buf, a.astype(dtype))
        label = f"npy {dtype} {a.shape} {values}"
    else:
        from PIL import Image

        mode = draw(st.sampled_from(_MODES))
        with np.errstate(invalid="ignore", over="ignore"):
            arr = {"I;16": np.nan_to_num(base).clip(0, 65535).astype(np.uint16),
                   "I": np.nan_to_num(base).astype(np.int32), "F": base.astype(np.float32)}.get(
                mode, np.nan_to_num(base).clip(0, 255).astype(np.uint8))
        img = Image.fromarray(arr) if mode in ("I;16", "I", "F", "L") else Image.new(mode, (w, h))
        png = fmt == ".png" and mode not in ("I", "F")  # PNG has no 32-bit modes: a TIFF named .png
        img.save(buf, format="PNG" if png else "TIFF")
        label = f"{fmt} {mode} {w}x{h} {values}" + ("" if png or fmt != ".png" else " (TIFF data)")
        if png and claimed != (w, h):
            buf = io.BytesIO(_claim_size(buf.getvalue(), *claimed))
            label += f" claiming {claimed[0]}x{claimed[1]}"
    data = buf.getvalue()
    if draw(st.integers(0, 4)) == 0:
        data = data[:draw(st.integers(0, max(0, len(data) - 1)))]
        label += " truncated"
    # the command too, now and then, for images small enough to be refused or planned in seconds
    return {"label": label, "name": "depth" + fmt, "data": data, "cli": w * h <= 64 * 48 and draw(st.booleans())}


@register("depth_images", "depth image files (API: read_depth_image; CLI: plan-scene --camera)", depth_images, 50)
def check_depth_image(case: dict) -> str:
    """read_depth_image() of a damaged or extreme file: finite depth >= 0 [m] with some
    valid pixel and at most MAX_PIXELS, or a PointCloudError; the file unchanged; now
    and then the same file through ``plan-scene --camera d435``: a clean outcome."""
    from graspsim.perception.depth_image import MAX_PIXELS, read_depth_image

    count("depth image files (API: read_depth_image; CLI: plan-scene --camera)")
    folder = assets().fresh()
    try:
        path = folder / case["name"]
        path.write_bytes(case["data"])
        before = snapshot(folder)
        res, err = api_call(read_depth_image, path)
        if res is not None:
            depth, scale = res
            assert depth.ndim == 2 and depth.size <= MAX_PIXELS and np.all(np.isfinite(depth)), depth.shape
            assert np.all(depth >= 0) and np.any(depth > 0) and math.isfinite(scale) and scale > 0
        assert snapshot(folder) == before, "reading changed the file"
        if case["cli"]:
            db = shutil.copytree(assets().db, folder / "db")
            run_checked(["plan-scene", str(path), "--camera", "d435", "-o", str(folder / "g.json"), "--db", str(db),
                         "--budget", "4:20", "--threads", "1", *options.FAST_FLAGS], folder, inputs=(case["name"],))
        return "ok" if err is None else type(err).__name__
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ the scene planner's API
_RNGS = ["generator", "generator", 42, None, "seed", 1.5, "legacy"]
_VIEWPOINTS = [None, None, [0.5, 0.0, 0.6], np.zeros(2), [np.nan, 0, 1], [1e300, 1e300, 1e300], "abc", [0, 0, 0],
               [0.0, 0.0, -0.5], np.ones((3, 3)), [1e2, 0, 0], [0.05, 0, 0.1]]


@st.composite
def scene_calls(draw) -> dict:
    """plan_scene() of the fuzz scene (or a damaged copy of it) with an rng and a
    viewpoint each drawn from good and bad ones, and a SceneConfig budget."""
    rng, view = draw(st.sampled_from(_RNGS)), draw(st.sampled_from(range(len(_VIEWPOINTS))))
    points = draw(st.sampled_from(["scene", "scene", "nan rows", "empty", "flat", "2 columns", "huge"]))
    budget = draw(st.sampled_from(["4:20", "4:20", "1:1", "0:0", "-1:5", "abc"]))
    return {"label": f"rng {rng!r}, viewpoint #{view}, points {points}, budget {budget}", "rng": rng,
            "viewpoint": view, "points": points, "budget": budget}


def _points(kind: str) -> np.ndarray:
    p = np.load(assets().scene_cloud)
    if kind == "nan rows":
        p = p.copy()
        p[::3] = np.nan
    return {"empty": np.zeros((0, 3)), "flat": p[:, :2], "2 columns": p[:, :2].T,
            "huge": p * 1e6}.get(kind, p)


@register("scene_api", "scene planning calls (API: plan_scene)", scene_calls, 30)
def check_scene_call(case: dict) -> str:
    """plan_scene() with bad or extreme arguments: a ScenePlan whose grasps are finite
    and ranked, or a GraspsimError; no map is stored for a refused call."""
    from dataclasses import replace

    from graspsim.maps.database import MapDatabase
    from graspsim.maps.generate import MapConfig
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SceneConfig, budget_fields

    count("scene planning calls (API: plan_scene)")
    folder = assets().fresh()
    try:
        db_dir = shutil.copytree(assets().db, folder / "db")
        db = MapDatabase(db_dir, config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
        rng = {"generator": np.random.default_rng(0), "seed": np.random.SeedSequence(0),
               "legacy": np.random.RandomState(0)}.get(case["rng"], case["rng"])
        fields, err = api_call(budget_fields, case["budget"])
        cfg = replace(SceneConfig(), **(fields or {}))
        before = snapshot(db_dir)
        res, err = api_call(plan_scene, _points(case["points"]), db=db, rng=rng, config=cfg,
                            viewpoint=_VIEWPOINTS[case["viewpoint"]])
        if res is not None:
            scores = [g.score for g in res.grasps]
            assert all(math.isfinite(s) for s in scores) and scores == sorted(scores, reverse=True)
        else:
            assert snapshot(db_dir) == before, "a refused call changed the database"
        return "ok" if err is None else type(err).__name__
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ adapt_to_gripper
@st.composite
def regrip_calls(draw) -> dict:
    grade = draw(st.sampled_from([None, None, 0.0, 0.5, 0.7, 0.999, 1.0, 2.0, -1.0, float("nan"), float("inf"),
                                  "0.5", True]))
    target = draw(st.sampled_from(["franka_hand", "festo_hgpl_25_60_a", "tiny", "spec", "stroke=0.01",
                                   "finger_length=0.2", "pad_length=1e-4"]))
    return {"label": f"to {target}, source grade {grade!r}", "grade": grade, "target": target,
            "base": draw(st.sampled_from(["hand", "real"]))}


@register("regrip_api", "gripper adaptations (API: adapt_to_gripper)", regrip_calls, 30)
def check_regrip_call(case: dict) -> str:
    """adapt_to_gripper() to a registered, user or varied gripper at a drawn source
    grade: a valid map of the target gripper (maybe empty), or a GraspsimError."""
    from graspsim.apps.design import resolve_design
    from graspsim.grippers.spec import GripperSpec
    from graspsim.maps.io import load_map
    from graspsim.maps.regrip import adapt_to_gripper
    from graspsim.maps.validate import map_problems

    from .props_cli import gripper_spec

    count("gripper adaptations (API: adapt_to_gripper)")
    a = assets()
    gmap = load_map(a.hand_map if case["base"] == "hand" else a.real_map)
    t = case["target"]
    if t in ("tiny", "spec"):
        target, err = GripperSpec.from_dict(gripper_spec(t)), None
    else:
        target, err = api_call(resolve_design, t, gmap.meta.gripper_spec)
    if target is None:
        return type(err).__name__
    out, err = api_call(adapt_to_gripper, gmap, target, source_min_grade=case["grade"])
    if out is not None:
        assert out.meta.gripper_spec == target and (len(out) == 0 or map_problems(out) == []), map_problems(out)
    return "ok" if err is None else type(err).__name__
