"""A user's object through the commands a user runs (issue 33): the mesh placement round
trip (cloud frame -> map -> simulated mesh), the CLI against E09's code path on one cloud,
and the same map whatever the database holds. The mesh is the vendored pybullet
``random_003`` (several lumps: a multi-part map, the case the CLI and E09 disagreed on)."""

import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from graspsim._resources import package_path
from graspsim.maps import GraspabilityMap, MapMeta
from graspsim.maps.graspmap import Placement

ROOT = Path(__file__).resolve().parents[1]
MESH = package_path("assets", "objects") / "pybullet" / "random_003.stl"
COARSE = ["--surface-step", "0.01", "--rotation-step-deg", "22"]


def _yaw(a: float, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]
    T[:3, 3] = t
    return T


def _standing_mesh(table_z: float = 0.03):
    """random_003 on its most stable face (trimesh's stable poses) on a table at
    ``table_z``, turned and moved away from the origin: the mesh in the 'camera' frame
    a user's cloud and mesh share."""
    import trimesh

    m = trimesh.load(MESH, force="mesh")
    T, p = trimesh.poses.compute_stable_poses(m)
    m.apply_transform(T[int(np.argmax(p))])
    m.apply_transform(_yaw(0.7, [0.45, -0.12, table_z - m.bounds[0, 2]]))
    return m


def _map_with(T_cloud_obj: np.ndarray, table: dict | None) -> GraspabilityMap:
    from graspsim.grippers import HGPL_25_60_A

    meta = MapMeta(object={"primitive": "box", "x": 0.03, "y": 0.09, "z": 0.09}, gripper=HGPL_25_60_A.to_dict(),
                   quality={}, resolution={}, method="adapted", extra=Placement(T_cloud_obj, table).to_extra())
    return GraspabilityMap.empty(meta)


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.1, -0.2, 1.0)])
def test_the_simulated_mesh_stands_where_the_cloud_was(tmp_path, normal):
    from scipy.spatial.transform import Rotation

    from graspsim.sim.mapsim import map_object, observed_placement
    from graspsim.transforms import invert_transform

    mesh = _standing_mesh().convex_hull  # convex: no decomposition (seconds); the placement is the same
    n = np.asarray(normal) / np.linalg.norm(normal)
    R_tilt = Rotation.align_vectors([n], [[0.0, 0.0, 1.0]])[0].as_matrix()  # the cloud's table along n
    mesh.apply_transform(np.block([[R_tilt, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]))
    path = tmp_path / "object.stl"
    mesh.export(path)
    # an object frame anywhere: what the planner's identification happened to choose
    T_cloud_obj = _yaw(2.1, [0.40, -0.05, 0.07]) @ np.block(
        [[Rotation.from_rotvec([0.3, 1.2, -0.4]).as_matrix(), np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])
    gmap = _map_with(T_cloud_obj, {"normal": n.tolist(), "height": -0.3, "clearance": 0.002})
    obj = map_object(gmap, mesh=path, cache_dir=tmp_path / "coacd")
    T_world_obj = observed_placement(gmap, obj, True)
    T_world_cloud = T_world_obj @ invert_transform(T_cloud_obj)
    v_cloud = np.asarray(mesh.vertices, float)
    v_world = v_cloud @ T_world_cloud[:3, :3].T + T_world_cloud[:3, 3]
    # a rigid motion: the table's normal up, every vertex at its height above the mesh's
    # lowest point (the mesh stands on its own support, not on the recorded -0.3 m)
    np.testing.assert_allclose(T_world_cloud[:3, :3] @ n, [0, 0, 1], atol=1e-9)
    h = v_cloud @ n
    np.testing.assert_allclose(v_world[:, 2], h - h.min(), atol=2e-6)
    # the simulated surface is the mesh's, where the cloud frame put it
    s = np.asarray(obj.surface.vertices, float)
    s_world = s @ T_world_obj[:3, :3].T + T_world_obj[:3, 3]
    assert s_world[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    # a grasp given in the cloud's frame lands at the same place on the mesh
    T_cloud_wrist = _yaw(0.3, v_cloud[0] + [0, 0, 0.05])
    T_world_wrist = T_world_obj @ invert_transform(T_cloud_obj) @ T_cloud_wrist
    d_cloud = np.linalg.norm(v_cloud - T_cloud_wrist[:3, 3], axis=1)
    d_world = np.linalg.norm(v_world - T_world_wrist[:3, 3], axis=1)
    np.testing.assert_allclose(d_world, d_cloud, atol=2e-6)


def test_a_mesh_is_simulated_with_its_own_mass_not_the_fitted_parts(tmp_path):
    """Against a mesh, the object's mass is density x the mesh's volume (an adapted map's mass
    is its fitted parts', which fill cavities), unless one is given. Mutation: taking the
    map's mass first (the old order) fails the first assertion."""
    import trimesh

    from graspsim.primitives import Box
    from graspsim.sim.mapsim import map_object

    gmap = _map_with(np.eye(4), None)
    gmap.meta.object.clear()
    gmap.meta.object.update(Box(0.03, 0.09, 0.09).to_dict(), mass=0.5)  # the fitted box's, say
    mesh = trimesh.creation.box([0.02, 0.04, 0.05])
    assert map_object(gmap, mesh=mesh, density=800.0, cache_dir=tmp_path).mass == pytest.approx(800 * 4e-5)
    assert map_object(gmap, mesh=mesh, mass=0.2, cache_dir=tmp_path).mass == pytest.approx(0.2)
    assert map_object(gmap).mass == pytest.approx(0.5)  # no mesh: the map's object, its mass


def test_a_partial_map_is_not_turned_onto_another_face():
    """The scene used to rest a map's primitives on the hull face nearest their centre of
    mass when they were not stable as seen: a partial map's grasps then pointed into the
    object (issue 33's random_003: 80-105 mm start penetration)."""
    from graspsim.primitives import Box
    from graspsim.sim.mapsim import map_object, observed_placement

    # a tall thin box leaning 30 deg: unstable as seen, stood as seen
    R = np.array([[1, 0, 0], [0, math.cos(0.5), -math.sin(0.5)], [0, math.sin(0.5), math.cos(0.5)]])
    T_cloud_obj = np.eye(4)
    T_cloud_obj[:3, :3] = R
    box = Box(0.01, 0.02, 0.12)
    table = {"normal": [0, 0, 1], "height": 0.0, "clearance": 0.002}
    meta = MapMeta(object=box.to_dict(), gripper=_map_with(np.eye(4), None).meta.gripper, quality={},
                   resolution={}, method="adapted", extra=Placement(T_cloud_obj, table).to_extra())
    gmap = GraspabilityMap.empty(meta)
    T = observed_placement(gmap, map_object(gmap), False)
    np.testing.assert_allclose(T[:3, :3], R, atol=1e-9)


def _e09():
    sys.path.insert(0, str(ROOT / "experiments"))
    path = ROOT / "experiments" / "e09_everyday_objects.py"
    spec = importlib.util.spec_from_file_location("e09_everyday_objects", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["e09_everyday_objects"] = mod
    spec.loader.exec_module(mod)
    return mod


def _cloud(mesh, n: int = 3000) -> np.ndarray:
    import trimesh

    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=3)
    return pts + np.random.default_rng(4).normal(0.0, 0.001, pts.shape)


@pytest.mark.slow
def test_the_cli_and_e09_give_the_same_map_and_outcomes(tmp_path, capsys, monkeypatch):
    from graspsim.cli import main
    from graspsim.maps import load_map, read_sim_results
    from graspsim.maps.database import MapDatabase
    from graspsim.maps.generate import MapConfig

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))  # CoACD's parts: not the user's cache
    mesh = _standing_mesh()
    mesh_path = tmp_path / "object.stl"
    mesh.export(mesh_path)
    cloud = tmp_path / "cloud.npy"
    np.save(cloud, _cloud(mesh).astype(np.float32))  # float32 on disk: E09 passes float64 arrays
    # the user: two commands, a fresh database
    assert main(["adapt", str(cloud), "-o", str(tmp_path / "cli.h5"), "--table", "auto", "--seed", "5",
                 "--db", str(tmp_path / "db_cli"), "--json", *COARSE]) == 0
    adapt_out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert main(["trial", str(tmp_path / "cli.h5"), "--top", "6", "--mesh", str(mesh_path), "--seed", "7",
                 "--json"]) == 0
    trial_out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    # E09's code path on the same cloud (as an array) and mesh, another fresh database
    e09 = _e09()
    cfg = e09.Config(seed=5, top=6, table="auto")
    db = MapDatabase(tmp_path / "db_e09", config=MapConfig(surface_step=0.01, rotation_step=math.radians(22)))
    entry, res = e09._plan_entry(np.load(cloud).astype(np.float64), db, "robust", cfg)
    e09_map = tmp_path / "e09.h5"
    from graspsim.maps.io import save_map

    save_map(res.map, e09_map)
    sim = e09._sim(e09_map, mesh_path, cfg, seed=7)
    a, b = load_map(tmp_path / "cli.h5"), load_map(e09_map)
    assert len(a) == len(b) == adapt_out["grasps"] and len(a) > 0
    np.testing.assert_array_equal(a.wrist_position, b.wrist_position)
    np.testing.assert_array_equal(a.wrist_quat, b.wrist_quat)
    assert a.meta.extra["table"] == b.meta.extra["table"]
    assert [p["primitive"] for p in adapt_out["parts"]] == [p["primitive"] for p in entry["parts"]]
    ra, rb = read_sim_results(tmp_path / "cli.h5"), read_sim_results(e09_map)
    np.testing.assert_array_equal(ra["simulated"], rb["simulated"])
    np.testing.assert_array_equal(ra["outcome"], rb["outcome"])
    assert sim["counts"] == trial_out["counts"] and sim["trials"] == trial_out["trials"] == 6
    # the multi-part map's best grasps are placed on the real mesh: none starts in collision
    # with the table or the object (the disagreement issue 33 found)
    assert trial_out["counts"]["start_collision"] == 0, trial_out["counts"]


# ------------------------------------------------------------------ reproducible planning
def _flipping_cloud() -> np.ndarray:
    """random_003 sampled so that, before clouds were made canonical, the float64 points
    and their float32 copy identified differently (cylinder + cone against box + cylinder)."""
    import trimesh

    m = trimesh.load(MESH, force="mesh")
    pts, _ = trimesh.sample.sample_surface(m, 3000, seed=1)
    return pts + np.random.default_rng(1).normal(0, 0.001, pts.shape) + [0.4, -0.1, 0.3]


def _write_ply_float32(path: Path, pts: np.ndarray) -> None:
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\n"
            "property float x\nproperty float y\nproperty float z\nend_header\n")
    path.write_bytes(head.encode() + np.ascontiguousarray(pts, "<f4").tobytes())


def test_float32_ply_and_float64_npy_of_the_same_points_identify_the_same(tmp_path):
    from graspsim.perception import IdentifyConfig, identify, read_point_cloud

    pts = _flipping_cloud()
    np.save(tmp_path / "c.npy", pts)
    _write_ply_float32(tmp_path / "c.ply", pts)
    a, b = read_point_cloud(tmp_path / "c.npy"), read_point_cloud(tmp_path / "c.ply")
    np.testing.assert_array_equal(a.points, b.points)  # canonical: float32, then the 1 um grid
    assert np.max(np.abs(a.points - pts)) < 1e-6
    cfg = IdentifyConfig.preset("robust")
    pa = identify(a.points, rng=np.random.default_rng(0), config=cfg)
    pb = identify(b.points, rng=np.random.default_rng(0), config=cfg)
    assert [(p.shape, p.n_points) for p in pa.parts] == [(p.shape, p.n_points) for p in pb.parts]


def _cylinder_cloud(radius=0.03, height=0.09) -> np.ndarray:
    from graspsim.primitives import Cylinder, synthetic_cloud

    return synthetic_cloud(Cylinder(radius, height), np.random.default_rng(2), resolution=0.004, noise=0.0005).points


@pytest.mark.slow
def test_a_grown_database_changes_no_part_and_names_the_map_it_used(tmp_path):
    from graspsim.maps.database import MapDatabase
    from graspsim.maps.generate import MapConfig
    from graspsim.planning.adapt import adapt_cloud, adapt_config
    from graspsim.primitives import Cylinder

    fast = MapConfig(surface_step=0.01, rotation_step=math.radians(22))
    pts = _cylinder_cloud()
    cfg = adapt_config(table="auto")
    db = MapDatabase(tmp_path / "db", config=fast)
    far = Cylinder(0.036, 0.09)  # x 1.2 on the radius: familiar, scaled
    db.add(far)
    first = adapt_cloud(pts, db=db, config=cfg, seed=1)
    (part,) = first.parts
    assert part.match.value == "familiar" and part.stored["key"] == db.key(far)
    r = part.primitive.dims["radius"]
    assert part.stored["ratio"] == pytest.approx(0.036 / r, rel=1e-9) and part.stored["ratio"] > 1.1
    # the map's own record names it too
    assert first.map.meta.extra["parts"][0]["stored"]["key"] == db.key(far)
    # the database grows by a map within 3 % of the part: now known, and the output says so
    near = Cylinder(round(r * 1.02, 5), round(part.primitive.dims["height"], 5))
    db.add(near)
    second = adapt_cloud(pts, db=db, config=cfg, seed=1)
    assert second.parts[0].match.value == "known" and second.parts[0].stored["key"] == db.key(near)
    # ... but the identification, and so the parts and the frame, did not change
    assert [p.primitive.to_dict() for p in second.parts] == [p.primitive.to_dict() for p in first.parts]
    np.testing.assert_array_equal(second.T_cloud_obj, first.T_cloud_obj)
    assert second.map.meta.extra["table"]["height"] == first.map.meta.extra["table"]["height"]
    # a fresh database gives the same map every time
    maps = []
    for k in range(2):
        fresh = MapDatabase(tmp_path / f"fresh{k}", config=fast)
        maps.append(adapt_cloud(pts, db=fresh, config=cfg, seed=1).map)
    assert len(maps[0]) == len(maps[1]) > 0
    np.testing.assert_array_equal(maps[0].wrist_position, maps[1].wrist_position)
    np.testing.assert_array_equal(maps[0].robust, maps[1].robust)


def test_table_auto_lies_at_the_cloud_never_under_a_fitted_shape_that_overshoots():
    from graspsim.geometry.table import TablePlane
    from graspsim.maps.table_clearance import table_height
    from graspsim.primitives import Box

    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.02, 0.02, 2000), rng.uniform(-0.02, 0.02, 2000), rng.uniform(0, 0.05, 2000)])
    box = Box(0.05, 0.05, 0.07)  # fitted over the object (or extrapolated behind a view), 1 cm below the cloud
    T = np.eye(4)
    T[2, 3] = 0.025
    auto = TablePlane()
    assert table_height(auto, pts, box, T) == pytest.approx(np.quantile(pts[:, 2], 0.005))
    assert table_height(auto, np.zeros((0, 3)), box, T) == pytest.approx(-0.01)  # no points: the shape's
    assert table_height(TablePlane(height=0.003), pts, box, T) == 0.003


# ------------------------------------------------------------------ the viewpoint
def _write_pcd(path: Path, pts: np.ndarray, viewpoint: str | None) -> None:
    head = ["# .PCD v0.7", "VERSION 0.7", "FIELDS x y z", "SIZE 4 4 4", "TYPE F F F", "COUNT 1 1 1",
            f"WIDTH {len(pts)}", "HEIGHT 1"] + ([f"VIEWPOINT {viewpoint}"] if viewpoint else []) + \
        [f"POINTS {len(pts)}", "DATA ascii"]
    path.write_text("\n".join(head) + "\n" + "\n".join(" ".join(f"{v:.6f}" for v in p) for p in pts) + "\n")


def test_the_pcd_viewpoint_header_is_read(tmp_path):
    from graspsim.errors import PointCloudError
    from graspsim.perception import read_point_cloud

    pts = _cylinder_cloud()
    _write_pcd(tmp_path / "a.pcd", pts, "0.1 -0.2 0.5 1 0 0 0")
    np.testing.assert_allclose(read_point_cloud(tmp_path / "a.pcd").viewpoint, [0.1, -0.2, 0.5])
    _write_pcd(tmp_path / "mm.pcd", 1000 * pts, "100 -200 500 1 0 0 0")
    np.testing.assert_allclose(read_point_cloud(tmp_path / "mm.pcd", units="mm").viewpoint, [0.1, -0.2, 0.5])
    # PCL writes the identity for every cloud, merged ones too: it says nothing
    _write_pcd(tmp_path / "b.pcd", pts, "0 0 0 1 0 0 0")
    assert read_point_cloud(tmp_path / "b.pcd").viewpoint is None
    _write_pcd(tmp_path / "c.pcd", pts, None)
    assert read_point_cloud(tmp_path / "c.pcd").viewpoint is None
    _write_pcd(tmp_path / "d.pcd", pts, "0 0 nan 1 0 0 0")
    with pytest.raises(PointCloudError, match="VIEWPOINT"):
        read_point_cloud(tmp_path / "d.pcd")


def test_identify_records_the_viewpoint(tmp_path, capsys):
    from graspsim.cli import main

    pts = _cylinder_cloud()
    _write_pcd(tmp_path / "a.pcd", pts, "0.1 -0.2 0.5 1 0 0 0")
    main(["identify", str(tmp_path / "a.pcd"), "--db", str(tmp_path / "db"), "--json"])
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["viewpoint"] == pytest.approx([0.1, -0.2, 0.5])
    main(["identify", str(tmp_path / "a.pcd"), "--db", str(tmp_path / "db"), "--json", "--viewpoint", "0", "0", "1"])
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["viewpoint"] == [0.0, 0.0, 1.0]
    assert main(["identify", str(tmp_path / "a.pcd"), "--viewpoint", "0", "nan", "1"]) != 0
    assert "--viewpoint" in capsys.readouterr().err


def test_identify_judges_the_fit_from_the_given_viewpoint(tmp_path, capsys):
    """The fit's coverage counts the surface facing the camera: the camera --viewpoint names,
    over the cloud's own record and for a cloud without one."""
    from graspsim.cli import main

    pts = _cylinder_cloud()
    pts = pts[pts[:, 0] > 0.005]  # the side a camera on +x sees
    _write_pcd(tmp_path / "a.pcd", pts, "-0.5 0 0.05 1 0 0 0")  # a record of another camera
    np.save(tmp_path / "a.npy", pts)

    def covered(*args):
        assert main(["identify", *map(str, args), "--db", str(tmp_path / "db"), "--json"]) == 0
        return json.loads(capsys.readouterr().out.strip().splitlines()[-1])["fit"]["covered"]

    seen = covered(tmp_path / "a.npy", "--viewpoint", 0.5, 0, 0.05)
    assert seen > 0.8
    assert covered(tmp_path / "a.pcd", "--viewpoint", 0.5, 0, 0.05) == pytest.approx(seen, abs=0.02)
    assert covered(tmp_path / "a.npy") < seen - 0.2  # judged as seen all round: the back is missing


@pytest.mark.slow
def test_adapt_takes_the_viewpoint_into_the_robust_score_and_records_it(tmp_path, capsys):
    from graspsim.cli import main
    from graspsim.maps import load_map
    from graspsim.primitives import Cylinder, synthetic_cloud

    T = np.eye(4)
    T[:3, 3] = [0.5, 0.0, 0.045]
    cam = np.array([0.5 + 0.45, 0.1, 0.4])
    pts = synthetic_cloud(Cylinder(0.03, 0.09), np.random.default_rng(3), resolution=0.003, noise=0.0005,
                          camera=cam, T_world_obj=T).points
    _write_pcd(tmp_path / "view.pcd", pts, " ".join(map(str, cam)) + " 1 0 0 0")
    args = ["--db", str(tmp_path / "db"), "--json", "--table", "auto", *COARSE]
    assert main(["adapt", str(tmp_path / "view.pcd"), "-o", str(tmp_path / "a.h5"), *args]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["viewpoint"] == pytest.approx(cam.tolist())
    m = load_map(tmp_path / "a.h5")
    assert m.meta.extra["viewpoint"] == pytest.approx(cam.tolist()) and m.meta.extra["robust"]["viewpoint"] is True
    # a single view's table lies at its lowest visible point (above the real one at z = 0), never under it
    assert m.meta.placement.table["height"] == pytest.approx(np.quantile(pts[:, 2], 0.005), abs=1e-6)
    assert m.meta.placement.table["height"] > 0.0
    assert s["parts"][0]["stored"]["key"]  # the stored map used, with its size ratio
    assert main(["trial", str(tmp_path / "a.h5"), "--top", "2", "--json", "--no-write"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["viewpoint"] == pytest.approx(cam.tolist())
    # --viewpoint wins over the file's; none at all: seen all round, no occlusion term
    np.save(tmp_path / "view.npy", pts)
    assert main(["adapt", str(tmp_path / "view.npy"), "-o", str(tmp_path / "b.h5"), *args]) == 0
    capsys.readouterr()
    b = load_map(tmp_path / "b.h5")
    assert b.meta.extra["viewpoint"] is None and b.meta.extra["robust"]["viewpoint"] is False


# ------------------------------------------------------------------ the unseen margin on a single view
class _Planned(Exception):
    """Raised by the stand-in planner once it has seen what ``adapt`` passes it."""


def test_adapt_passes_the_unseen_margin_to_the_planner(tmp_path, capsys, monkeypatch):
    """With a viewpoint, robust mode: the planner gets the default margin, the flag alone the
    measured one, a value that value, 0 none; paper mode none unless given; a cloud without
    a viewpoint none (nothing unseen). The planner is a stand-in: the option handling is
    under test here, the score in the slow test below."""
    import graspsim.planning.planner as planner
    from graspsim.cli import main
    from graspsim.maps.robust import UNSEEN_MARGIN
    from graspsim.planning.adapt import DEFAULT_UNSEEN_MARGIN

    seen = {}

    def stand_in(points, *, config, viewpoint, **kw):
        seen.update(margin=config.robust.unseen_margin, viewpoint=viewpoint)
        raise _Planned

    monkeypatch.setattr(planner, "plan", stand_in)
    np.save(tmp_path / "view.npy", _cylinder_cloud())
    head = ["adapt", str(tmp_path / "view.npy"), "-o", str(tmp_path / "a.h5"), "--db", str(tmp_path / "db")]
    cam = ["--viewpoint", "0.4", "0", "0.5"]
    for flag, want in (([*cam], DEFAULT_UNSEEN_MARGIN), ([*cam, "--unseen-margin"], UNSEEN_MARGIN),
                       ([*cam, "--unseen-margin", "0.01"], 0.01), ([*cam, "--unseen-margin", "0"], 0.0),
                       ([*cam, "--mode", "paper"], 0.0), ([*cam, "--mode", "paper", "--unseen-margin"], UNSEEN_MARGIN),
                       ([], 0.0), (["--unseen-margin", "0"], 0.0)):
        seen.clear()
        with pytest.raises(_Planned):
            main([*head, *flag])
        assert seen["margin"] == want and (seen["viewpoint"] is not None) == bool(flag[:1] == cam[:1]), flag
    assert DEFAULT_UNSEEN_MARGIN == UNSEEN_MARGIN > 0


@pytest.mark.parametrize("flags, says", [
    (["--unseen-margin", "0.5", "--viewpoint", "0", "0", "1"], "--unseen-margin must be in [0, 0.1] m"),
    (["--unseen-margin", "-0.01", "--viewpoint", "0", "0", "1"], "--unseen-margin must be in [0, 0.1] m"),
    (["--unseen-margin", "nan", "--viewpoint", "0", "0", "1"], "--unseen-margin must be in [0, 0.1] m"),
    (["--unseen-margin", "0.02"], "--unseen-margin needs the camera's place"),
    (["--unseen-margin"], "--unseen-margin needs the camera's place"),
])
def test_a_bad_unseen_margin_is_one_line_and_writes_nothing(tmp_path, capsys, flags, says):
    from graspsim.cli import main

    np.save(tmp_path / "view.npy", _cylinder_cloud())  # a .npy records no camera: no viewpoint
    out = tmp_path / "a.h5"
    code = main(["adapt", str(tmp_path / "view.npy"), "-o", str(out), "--db", str(tmp_path / "db"), *flags])
    err = capsys.readouterr().err.strip()
    assert code == 2 and says in err and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists() and not (tmp_path / "db").exists()  # refused before any work


def test_the_api_plans_a_cloud_without_a_viewpoint_without_the_margin(monkeypatch):
    import graspsim.planning.planner as planner
    from graspsim.errors import InvalidParameterError
    from graspsim.planning.adapt import DEFAULT_UNSEEN_MARGIN, adapt_cloud, adapt_config

    seen = []

    def stand_in(points, *, config, viewpoint, **kw):
        seen.append(config.robust.unseen_margin)
        raise _Planned

    monkeypatch.setattr(planner, "plan", stand_in)
    for vp, want in ((None, 0.0), (np.array([0.4, 0.0, 0.5]), DEFAULT_UNSEEN_MARGIN)):
        with pytest.raises(_Planned):
            adapt_cloud(_cylinder_cloud(), db=None, config=adapt_config(), viewpoint=vp)
        assert seen[-1] == want
    assert adapt_config(mode="paper").robust.unseen_margin == 0.0
    assert adapt_config(unseen_margin=0).robust.unseen_margin == 0.0
    for bad in (-0.01, 0.5, float("nan"), "abc"):
        with pytest.raises(InvalidParameterError, match="unseen_margin must be in"):
            adapt_config(unseen_margin=bad)


@pytest.mark.slow
def test_the_unseen_margin_changes_a_single_views_robust_scores_and_is_recorded(tmp_path, capsys):
    """A box seen from one side: with an unseen margin the robust score of grasps whose far
    finger passes near the fitted (unseen) back changes, and the map and the JSON record
    the margin; with --unseen-margin 0 the map records none."""
    from graspsim.cli import main
    from graspsim.maps import load_map
    from graspsim.primitives import Box, synthetic_cloud

    T = np.eye(4)
    T[:3, 3] = [0.5, 0.0, 0.03]
    cam = np.array([0.5 + 0.45, 0.1, 0.4])
    pts = synthetic_cloud(Box(0.05, 0.07, 0.06), np.random.default_rng(3), resolution=0.003, noise=0.0005,
                          camera=cam, T_world_obj=T).points
    np.save(tmp_path / "view.npy", pts)
    args = ["--db", str(tmp_path / "db"), "--json", "--table", "auto", "--viewpoint", *map(str, cam), *COARSE]
    runs = {}
    for name, flag in (("off", ["--unseen-margin", "0"]), ("on", ["--unseen-margin", "0.015"])):
        assert main(["adapt", str(tmp_path / "view.npy"), "-o", str(tmp_path / f"{name}.h5"), *args, *flag]) == 0
        runs[name] = (json.loads(capsys.readouterr().out.strip().splitlines()[-1]), load_map(tmp_path / f"{name}.h5"))
    (s_off, off), (s_on, on) = runs["off"], runs["on"]
    assert s_off["unseen_margin"] == 0.0 and off.meta.extra["robust"]["unseen_margin"] == 0.0
    assert s_on["unseen_margin"] == 0.015 and on.meta.extra["robust"]["unseen_margin"] == 0.015
    # the same grasps planned (the margin only scores and so orders them), scored otherwise
    a, b = (np.lexsort(np.c_[m.wrist_position, m.wrist_quat].T) for m in (off, on))
    np.testing.assert_array_equal(off.wrist_position[a], on.wrist_position[b])
    np.testing.assert_array_equal(off.wrist_quat[a], on.wrist_quat[b])
    r_off, r_on = off.robust[a], on.robust[b]
    scored = np.isfinite(r_off) & np.isfinite(r_on)
    assert scored.sum() > 10 and not np.allclose(r_off[scored], r_on[scored])
