"""Simulating map files: selection, object reconstruction, results written back."""

import h5py
import numpy as np
import pytest
import trimesh
from hand_made import grasp_pose, hand_made_map

from graspsim.errors import GraspsimError, MapFileError, SimulationError
from graspsim.maps import load_map, read_sim_results, save_map
from graspsim.primitives import Box, Cylinder
from graspsim.sim import TrialOutcome, select_grasps, simulate_map
from graspsim.transforms import make_transform


def _cylinder_map(n=6, mass=None, extra=None, shape=Cylinder(0.02, 0.20), width=0.04):
    ang = np.linspace(0.0, np.pi, n)
    z = np.linspace(-0.04, 0.04, n)
    T = np.stack([grasp_pose([0, 0, zi], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0])
                  for a, zi in zip(ang, z)])
    return hand_made_map(shape, T, np.full(n, width), grades=np.linspace(0.6, 1.0, n),
                         mass=mass, extra=extra)


def test_results_go_back_into_the_map_and_merge(tmp_path):
    path = save_map(_cylinder_map(), tmp_path / "cyl.h5")
    first = simulate_map(path, top=2, threads=1)
    assert first.index.tolist() == [5, 4]  # best grades first
    assert first.group == "grasps/qualities/mujoco"
    assert first.results.counts()["success"] == 2
    res = read_sim_results(path)
    assert res["simulated"].tolist() == [False] * 4 + [True] * 2
    assert res["object_in_gripper"].tolist() == [-1] * 4 + [1, 1]
    assert res["outcome"][5] == TrialOutcome.SUCCESS and np.isnan(res["lift_height"][0])
    assert res["info"]["protocol"]["name"] == "lift_place"
    assert res["info"]["mujoco_version"]
    simulate_map(path, sample=2, min_grade=0.0, threads=1, seed=1)  # same scene: merged
    res = read_sim_results(path)
    assert res["simulated"].sum() >= 3 and res["simulated"][5]
    assert len(load_map(path)) == 6  # the map itself is untouched


def test_tug_results_go_to_their_own_group(tmp_path):
    path = save_map(_cylinder_map(n=2), tmp_path / "cyl.h5")
    from graspsim.sim import Tug

    out = simulate_map(path, protocol=Tug(), threads=1)
    assert out.group == "grasps/qualities/mujoco_tug"
    assert read_sim_results(path, out.group)["object_in_gripper"].tolist() == [1, 1]


def test_select_grasps():
    m = _cylinder_map(n=10)
    rng = np.random.default_rng(0)
    assert select_grasps(m, top=3).tolist() == [9, 8, 7]
    idx = select_grasps(m, sample=4, min_grade=0.75, rng=rng)
    assert len(idx) == 4 and len(set(idx.tolist())) == 4
    assert np.all(m.grade[idx] > 0.75)
    assert select_grasps(m).tolist() == list(range(10))


def test_map_without_needed_keys_is_a_clear_error(tmp_path):
    path = tmp_path / "acronym_only.h5"  # an ACRONYM-style file (graspsim.maps.formats) without its object
    with h5py.File(path, "w") as f:
        f["grasps/transforms"] = np.repeat(np.eye(4)[None], 3, axis=0)
    with pytest.raises(MapFileError, match="names no object mesh"):
        simulate_map(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["acronym_only.h5"]  # nothing written
    with pytest.raises(MapFileError):
        simulate_map(tmp_path / "nope.h5")


def test_non_positive_map_mass_is_a_clear_error(tmp_path):
    path = save_map(_cylinder_map(n=1, mass=-0.3), tmp_path / "cyl.h5")
    with pytest.raises(SimulationError, match="mass"):
        simulate_map(path, write=False)


def test_mesh_option_places_the_real_object_by_the_cloud_transform(tmp_path):
    # the "real object" is a box mesh stored in the cloud (camera) frame; the map was
    # planned on a box primitive in the object frame, T_cloud_obj relates the two
    T_cloud_obj = make_transform(np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]), [0.4, -0.2, 0.7])
    mesh = trimesh.creation.box([0.06, 0.06, 0.06])
    mesh.apply_transform(T_cloud_obj)
    mesh_file = tmp_path / "real_box.stl"
    mesh.export(mesh_file)
    T = np.stack([grasp_pose([0, 0, 0], [-1, 0, 0], [0, 1, 0]), grasp_pose([0, 0, 0], [0, 0, -1], [1, 0, 0])])
    m = hand_made_map(Box(0.06, 0.06, 0.06), T, [0.06, 0.06], extra={"T_cloud_obj": T_cloud_obj.tolist()})
    path = save_map(m, tmp_path / "box.h5")
    out = simulate_map(path, mesh=mesh_file, threads=1, write=False)
    assert out.results.outcomes == [TrialOutcome.SUCCESS] * 2
    assert out.scene.obj.description["primitive"] == "mesh"
    # without the transform the mesh lies 0.8 m away from the map's poses
    bad = hand_made_map(Box(0.06, 0.06, 0.06), T, [0.06, 0.06])
    out = simulate_map(save_map(bad, tmp_path / "bad.h5"), mesh=mesh_file, threads=1, write=False)
    assert TrialOutcome.SUCCESS not in out.results.outcomes


def test_unreadable_mesh_is_a_clear_error(tmp_path):
    path = save_map(_cylinder_map(n=1), tmp_path / "cyl.h5")
    (tmp_path / "junk.obj").write_bytes(b"\x00\x01 not a mesh")
    with pytest.raises(GraspsimError):
        simulate_map(path, mesh=tmp_path / "junk.obj", write=False)


def test_a_planned_table_sets_which_way_up_the_object_stands(tmp_path):
    """An adapted map whose object frame is upside down in the cloud (a cylinder's axis
    sign is arbitrary) and that was planned for a table under the cloud's +z: the
    simulator stands the object as in the cloud, so a top grasp stays a top grasp."""
    cyl = Cylinder(0.02, 0.10)
    flip = make_transform(np.diag([1.0, -1.0, -1.0]), [0.5, 0.0, 0.05])  # object z = cloud -z
    # seen in the cloud from above: approach along cloud -z = object +z, near the object's -z end
    T = grasp_pose([0, 0, -0.035], [0, 0, 1], [1, 0, 0])[None]
    table = {"normal": [0.0, 0.0, 1.0], "height": 0.0, "clearance": 0.002, "dropped": 0}
    with_table = hand_made_map(cyl, T, [0.04], extra={"T_cloud_obj": flip.tolist(), "table": table})
    out = simulate_map(save_map(with_table, tmp_path / "t.h5"), threads=1, write=False)
    assert out.results.outcomes == [TrialOutcome.SUCCESS]
    # without the table the object rests on its own +z: the same pose comes from below
    bare = hand_made_map(cyl, T, [0.04], extra={"T_cloud_obj": flip.tolist()})
    out = simulate_map(save_map(bare, tmp_path / "b.h5"), threads=1, write=False)
    assert out.results.outcomes == [TrialOutcome.START_COLLISION]
