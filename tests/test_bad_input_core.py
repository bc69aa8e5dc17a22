"""Bad and extreme input to the core (issue 13, items 1-2): refused early and clearly,
never a runaway allocation, never a degenerate map, never a poisoned database.

Each test is named after the case it guards. CLI cases check the exit status, a
single ``graspsim: error:`` line on stderr and that nothing was written.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import time
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest

from graspsim.cli import main
from graspsim.errors import (
    BudgetExceededError,
    GraspsimError,
    IdentificationError,
    InvalidParameterError,
    MapDatabaseError,
    NoFeasibleGraspError,
    PointCloudError,
    PrimitiveError,
)
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.maps.database import MapDatabase
from graspsim.maps.dbcheck import check_database
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.graspmap import GraspabilityMap
from graspsim.maps.map_config import MapConfig
from graspsim.maps.preflight import check_memory, estimate_map_memory, memory_budget, parse_size
from graspsim.maps.validate import map_problems
from graspsim.perception import identify
from graspsim.perception.split import theta_star
from graspsim.planning.planner import plan
from graspsim.primitives import PRIMITIVES, Box, Cone, Cylinder, HalfToroid, Sphere, make_primitive, synthetic_cloud
from graspsim.transforms import make_transform, random_rotation

FAST = MapConfig(surface_step=0.01, rotation_step=math.radians(22))
FAST_FLAGS = ["--surface-step", "0.01", "--rotation-step-deg", "22"]



def _ten_metres(kind: str) -> dict[str, float]:
    """Every dimension 10 m (a half-toroid's tube 5 m: it must be thinner than the ring)."""
    dims = {n: 10.0 for n in PRIMITIVES[kind].dim_names}
    return {**dims, "minor_radius": 5.0} if kind == "half_toroid" else dims


def _flags(dims: dict[str, float]) -> list[str]:
    return [x for k, v in dims.items() for x in (f"--{k.replace('_', '-')}", str(v))]


def _fails_cleanly(capsys, argv, *needles, code=2) -> str:
    """Run the CLI; assert the exit status and one clean error line naming ``needles``."""
    assert main(argv) == code
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("graspsim: error: "), err
    assert "Traceback" not in err
    for n in needles:
        assert n in err, err
    return err


def _traced_peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


# ------------------------------------------------------------------ maps: early refusal
# Requests that would fill the machine run in a child process whose address space is
# capped at 2 GiB: a regression there ends in a MemoryError, not in the OOM killer.
_CAPPED = """
import contextlib, io, json, resource, sys, tracemalloc
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from graspsim.cli import main
import graspsim.maps.generate, graspsim.maps.io, graspsim.primitives  # imported before tracing
out = []
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    tracemalloc.start()
    try:
        with contextlib.redirect_stderr(err):
            code = main(argv)
    except BaseException as exc:  # a regression: record it, keep going
        code = f"{type(exc).__name__}: {exc}"[:300]
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    out.append({"code": code, "stderr": err.getvalue(), "traced_peak": peak})
print(json.dumps(out))
"""


def _run_capped(argvs: list[list[str]], budget: str) -> list[dict]:
    import subprocess
    import sys

    env = {**os.environ, "GRASPSIM_MEMORY_BUDGET": budget, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-c", _CAPPED, json.dumps(argvs)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_map_of_each_primitive_at_10_m_is_refused_before_allocating(tmp_path):
    kinds = sorted(PRIMITIVES)
    outs = [tmp_path / f"{k}.h5" for k in kinds]
    plate = tmp_path / "plate.h5"  # 10 m x 10 m x 5 cm: graspable at its edge, ~1e7 contacts
    argvs = [["map", k, *_flags(_ten_metres(k)), "-o", str(o)] for k, o in zip(kinds, outs)]
    argvs.append(["map", "box", "--x", "10", "--y", "10", "--z", "0.05", "-o", str(plate)])
    results = _run_capped(argvs, budget="1GiB")
    for argv, r in zip(argvs, results):
        lines = r["stderr"].strip().splitlines()
        assert r["code"] == 2 and len(lines) == 1 and lines[0].startswith("graspsim: error: "), (argv, r)
        assert r["traced_peak"] < 5e6, (argv, r)  # nothing the size of the object was allocated
    for r in results[:-1]:
        assert "nothing of" in r["stderr"] and "maximum opening" in r["stderr"]
    assert "would need about" in results[-1]["stderr"] and "budget of 1 GiB" in results[-1]["stderr"]
    assert "GRASPSIM_MEMORY_BUDGET" in results[-1]["stderr"]
    assert not any(o.exists() for o in [*outs, plate]) and not list(tmp_path.iterdir())


def test_nothing_graspable_and_over_budget_errors_from_the_api(monkeypatch):
    with pytest.raises(NoFeasibleGraspError, match="thinnest cross-section, 20 m"):
        generate_fs_map(Sphere(10.0), memory_budget="1GiB")
    plate = Box(10.0, 10.0, 0.05)  # (generating it is tested in a capped child process above)
    with pytest.raises(BudgetExceededError, match=r"would need about [0-9.]+ [GM]iB .* budget of 1 GiB"):
        check_memory(plate, estimate_map_memory(plate, HGPL_25_60_A, MapConfig()), 1 << 30)
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", "2GiB")
    assert memory_budget() == 2 << 30 and memory_budget("3GiB") == 3 << 30
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", "lots")
    with pytest.raises(InvalidParameterError, match="GRASPSIM_MEMORY_BUDGET"):
        memory_budget()


def test_memory_budget_sizes():
    assert parse_size("4GiB") == 4 << 30 and parse_size("512M") == 512 << 20 and parse_size("1e9") == 10**9
    assert parse_size("50%") > 0
    for bad in ("", "-1G", "4 parsecs", "1.2.3G", "0"):
        with pytest.raises(InvalidParameterError):
            parse_size(bad)


def test_budget_is_checked_again_once_the_grasps_are_counted():
    # the scan fits in 150 MiB, but the ~1.7 million collision-free grasps of this
    # sphere do not: refused before the map's columns are allocated
    s = Sphere(0.035)
    est = estimate_map_memory(s, HGPL_25_60_A, MapConfig())
    assert est.work_bytes < 150 << 20 < est.bytes()
    with pytest.raises(BudgetExceededError, match="collision-free grasps"):
        generate_fs_map(s, memory_budget="150MiB")


@pytest.mark.parametrize("shape", [Sphere(0.035), HalfToroid(0.04, 0.01)], ids=str)
def test_memory_estimate_bounds_what_the_generator_allocates(shape):
    maps = []
    peak = _traced_peak(lambda: maps.append(generate_fs_map(shape, config=MapConfig(depth_step=0.02))))
    est = estimate_map_memory(shape, HGPL_25_60_A, MapConfig(depth_step=0.02))
    assert est.contacts >= maps[0].meta.extra["stats"]["contacts"]
    assert 0.25 * est.bytes(len(maps[0])) <= peak <= est.bytes(len(maps[0]))


def test_nothing_graspable_threshold_is_the_gripper_opening():
    opening = HGPL_25_60_A.max_opening
    with pytest.raises(NoFeasibleGraspError, match="thinnest cross-section"):
        generate_fs_map(Sphere(0.5 * opening + 0.001))
    with pytest.raises(NoFeasibleGraspError):
        generate_fs_map(Cylinder(1.0, opening + 0.001))
    # a wide cone with a narrow end, a thin ring: something fits, no early refusal
    assert Cone(1.0, 0.01, 0.5).min_cross_section <= opening
    assert HalfToroid(1.0, 0.02).min_cross_section <= opening


def test_primitive_below_the_1_mm_floor_is_refused():
    with pytest.raises(PrimitiveError, match="degenerate"):
        Cylinder(1.76e-17, 0.1)
    with pytest.raises(PrimitiveError, match=">= 0.001 m"):
        Box(0.05, 0.05, 0.0005)
    assert Cone(0.04, 0.0, 0.1).top_radius == 0.0  # a full cone is not degenerate


# ------------------------------------------------------------------ clouds: units
def _cylinder_cloud(n_res=0.004, seed=2):
    rng = np.random.default_rng(seed)
    T = make_transform(random_rotation(rng), [0.3, 0.0, 0.1])
    return synthetic_cloud(Cylinder(0.03, 0.10), rng, resolution=n_res, noise=0.0003, T_world_obj=T)


def test_mm_cloud_is_caught_by_identify_and_units_mm_converts(tmp_path, capsys):
    sphere = synthetic_cloud(Sphere(0.04), np.random.default_rng(0), resolution=0.005, noise=0.0005).points
    np.save(tmp_path / "mm.npy", sphere * 1000.0)  # a 40 mm sphere given as 40.0
    _fails_cleanly(capsys, ["identify", str(tmp_path / "mm.npy")], "implausible in metres",
                   "millimetres", "--units mm")
    with pytest.raises(PointCloudError, match="millimetres"):
        identify(sphere * 1000.0, rng=np.random.default_rng(0))
    assert main(["identify", str(tmp_path / "mm.npy"), "--units", "mm", "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["units"] == "mm" and s["parts"][0]["primitive"] == "sphere"
    assert s["parts"][0]["dims"]["radius"] == pytest.approx(0.04, abs=0.002)


@pytest.fixture(scope="module")
def fast_db(tmp_path_factory):
    root = tmp_path_factory.mktemp("db")
    assert main(["db", "build", "--primitives", "cylinder", "--db", str(root), *FAST_FLAGS, "--json"]) == 0
    return root


def _db_copy(fast_db, tmp_path):
    root = tmp_path / "db"
    shutil.copytree(fast_db, root)
    return root


def test_mm_cloud_is_caught_by_adapt_and_units_mm_converts(fast_db, tmp_path, capsys):
    capsys.readouterr()
    root = _db_copy(fast_db, tmp_path)
    before = json.loads((root / "index.json").read_text())
    pts = _cylinder_cloud(n_res=0.0009).points  # ~30000 points: downsampled
    np.save(tmp_path / "mm.npy", pts * 1000.0)  # r 30 mm x 100 mm, in millimetres
    out = tmp_path / "a.h5"
    _fails_cleanly(capsys, ["adapt", str(tmp_path / "mm.npy"), "-o", str(out), "--db", str(root), *FAST_FLAGS],
                   "millimetres", "--units mm")
    assert not out.exists() and json.loads((root / "index.json").read_text()) == before
    assert main(["adapt", str(tmp_path / "mm.npy"), "--units", "mm", "-o", str(out), "--db", str(root),
                 *FAST_FLAGS, "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["status"] == "complete" and s["parts"][0]["primitive"] == "cylinder" and s["grasps"] > 0
    assert s["parts"][0]["dims"]["radius"] == pytest.approx(0.03, abs=0.002)
    # the downsampling is recorded in the adapted map's metadata
    with h5py.File(out) as f:
        meta = json.loads(f["graspability/meta"][()])
    down = meta["extra"]["identification"]["downsampling"]
    assert down["input_points"] == len(pts) > down["used_points"] and 0 < down["voxel"] < 0.01


# ------------------------------------------------------------------ clouds: degenerate
def _collinear():
    t = np.linspace(0.0, 0.1, 200)
    return np.outer(t, [1.0, 2.0, 3.0]) / math.sqrt(14.0) + [0.1, 0.2, 0.3]


def _planar_square():
    g = np.linspace(-0.03, 0.03, 25)
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def _no_maps_stored(root) -> bool:
    idx = root / "index.json"
    return (not idx.exists() or not json.loads(idx.read_text())["maps"]) and not list(root.glob("*/*.h5"))


def test_collinear_cloud_is_an_error_and_nothing_is_stored(tmp_path, capsys):
    # was: "identified" as a cylinder of radius 1.76e-17, and adapt stored its map
    with pytest.raises(IdentificationError, match="collinear"):
        identify(_collinear(), rng=np.random.default_rng(0))
    np.save(tmp_path / "line.npy", _collinear())
    _fails_cleanly(capsys, ["identify", str(tmp_path / "line.npy")], "collinear")
    root, out = tmp_path / "db", tmp_path / "line.h5"
    _fails_cleanly(capsys, ["adapt", str(tmp_path / "line.npy"), "-o", str(out), "--db", str(root), *FAST_FLAGS],
                   "collinear")
    assert not out.exists() and _no_maps_stored(root)


def test_planar_square_is_a_clear_error_from_identify_adapt_and_plan(tmp_path, capsys):
    # was: ZeroDivisionError in perception/split.py theta_star
    sq = _planar_square()
    with pytest.raises(IdentificationError, match="planar"):
        identify(sq, rng=np.random.default_rng(0))
    with pytest.raises(IdentificationError, match="planar"):
        plan(sq, db=MapDatabase(tmp_path / "db", config=FAST), rng=np.random.default_rng(0))
    np.save(tmp_path / "sq.npy", sq)
    _fails_cleanly(capsys, ["identify", str(tmp_path / "sq.npy")], "planar")
    out = tmp_path / "sq.h5"
    _fails_cleanly(capsys, ["adapt", str(tmp_path / "sq.npy"), "-o", str(out), "--db", str(tmp_path / "db"),
                            *FAST_FLAGS], "planar")
    assert not out.exists() and _no_maps_stored(tmp_path / "db")


def test_flat_split_boxes_gain_no_volume():
    assert theta_star(0.0, (0.0, 0.0), 0.0) == 1.0
    assert theta_star(2.0, (0.5, 0.5), 0.0) == 0.5


def test_flat_face_split_off_a_box_is_no_sub_millimetre_box():
    """E01 partial box (variant 4, trial 2): one face split off was "identified" as a box
    0.6 mm thick (a 2-part result). Whether this cloud splits a face off at all depends on the
    machine's floating point; what may not happen on any machine is a part under 1 mm. The
    mechanism itself, on clusters made for it: a thin slab whose box fit is under 1 mm is left
    unidentified, with the degenerate fit as its reason where the box otherwise fits."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    from _identification_trials import CloudSpec, trial_cloud  # E01's trial clouds

    from graspsim.perception.cluster import identify_cluster
    from graspsim.perception.identify_config import IdentifyConfig

    seed = np.random.SeedSequence(entropy=20180101, spawn_key=(1, 0, 4, 10, 2))
    cloud, rng = trial_cloud("box", 4, seed, CloudSpec(noise=0.001, outliers=0.01, partial=True))
    res = identify(cloud.points, rng=rng)
    assert all(min(p.dims.values()) >= 0.001 for p in res.parts) and len(res.parts) == 1
    assert all(u.reason for u in res.unidentified)
    reasons = []
    for t in (0.0003, 0.0005, 0.0007):
        for k in range(4):
            r = np.random.default_rng(k)
            z = r.choice([-t / 2, t / 2], 1500)
            pts = np.column_stack([r.uniform(-0.02, 0.02, 1500), r.uniform(-0.015, 0.015, 1500),
                                   z + r.normal(0, 3e-5, 1500)])
            normals = np.zeros((1500, 3))
            normals[:, 2] = np.sign(z)
            part = identify_cluster(pts, normals, np.arange(1500), 1e-4, np.random.default_rng(k), IdentifyConfig())
            assert part.shape.value == "unidentified" and part.reason and not part.dims
            reasons.append(part.reason)
    assert any(x.startswith("degenerate box fit") for x in reasons)


# ------------------------------------------------------------------ clouds: density
def _dense(shape: str, n: int, rng) -> np.ndarray:
    """n points uniform on a cylinder (r 3 cm, h 12 cm) or sphere (r 4 cm) surface,
    0.5 mm noise, posed; i.i.d., so any prefix is a uniform subsample."""
    if shape == "sphere":
        p = rng.normal(size=(n, 3))
        p *= 0.04 / np.linalg.norm(p, axis=1, keepdims=True)
    else:
        r, h = 0.03, 0.12
        side = rng.random(n) < (h / (h + r))  # side area 2 pi r h, caps 2 pi r^2
        phi = rng.uniform(0, 2 * np.pi, n)
        rad = np.where(side, r, r * np.sqrt(rng.random(n)))
        z = np.where(side, rng.uniform(-h / 2, h / 2, n), np.where(rng.random(n) < 0.5, -h / 2, h / 2))
        p = np.column_stack([rad * np.cos(phi), rad * np.sin(phi), z])
    p += rng.normal(0.0, 0.0005, p.shape)
    T = make_transform(random_rotation(rng), [0.2, -0.1, 0.6])
    return p @ T[:3, :3].T + T[:3, 3]


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["cylinder", "sphere"])
def test_dense_cloud_is_downsampled_and_agrees_with_a_tenth_of_it(shape):
    # was: ~2 CPU-minutes and 2.8 GiB for 10^6 points (no downsampling)
    pts = _dense(shape, 10**6, np.random.default_rng(7))
    runs = []
    peak = _traced_peak(lambda: runs.append(identify(pts, rng=np.random.default_rng(0))))
    assert peak < 1 << 30, peak  # the goal: <= 1 GiB (what numpy allocates; the 24 MB cloud is outside)
    full = runs[0]
    tenth = identify(pts[: 10**5], rng=np.random.default_rng(0))
    for res, n in ((full, 10**6), (tenth, 10**5)):
        d = res.downsampling
        assert d.input_points == n == res.n_points and d.used_points <= 20000 and d.voxel > 0
        assert res.status.value == "identified" and [p.shape.value for p in res.parts] == [shape]
        assert res.parts[0].n_points > 0.95 * n  # indices cover the input cloud
    for k, v in full.parts[0].dims.items():
        assert tenth.parts[0].dims[k] == pytest.approx(v, abs=0.003)
    truth = {"radius": 0.04} if shape == "sphere" else {"radius": 0.03, "height": 0.12}
    for k, v in truth.items():
        assert full.parts[0].dims[k] == pytest.approx(v, abs=0.003)


def test_identify_json_records_the_downsampling(tmp_path, capsys):
    pts = _dense("sphere", 30000, np.random.default_rng(1))
    np.save(tmp_path / "s.npy", pts)
    assert main(["identify", str(tmp_path / "s.npy"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["downsampling"]["input_points"] == 30000 >= 20000 >= s["downsampling"]["used_points"]
    small = tmp_path / "small.npy"
    np.save(small, pts[:2000])
    assert main(["identify", str(small), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["downsampling"] is None


# ------------------------------------------------------------------ the database
def test_database_refuses_to_store_an_invalid_map(tmp_path, monkeypatch):
    import graspsim.maps.database as database

    db = MapDatabase(tmp_path, config=FAST)
    good = db.get(Sphere(0.025))
    bad_maps = {"empty": GraspabilityMap.empty(good.meta),
                "nan": good.select(np.arange(10)).with_meta()}
    bad_maps["nan"].grade[3] = np.nan
    for bad in bad_maps.values():
        monkeypatch.setattr(database, "generate_fs_map", lambda *a, _b=bad, **k: _b)
        with pytest.raises(MapDatabaseError, match="not stored"):
            db.add(Sphere(0.03))
        assert not db.contains(Sphere(0.03)) and not db.path(Sphere(0.03)).exists()
    assert map_problems(good) == []
    assert "no grasps" in map_problems(bad_maps["empty"])[0]


def _poison(root):
    """Add a truncated map, a zero-radius map (as the collinear cloud produced), a
    record without a file and a stale temporary file to a database with one good map."""
    index = json.loads((root / "index.json").read_text())
    good = index["maps"][0]
    src = root / good["file"]
    recs = []
    for name, edit in (("corrupt", "truncate"), ("zero", "radius")):
        rel = f"cylinder/{name}_{good['settings']}.h5"
        shutil.copy(src, root / rel)
        if edit == "truncate":
            with open(root / rel, "r+b") as f:
                f.truncate(os.path.getsize(root / rel) // 2)
            dims = good["dims"]
        else:
            dims = {"radius": 1.76e-17, "height": 0.098}
            with h5py.File(root / rel, "r+") as f:
                desc = json.loads(f["object/description"][()])
                desc["dims"] = dims
                del f["object/description"], f["object/dims"]
                f["object/description"], f["object/dims"] = json.dumps(desc), json.dumps(dims)
        recs.append({**good, "key": f"{name}_{good['settings']}", "file": rel, "dims": dims})
    recs.append({**good, "key": "gone", "file": "cylinder/gone.h5"})
    index["maps"] += recs
    (root / "index.json").write_text(json.dumps(index))
    tmp = root / "cylinder" / ".x.h5.abcd.tmp"
    tmp.write_bytes(b"half a map")
    old = time.time() - 3600
    os.utime(tmp, (old, old))
    return good


def test_db_check_reports_and_repairs_a_corrupted_and_a_zero_radius_map(fast_db, tmp_path, capsys):
    capsys.readouterr()
    root = _db_copy(fast_db, tmp_path)
    good = _poison(root)
    db = MapDatabase(root, config=FAST)
    # the zero-radius record is never a lookup source, even before the repair
    assert good["key"] in [e["key"] for e in db.entries()]
    assert not any(e["key"].startswith("zero") for e in db.entries())
    assert main(["db", "check", "--db", str(root), "--json"]) == 1
    rep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert rep["maps"] == 4 and rep["valid"] == 1 and not rep["ok"]
    why = {p["file"]: p["problem"] for p in rep["problems"]}
    assert "unreadable" in why[f"cylinder/corrupt_{good['settings']}.h5"]
    assert "radius must be >= 0.001 m" in why[f"cylinder/zero_{good['settings']}.h5"]
    assert "missing" in why["cylinder/gone.h5"] and "stale temporary" in why["cylinder/.x.h5.abcd.tmp"]
    assert main(["db", "check", "--db", str(root), "--repair"]) == 0
    text = capsys.readouterr().out
    assert "4 problems, all repaired" in text
    assert sorted(p.name for p in (root / "cylinder").iterdir()) == [good["file"].split("/")[1]]
    assert main(["db", "check", "--db", str(root)]) == 0
    assert "no problems" in capsys.readouterr().out
    assert [e["key"] for e in json.loads((root / "index.json").read_text())["maps"]] == [good["key"]]


def test_db_check_rebuilds_a_damaged_index_from_the_valid_maps(fast_db, tmp_path):
    root = _db_copy(fast_db, tmp_path)
    good = json.loads((root / "index.json").read_text())["maps"][0]
    (root / "index.json").write_text("{not json")
    db = MapDatabase(root, config=FAST)
    rep = check_database(db, stale_after=0.0)
    assert not rep.ok and rep.problems[0][0] == "index.json"
    rep = check_database(db, repair=True, stale_after=0.0)
    assert rep.repaired and rep.reindexed == (good["file"],)
    (e,) = db.entries()
    assert {k: e[k] for k in ("key", "primitive", "dims", "grasps", "accepted", "file")} == \
        {k: good[k] for k in ("key", "primitive", "dims", "grasps", "accepted", "file")}


def test_errors_are_graspsim_errors():
    for cls in (BudgetExceededError, NoFeasibleGraspError, IdentificationError, PointCloudError):
        assert issubclass(cls, GraspsimError)


# ------------------------------------------------------------------ found by the fuzz suite
def test_cloud_of_complex_ragged_or_boolean_values_is_a_point_cloud_error():
    # complex: a leaked ComplexWarning and the imaginary part silently dropped; ragged: ValueError
    from graspsim.perception import to_metres
    from graspsim.perception.cloud_input import check_cloud

    good = synthetic_cloud(Sphere(0.04), np.random.default_rng(0), resolution=0.01).points
    for bad in (good.astype(complex), [[0.1], [0.1, 0.2]], good > 0, [["a", "b", "c"]] * 20, [[10**400, 0, 0]] * 20):
        with pytest.raises(PointCloudError, match="real-valued"):
            identify(bad, rng=np.random.default_rng(0))
        with pytest.raises(PointCloudError):
            to_metres(bad, "mm")
        with pytest.raises(PointCloudError):
            check_cloud(bad)


def test_tiny_cloud_is_named_tiny_not_collinear(tmp_path, capsys):
    # a 3 cm sphere read with --units mm was "collinear ... a line 0.142 mm long"
    sphere = synthetic_cloud(Sphere(0.03), np.random.default_rng(0), resolution=0.005).points
    np.save(tmp_path / "s.npy", sphere)
    _fails_cleanly(capsys, ["identify", str(tmp_path / "s.npy"), "--units", "mm"], "only", "across",
                   "in metres?")


def test_identify_config_refuses_infinite_noise_huge_repetitions_and_non_numbers():
    from graspsim.perception import IdentifyConfig
    from graspsim.perception.identify_config import MAX_REPETITIONS

    for bad in ({"noise": math.inf}, {"repetitions": MAX_REPETITIONS + 1}, {"repetitions": math.nan},
                {"theta": "0.5"}, {"max_points": None}):
        with pytest.raises(InvalidParameterError, match=list(bad)[0]):
            IdentifyConfig(**bad)
    assert IdentifyConfig(repetitions=MAX_REPETITIONS).repetitions == 1000


def test_identification_memory_does_not_grow_with_repetitions(monkeypatch):
    # hypotheses are made and scored in blocks: 1000 repetitions on 20000 points took 1.6 GB
    import graspsim.perception.mlesac as mlesac
    from graspsim.perception import IdentifyConfig

    pts = _dense("cylinder", 3000, np.random.default_rng(3))
    monkeypatch.setattr(mlesac, "SCORE_BLOCK", 3000 * 40)  # 40 hypotheses at a time
    peaks = {}
    for reps in (40, 400):
        runs = []
        cfg = IdentifyConfig(repetitions=reps)
        peaks[reps] = _traced_peak(lambda runs=runs, cfg=cfg: runs.append(
            identify(pts, rng=np.random.default_rng(0), config=cfg)))
        assert runs[0].parts[0].shape.value == "cylinder"
    assert peaks[400] < 1.5 * peaks[40], peaks
    monkeypatch.setattr(mlesac, "SCORE_BLOCK", 1 << 40)  # one block: the same result
    whole = identify(pts, rng=np.random.default_rng(0), config=IdentifyConfig(repetitions=400))
    assert whole.parts[0].dims == runs[0].parts[0].dims


def test_memory_budget_of_a_fraction_of_a_byte_or_beyond_floats_is_refused():
    for bad in ("0.5", "0.0000000001%", "1e300T", "1e30G"):  # were 0 bytes, or an OverflowError
        with pytest.raises(InvalidParameterError, match="between one byte and 4 EiB"):
            parse_size(bad)
    assert parse_size("1") == 1


def test_default_memory_budget_is_half_the_memory_at_most_3_5_gib(monkeypatch):
    # was half the RAM (11.8 GiB here): the goal is a peak below 4 GiB for any command
    import graspsim.maps.preflight as preflight

    monkeypatch.delenv("GRASPSIM_MEMORY_BUDGET", raising=False)
    monkeypatch.setattr(preflight, "total_memory", lambda: 64 << 30)
    assert memory_budget() == 3584 << 20 == preflight.DEFAULT_CAP
    monkeypatch.setattr(preflight, "total_memory", lambda: 4 << 30)
    assert memory_budget() == 2 << 30


def test_preflight_of_absurd_steps_and_sizes_is_instant_and_refused():
    # roll and depth arrays of 10^10 entries, a Python loop over 10^8 rings, float overflow
    configs = [MapConfig(rotation_step=1e-9), MapConfig(depth_step=1e-12), MapConfig(surface_step=1e-300),
               MapConfig(collision_tolerance=1e-200)]
    for cfg in configs:
        t0 = time.perf_counter()
        peak = _traced_peak(lambda cfg=cfg: pytest.raises(BudgetExceededError, generate_fs_map, Sphere(0.02),
                                                          config=cfg, memory_budget="4GiB"))
        assert peak < 5e6 and time.perf_counter() - t0 < 5.0, cfg
    with pytest.raises(BudgetExceededError):
        generate_fs_map(Box(0.002, 0.002, 1000.0), memory_budget="4GiB")


def test_primitive_beyond_1_km_or_overflowing_is_refused():
    for make in (lambda: Box(1e300, 0.05, 0.05), lambda: Sphere(10**400), lambda: Cylinder(0.02, 1001.0),
                 lambda: make_primitive(None, radius=0.02)):
        with pytest.raises(PrimitiveError):
            make()


def test_collision_samples_of_a_large_familiar_object_are_budgeted(fast_db, monkeypatch):
    # scaling a 2 x 20 cm cylinder's map to 5.5 x 55 cm built 2.7 M collision samples
    # (~0.8 GB) whatever the budget
    from graspsim.maps.scaling import scale_map

    db = MapDatabase(fast_db, config=FAST)
    fs = db.load_entry(db.entries()[0])
    monkeypatch.setenv("GRASPSIM_MEMORY_BUDGET", "256MiB")
    with pytest.raises(BudgetExceededError, match="collision samples of cylinder.*budget of 256 MiB"):
        scale_map(fs, Cylinder(0.055, 0.55))


def test_seed_below_zero_and_threads_below_one_are_refused(tmp_path, capsys):
    pts = _cylinder_cloud().points
    np.save(tmp_path / "c.npy", pts)
    with pytest.raises(SystemExit):  # argparse: was a ValueError traceback from numpy
        main(["identify", str(tmp_path / "c.npy"), "--seed", "-1"])
    assert "--seed: must be a whole number >= 0" in capsys.readouterr().err
    _fails_cleanly(capsys, ["map", "sphere", "--radius", "0.02", "-o", str(tmp_path / "m.h5"), "--threads", "0"],
                   "--threads must be >= 1")  # was: silently one thread


def test_database_index_with_junk_records_is_skipped_not_a_crash(fast_db, tmp_path):
    # records that are not dicts crashed entries() and every adapt with AttributeError
    root = _db_copy(fast_db, tmp_path)
    index = json.loads((root / "index.json").read_text())
    good = index["maps"][0]
    index["maps"] += [1, "x", None, {**good, "accepted": "many"}, {**good, "file": 5}]
    (root / "index.json").write_text(json.dumps(index))
    db = MapDatabase(root, config=FAST)
    assert [e["key"] for e in db.entries()] == [good["key"]]
    assert db.lookup("cylinder", good["dims"]).match.value == "known"
    (root / "index.json").write_text(json.dumps({"maps": {"a": 1}}))
    with pytest.raises(MapDatabaseError, match="damaged"):
        db.entries()


def test_unusable_stored_map_says_how_to_repair(fast_db, tmp_path):
    root = _db_copy(fast_db, tmp_path)
    db = MapDatabase(root, config=FAST)
    entry = db.entries()[0]
    (root / entry["file"]).write_bytes(b"junk")
    with pytest.raises(MapDatabaseError, match="db check --repair"):
        db.load_entry(entry, accepted_only=True)


def test_gripper_fields_of_the_wrong_kind_are_gripper_errors():
    # found by fuzz_long: a map whose gripper JSON held a list as closed_gap ended in a
    # TypeError (a tuple plus a float) instead of a MapFileError
    from graspsim.errors import GripperError
    from graspsim.grippers.spec import GripperSpec

    base = HGPL_25_60_A.to_dict()
    for field, value in (("closed_gap", [0.01, 0.01, 0.01]), ("finger_size", 0.08), ("stroke_per_jaw", "x"),
                         ("jaw_size", [0.03, "a", 0.01]), ("pad_length", None)):
        with pytest.raises(GripperError, match=field):
            GripperSpec.from_dict({**base, field: value})
