"""Properties of the Python API (in-process, fast): clouds through identification,
cloud files through the reader, primitive dimensions through the map preflight and a
coarse generation, memory budgets, and corrupted map files through the loader.

Each check returns an outcome label ("ok" or the error class) and raises when a
property breaks: an exception that is not a GraspsimError, a leaked warning, a
result that breaks its invariants, or a file changed by reading it.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
from hypothesis import strategies as st

from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.primitives.base import MIN_DIM

from . import cases, corrupt
from .assets import assets
from .harness import api_call, count, no_leaked_warnings, oracle_problems, snapshot
from .registry import register

COARSE = dict(surface_step=0.02, rotation_step=math.radians(45), collision_tolerance=0.002, depth_step=0.02)
GENERATE_BELOW = 48 << 20  # generate the map when its estimate is below this [bytes]


def _label(result, err) -> str:
    return "ok" if err is None else type(err).__name__


# ------------------------------------------------------------------ clouds
def _solid(dims: dict) -> bool:
    """Every dimension at the floor or above (a cone: its height and one radius)."""
    if "bottom_radius" in dims:
        return dims["height"] >= MIN_DIM and max(dims["bottom_radius"], dims["top_radius"]) >= MIN_DIM
    return min(dims.values()) >= MIN_DIM


def _check_identification(res) -> None:
    for p in res.parts:
        assert all(math.isfinite(v) and v >= 0 for v in p.dims.values()), p.dims
        assert _solid(p.dims), p.dims
        assert np.all(np.isfinite(p.T_world_obj)), p.T_world_obj
        assert len(p.indices) and p.indices.min() >= 0 and p.indices.max() < res.n_points


@register("cloud_arrays", "clouds (API: identify)", cases.cloud_arrays, 130)
def check_cloud_array(case: dict) -> str:
    """identify() of a bad or extreme array: an Identification whose parts are solid
    primitives (every dimension finite and >= 1 mm), or a GraspsimError."""
    from graspsim.perception import IdentifyConfig, identify, to_metres

    count("clouds (API: identify)")
    cfg = IdentifyConfig(repetitions=3)
    res, err = api_call(lambda: identify(to_metres(case["points"], case["units"]), rng=np.random.default_rng(0),
                                         config=cfg))
    if res is not None:
        _check_identification(res)
    return _label(res, err)


@register("cloud_files", "cloud files (API: read_point_cloud)", cases.cloud_files, 160)
def check_cloud_file(case: dict) -> str:
    """read_point_cloud() of a well-formed or damaged file: finite (N >= 10, 3) metres
    within the plausible extent, or a GraspsimError; the file is not changed."""
    from graspsim.perception import read_point_cloud
    from graspsim.perception.prepare import MAX_EXTENT

    count("cloud files (API: read_point_cloud)")
    folder = assets().fresh()
    try:
        path = folder / case["name"]
        path.write_bytes(case["data"])
        before = snapshot(folder)
        cloud, err = api_call(read_point_cloud, path, units=case["units"])
        if cloud is not None:
            p = cloud.points
            assert p.dtype == np.float64 and p.ndim == 2 and p.shape[1] == 3 and len(p) >= 10, p.shape
            lo, hi = np.quantile(p, [0.005, 0.995], axis=0)  # check_extent's robust width
            assert np.all(np.isfinite(p)) and float(np.max(hi - lo)) <= MAX_EXTENT * 1.01
            assert cloud.n_read == len(p) + cloud.n_dropped
        assert snapshot(folder) == before, "reading changed the file"
        return _label(cloud, err)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ dimensions, budgets
def _preflight(shape, budget, cfg):
    from graspsim.maps.preflight import check_graspable, check_memory, estimate_map_memory, memory_budget

    check_graspable(shape, HGPL_25_60_A)
    b = memory_budget(budget)
    est = estimate_map_memory(shape, HGPL_25_60_A, cfg)
    check_memory(shape, est, b)
    return est


@register("primitive_specs", "primitive dimensions and budgets (API)", cases.primitive_specs, 130)
def check_primitive_spec(case: dict) -> str:
    """make_primitive(), the preflight (gripper fit, memory estimate against the budget)
    and, when the estimate is small, a coarse generate_fs_map(): a GraspsimError or a
    valid primitive and map."""
    from graspsim.maps.generate import generate_fs_map
    from graspsim.maps.map_config import MapConfig
    from graspsim.maps.validate import map_problems
    from graspsim.primitives import make_primitive

    count("primitive dimensions and budgets (API)")
    shape, err = api_call(make_primitive, case["kind"], **case["dims"])
    if shape is None:
        return _label(shape, err)
    with no_leaked_warnings():
        for attr in ("volume", "circumradius", "size_scale"):
            v = getattr(shape, attr)
            assert math.isfinite(v) and v > 0, (attr, v)
        assert 0 <= shape.min_cross_section < math.inf  # 0: a full cone's tip
    assert _solid(shape.dims), shape.dims
    cfg = MapConfig(**COARSE)
    est, err = api_call(_preflight, shape, case["budget"], cfg)
    if est is None or est.bytes() > GENERATE_BELOW:
        return _label(est, err)
    gmap, err = api_call(generate_fs_map, shape, config=cfg, memory_budget=case["budget"], threads=1)
    if gmap is not None and len(gmap):
        assert map_problems(gmap) == [], map_problems(gmap)
    return "generated" if gmap is not None else _label(gmap, err)


_SIZE_TEXT = st.one_of(st.sampled_from(["4GiB", "512M", "1e9", "50%", "0", "-1", "0.5", "1e400", "nan", "inf", "",
                                        "4 parsecs", "1.2.3G", "200%", "0%", "1e-300%", "9" * 400, "1k", "1T", "1e3e3",
                                        "\x00", " 4G ", "4gib", "4GB", "0.0000001G"]),
                       st.text(max_size=12), st.floats().map(repr), st.integers().map(str))


@register("budget_sizes", "memory budgets (API)", lambda: _SIZE_TEXT, 60)
def check_budget_size(text: str) -> str:
    """parse_size() / memory_budget(): a positive whole number of bytes, or an
    InvalidParameterError naming the value."""
    from graspsim.maps.preflight import memory_budget, parse_size

    count("memory budgets (API)")
    n, err = api_call(parse_size, text)
    if n is not None:
        assert isinstance(n, int) and n >= 1, n
        m, err2 = api_call(memory_budget, text)
        assert m == n, (m, n)
    return _label(n, err)


# ------------------------------------------------------------------ map files
@register("map_files", "corrupted map files (API: load_map)", corrupt.corruptions, 110)
def check_map_file(case: dict) -> str:
    """load_map() of a corrupted file: a map that passes map_problems(), or a
    GraspsimError; a partial read the same; the file is not changed by reading it."""
    from graspsim.maps.io import load_map
    from graspsim.maps.validate import map_problems

    count("corrupted map files (API: load_map)")
    a = assets()
    folder = a.fresh()
    try:
        target = corrupt.apply(a.hand_map if case["base"] == "hand" else a.real_map, folder / "m.h5", case["ops"])
        before = snapshot(folder)
        gmap, err = api_call(load_map, target)
        if gmap is not None:
            problems = map_problems(gmap) + oracle_problems(gmap)
            assert problems == [], f"load_map accepted an invalid map: {problems}"
            part, err2 = api_call(load_map, target, rows=slice(0, max(1, len(gmap) // 2)))
            assert part is not None, f"the whole map loads, half of it does not: {err2}"
            assert map_problems(part) + oracle_problems(part) == []
        assert snapshot(folder) == before, "loading changed the file"
        return _label(gmap, err)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
