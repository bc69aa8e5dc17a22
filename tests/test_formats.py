"""Third-party grasp files: frames, reading, writing, round trips (graspsim.maps.formats / export).

The ACRONYM files here are generated in ACRONYM's layout (no dataset file is shipped: the
example grasps are CC BY-NC and their mug mesh is ShapeNet's); the layout is the one
``acronym_tools.load_grasps`` / ``load_mesh`` read (NVlabs/acronym, MIT), mirrored in
:func:`_acronym_load_grasps`, and checked with the real reader when it is installed.
"""

import hashlib
import json
import os

import h5py
import numpy as np
import pytest
import trimesh
from hand_made import grasp_pose, hand_made_map

from graspsim.errors import GraspsimError, MapFileError
from graspsim.grippers import get_gripper
from graspsim.maps import load_map, read_sim_results, save_map, write_sim_results
from graspsim.maps.export import export_map
from graspsim.maps.formats import (
    GRASPNET_AXES,
    detect_format,
    grasp_frame,
    graspnet_to_wrist,
    read_grasp_file,
)
from graspsim.maps.imported import SOURCE_GROUP, imported_path
from graspsim.primitives import Box
from graspsim.transforms import invert_transform, make_transform

FRANKA = get_gripper("franka_hand")
# The hand part (z < 5.8 cm) of ACRONYM's data/franka_gripper_collision_mesh.stl (and of
# GraspGen's assets/panda_gripper/hand.stl, the same bounds), in ACRONYM's gripper frame [m]:
ACRONYM_HAND_BOUNDS = np.array([[-0.10043, -0.03164, -0.02592], [0.10399, 0.03162, 0.05690]])


# ACRONYM's reader, github.com/NVlabs/acronym acronym_tools/acronym.py at d02f58f (MIT), is not on
# PyPI; the two functions below make exactly its h5py / trimesh calls for an .h5 file, nothing else:
#   load_grasps (l. 381-400): data = h5py.File(filename, "r"); T = np.array(data["grasps/transforms"])
#       success = np.array(data["grasps/qualities/flex/object_in_gripper"])
#   load_mesh (l. 354-378): mesh_fname = data["object/file"][()].decode('utf-8')
#       mesh_scale = data["object/scale"][()]; obj_mesh = trimesh.load(os.path.join(mesh_root_dir, mesh_fname))
#       obj_mesh = obj_mesh.apply_scale(mesh_scale)
def _acronym_load_grasps(filename):
    """``acronym_tools.load_grasps`` for an .h5 file (see above)."""
    data = h5py.File(filename, "r")
    T = np.array(data["grasps/transforms"])
    success = np.array(data["grasps/qualities/flex/object_in_gripper"])
    data.close()
    return T, success


def _acronym_load_mesh(filename, mesh_root_dir):
    """``acronym_tools.load_mesh`` for an .h5 file (see above)."""
    data = h5py.File(filename, "r")
    mesh_fname = data["object/file"][()].decode("utf-8")
    mesh_scale = data["object/scale"][()]
    data.close()
    obj_mesh = trimesh.load(os.path.join(mesh_root_dir, mesh_fname))
    return obj_mesh.apply_scale(mesh_scale)


def _box_mesh(tmp_path, extents=(0.05, 0.12, 0.08)):
    path = tmp_path / "meshes" / "box.obj"
    path.parent.mkdir(exist_ok=True)
    trimesh.creation.box(extents=extents).export(path)
    return path


def _write_acronym(path, T, labels, mesh_rel="meshes/box.obj", scale=1.0, mass=0.1):
    """A grasp file in ACRONYM's layout, as the dataset's files are."""
    with h5py.File(path, "w") as f:
        f["grasps/transforms"] = T
        f["grasps/qualities/flex/object_in_gripper"] = np.asarray(labels, np.int64)
        f["object/file"] = np.bytes_(mesh_rel.encode())
        f["object/scale"] = scale
        f["object/mass"] = mass
        f["object/friction"] = 1.0
        f["gripper/type"] = np.bytes_(b"panda")
        f["gripper/configuration"] = np.array([0.04])


def _acronym_top_grasp(depth_below_top, top=0.04, turn=0.0):
    """ACRONYM Franka pose: approaching the box top (-z), fingers (x_A) along the object's
    x turned ``turn`` about the approach, the pad centre (z_A = 10.34 cm, the franka_ros TCP)
    ``depth_below_top`` below the top face."""
    c, s = np.cos(turn), np.sin(turn)
    x = np.array([c, s, 0.0])
    z = np.array([0.0, 0.0, -1.0])
    R = np.stack([x, np.cross(z, x), z], axis=1)
    return make_transform(R, np.array([0.0, 0.0, top - depth_below_top + 0.1034]))


# ---------------------------------------------------------------------- frames
def test_franka_frame_matches_acronym_gripper_mesh():
    """The vendored hand's hull, carried into ACRONYM's frame by T_grasp_wrist, spans
    ACRONYM's own gripper mesh (asymmetric in x by 3.6 mm: a wrong turn about z shows)."""
    from graspsim._gl import import_mujoco
    from graspsim.grippers.franka import franka_hand_mount, hand_to_wrist, hull_points
    from graspsim.grippers.vendored import model_folder

    mujoco = import_mujoco()
    model = mujoco.MjModel.from_xml_path(str(model_folder("franka_hand") / "franka_hand.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    z0 = -float(franka_hand_mount().pos[2])  # the hand frame sits at (0, 0, -z0) in the wrist frame
    hull_W = hand_to_wrist(hull_points(model, data, "hand_collision"), z0)
    T = grasp_frame(FRANKA)
    hull_A = hull_W @ T[:3, :3].T + T[:3, 3]
    assert np.allclose(hull_A.min(0), ACRONYM_HAND_BOUNDS[0], atol=2e-4)
    assert np.allclose(hull_A.max(0)[:2], ACRONYM_HAND_BOUNDS[1][:2], atol=2e-4)
    # a 180 deg turn about the approach and 25.93 mm along it
    assert np.allclose(T[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    assert T[2, 3] == pytest.approx(-0.02593, abs=1e-6)
    assert np.allclose(grasp_frame(get_gripper()), np.eye(4))  # other grippers: the wrist frame


@pytest.mark.slow
def test_acronym_grasp_closes_on_the_same_box_faces_in_mujoco(tmp_path):
    """A grasp that closes on the 5 cm faces of a 5 x 12 x 8 cm box in ACRONYM's
    convention holds in graspsim's simulation; turned 90 deg (fingers across the 12 cm
    faces, wider than the hand opens) it cannot start. Mutation: without the 25.93 mm
    offset (T_grasp_wrist = I) the palm starts inside the box and the first grasp fails."""
    from graspsim.sim import TrialOutcome, make_protocol, simulate_map

    _box_mesh(tmp_path)
    T = np.stack([_acronym_top_grasp(0.018), _acronym_top_grasp(0.018, turn=np.pi / 2)])
    path = tmp_path / "Box_test.h5"
    _write_acronym(path, T, [1, 0])
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    out = simulate_map(path, protocol=make_protocol("tug"), threads=1)
    assert out.results.outcome[0] == TrialOutcome.SUCCESS
    assert out.results.outcome[1] == TrialOutcome.START_COLLISION
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before  # the dataset file untouched
    assert out.file == imported_path(path)
    assert read_sim_results(out.file, out.group)["object_in_gripper"].tolist() == [1, 0]
    src = read_sim_results(out.file, SOURCE_GROUP)
    assert src["object_in_gripper"].tolist() == [1, 0] and src["info"]["label_source"] == "FleX (ACRONYM)"


def test_graspnet_grasp_point_is_the_tcp_at_its_depth():
    """GraspNet: x approach, y closing, the centre ``depth`` behind the fingertips."""
    R_G = np.eye(3)[None]
    T = graspnet_to_wrist(R_G, np.array([[0.1, 0.0, 0.0]]), np.array([0.02]), FRANKA)[0]
    assert np.allclose(T[:3, 2], [1, 0, 0]) and np.allclose(T[:3, 0], [0, 1, 0])  # approach, closing
    tip = T[:3, 3] + FRANKA.fingertip_z * T[:3, 2]
    assert tip[0] == pytest.approx(0.12)  # the fingertips reach 2 cm past the centre
    assert np.allclose(T[:3, :3] @ GRASPNET_AXES, R_G[0])


# ---------------------------------------------------------------------- reading
def test_acronym_file_reads_with_missing_grades_and_its_labels(tmp_path):
    _box_mesh(tmp_path)
    T = np.stack([_acronym_top_grasp(0.018, turn=a) for a in np.linspace(0, 3, 5)])
    path = tmp_path / "grasps" / "Box.h5"
    path.parent.mkdir()
    _write_acronym(path, T, [1, 0, 1, 1, 0], mesh_rel="meshes/box.obj")  # ACRONYM's grasps/ + meshes/
    assert detect_format(path) == "acronym"
    gf = read_grasp_file(path)
    g = gf.gmap
    assert len(g) == 5 and np.isnan(g.grade).all() and g.summary()["graded"] == 0
    assert gf.labels["object_in_gripper"].tolist() == [1, 0, 1, 1, 0]
    assert g.meta.object["file"] == str((tmp_path / "meshes" / "box.obj").resolve())
    assert g.meta.gripper_spec == FRANKA and g.meta.quality["friction"] == 1.0
    assert np.allclose(FRANKA.pregrasp_opening(g.width), 0.08)  # opened as ACRONYM's 0.04 per finger
    assert np.allclose(g.T_obj_wrist, T @ grasp_frame(FRANKA), atol=1e-7)
    # the grasp point: the pad centre ACRONYM put 1.8 cm below the top (z = 4 cm)
    assert np.allclose(g.grasp_point[:, 2], 0.04 - 0.018, atol=2e-4)
    assert len(g.uniform_surface_rows(3, np.random.default_rng(0))) == 3  # no contacts: by TCP


def test_foreign_gripper_and_bad_files_are_clear_errors(tmp_path):
    path = tmp_path / "r.h5"
    _write_acronym(path, np.eye(4)[None], [1])
    with h5py.File(path, "r+") as f:
        del f["gripper/type"]
        f["gripper/type"] = np.bytes_(b"robotiq_2f_85")
    with pytest.raises(MapFileError, match="robotiq_2f_85"):
        read_grasp_file(path)
    assert read_grasp_file(path, gripper="franka_hand").gmap.meta.gripper["name"] == "franka_hand"
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((3, 16)))
    with pytest.raises(MapFileError, match="17"):
        read_grasp_file(bad)
    j = tmp_path / "g.json"
    j.write_text(json.dumps({"object": {"file": "x.obj", "scale": 1}, "grasps": {"transforms": [[1, 2]]}}))
    with pytest.raises(MapFileError, match="4, 4"):
        read_grasp_file(j)


def test_graspnet_camera_frame_and_object_id(tmp_path):
    rng = np.random.default_rng(3)
    T_cam_obj = make_transform(trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3],
                               np.array([0.1, -0.2, 0.6]))
    R = np.stack([trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3] for _ in range(4)])
    t = rng.normal(0, 0.03, (4, 3))
    a = np.zeros((4, 17))
    a[:, 0], a[:, 1], a[:, 2], a[:, 3] = [0.9, 0.1, 0.5, 0.3], 0.06, 0.02, 0.02
    a[:, 4:13] = (T_cam_obj[:3, :3] @ R).reshape(4, 9)
    a[:, 13:16] = t @ T_cam_obj[:3, :3].T + T_cam_obj[:3, 3]
    a[:, 16] = [7, 7, 9, 7]
    np.save(tmp_path / "g.npy", a)
    gf = read_grasp_file(tmp_path / "g.npy", mesh=_box_mesh(tmp_path), T_camera_obj=T_cam_obj, object_id=7)
    want = graspnet_to_wrist(R[[0, 1, 3]], t[[0, 1, 3]], np.full(3, 0.02), FRANKA)
    assert np.allclose(gf.gmap.T_obj_wrist, want, atol=1e-6)
    assert gf.labels["score"].tolist() == [0.9, 0.1, 0.3]
    assert np.allclose(FRANKA.pregrasp_opening(gf.gmap.width), 0.06)


# ---------------------------------------------------------------------- writing, round trips
def _franka_box_map(tmp_path, gripper=FRANKA):
    box = Box(0.05, 0.06, 0.08)
    rng = np.random.default_rng(1)
    poses = []
    for _ in range(6):
        a = rng.normal(size=3)
        a[2] = -abs(a[2]) - 1
        a /= np.linalg.norm(a)
        c = np.cross(a, [0.0, 1.0, 0.0])
        poses.append(grasp_pose(rng.normal(0, 0.01, 3), a, c / np.linalg.norm(c), depth=0.008, gripper=gripper))
    gmap = hand_made_map(box, np.stack(poses), np.linspace(0.03, 0.06, 6), gripper=gripper,
                         grades=np.linspace(0.2, 0.95, 6), depth=0.008, mass=0.2)
    path = save_map(gmap, tmp_path / "box.h5")
    sim = {"object_in_gripper": np.array([1, 0, -1, 1, 1, 0], np.int8),
           "simulated": np.array([1, 1, 0, 1, 1, 1], bool)}
    write_sim_results(path, sim, attrs_json={"protocol": {"name": "lift_place"}, "mujoco_version": "3.x"})
    return load_map(path), path


@pytest.mark.parametrize("fmt,suffix", [("acronym", ".h5"), ("graspgen", ".json"), ("graspnet", ".npy")])
@pytest.mark.parametrize("gripper", ["franka_hand", "festo_hgpl_25_60_a"])
def test_round_trip_poses_and_labels(tmp_path, fmt, suffix, gripper):
    """Written and read back: the same wrist poses (<= 1e-9), labels, widths and grades.
    Mutations caught: GraspNet depth measured from the wrong end; the ACRONYM frame not
    inverted on writing; labels written as grades."""
    gmap, path = _franka_box_map(tmp_path, get_gripper(gripper))
    out = tmp_path / f"export{suffix}"
    files = export_map(gmap, fmt, out, map_path=path)
    assert files[0] == out and all(f.is_file() for f in files)
    back = read_grasp_file(out).gmap
    assert np.abs(back.T_obj_wrist - gmap.T_obj_wrist).max() <= 1e-9
    assert np.array_equal(back.width, gmap.width) and np.array_equal(back.grade, gmap.grade)
    assert back.meta.gripper_spec == gmap.meta.gripper_spec
    assert back.meta.object["mass"] == pytest.approx(0.2) and back.meta.quality["friction"] == 0.5
    labels = read_grasp_file(out).labels["object_in_gripper"]
    assert labels.tolist() == [1, 0, -1, 1, 1, 0]
    assert (tmp_path / "export.obj").is_file()  # the box primitive as the format's mesh


def test_acronym_export_loads_with_acronyms_reader(tmp_path):
    """A Franka-hand map exported as ACRONYM is read by ACRONYM's own calls: its grasps in
    ACRONYM's gripper frame, its labels (1 held, 0 not, -1 not simulated: ACRONYM's scripts
    select ``success == 1`` / ``== 0``) and its mesh at its scale. Mutations caught: labels
    written elsewhere (KeyError), the wrist poses written without the frame change."""
    gmap, path = _franka_box_map(tmp_path)
    out = tmp_path / "a.h5"
    export_map(gmap, "acronym", out, map_path=path)
    T, success = _acronym_load_grasps(str(out))
    assert T.shape == (6, 4, 4) and success.tolist() == [1, 0, -1, 1, 1, 0]
    assert np.allclose(T, gmap.T_obj_wrist @ invert_transform(grasp_frame(FRANKA)), atol=1e-12)
    mesh = _acronym_load_mesh(str(out), str(tmp_path))
    assert mesh.extents == pytest.approx([0.05, 0.06, 0.08])
    with h5py.File(out, "r") as f:
        assert f["object/file"][()].decode("utf-8") == "a.obj" and f["object/scale"][()] == 1.0
        assert f["gripper/type"][()] == b"panda"
        record = json.loads(f.attrs["graspsim"])
    assert record["label_source"].startswith("MuJoCo") and "lift_place" in record["label_source"]
    try:
        from acronym_tools import load_grasps, load_mesh
    except ImportError:
        return  # the mirror above reads the same datasets the same way
    T2, s2 = load_grasps(str(out))
    assert np.array_equal(T2, T) and np.array_equal(s2, success)
    assert load_mesh(str(out), str(tmp_path)).extents == pytest.approx([0.05, 0.06, 0.08])


def test_graspgen_export_is_graspgens_json(tmp_path):
    gmap, path = _franka_box_map(tmp_path)
    out = tmp_path / "g.json"
    export_map(gmap, "graspgen", out, map_path=path, label="grade")
    d = json.loads(out.read_text())  # as GraspGen's GRASP_DATASET_FORMAT.md describes its loader
    grasps = np.array(d["grasps"]["transforms"])
    mask = np.array(d["grasps"]["object_in_gripper"])
    assert mask.dtype == bool and mask.tolist() == (gmap.grade > 0.7).tolist()
    assert grasps[mask].shape == (int(mask.sum()), 4, 4)
    assert d["object"] == {"file": "g.obj", "scale": 1.0}
    assert d["graspsim"]["label_source"].startswith("graspsim analytic grade > 0.7")


def test_imported_map_views_and_infos_without_grades(tmp_path, capsys):
    from graspsim.cli import main
    from graspsim.viewer.columns import Selection, ViewData

    _box_mesh(tmp_path)
    path = tmp_path / "Box.h5"
    _write_acronym(path, np.stack([_acronym_top_grasp(0.018, turn=a) for a in (0.0, 1.0, 2.0)]), [1, 0, 1])
    data = ViewData.from_grasp_file(path)
    assert len(data.selected(Selection())) == 3  # no grade: not filtered out by one
    assert "source/object_in_gripper" in data.colour_names()
    assert main(["info", str(path), "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["format"] == "acronym" and s["grasps"] == 3 and s["labels"] == ["object_in_gripper"]
    with pytest.raises(GraspsimError):  # nothing has a grade
        export_map(read_grasp_file(path).gmap, "acronym", tmp_path / "x.h5", label="grade")


def test_trial_of_a_dataset_against_its_mesh_surface(tmp_path, capsys):
    """``graspsim trial FILE --mesh-model surface`` simulates the file's own mesh (found
    beside it, at its scale) as its surface, writes beside the file and leaves it as it
    was; a map whose object is not a mesh is refused in one line."""
    from graspsim.cli import main

    _box_mesh(tmp_path)
    path = tmp_path / "Box.h5"
    _write_acronym(path, np.stack([_acronym_top_grasp(0.018), _acronym_top_grasp(0.018, turn=np.pi / 2)]), [1, 0])
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    assert main(["trial", str(path), "--protocol", "tug", "--mesh-model", "surface", "--threads", "1",
                 "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["mesh_model"]["method"] == "surface" and s["mesh_model"]["parts"] == 12  # a box: 12 triangles
    assert s["counts"]["success"] == 1 and s["counts"]["start_collision"] == 1
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
    gmap, map_path = _franka_box_map(tmp_path)
    assert main(["trial", str(map_path), "--top", "1", "--mesh-model", "surface", "--threads", "1"]) != 0
    assert "--mesh-model surface needs a mesh" in capsys.readouterr().err
