"""Grippers from their model files: the measured spec, the opening table, the harness."""

import json
import shutil

import mujoco
import numpy as np
import pytest
from hand_made import grasp_pose
from scipy.spatial import ConvexHull

from graspsim.errors import GripperError
from graspsim.grippers import get_gripper, load_model_gripper, model_folder, mount
from graspsim.grippers.model_file import GRID, pad_arc, straight_line_error
from graspsim.sim import LiftPlace, TrialOutcome, build_scene, object_from_shape, run_trials
from graspsim.sim.authored_model import PREFIX
from graspsim.sim.harness import build_gripper_spec

MODELS = ("franka_hand", "rethink_gripper", "robotiq_2f85")
TOL = 1.5e-4  # [m] the Franka finger mesh's inner face lies 0.1 mm past its joint's zero

# The Franka hand's spec as graspsim/grippers/franka.py measured it before every model
# file went through graspsim/grippers/model_file.py (commit e36382a): the same spec,
# digest and maps.
FRANKA_BEFORE = {
    "name": "franka_hand", "housing_size": [0.208, 0.06328, 0.0919], "jaw_size": [0.02596, 0.02099, 0.0286],
    "finger_size": [0.01987, 0.01918, 0.01768], "pad_length": 0.01768, "contact_depth_margin": 0.005,
    "stroke_per_jaw": 0.04, "closed_gap": 0.0, "approach_clearance": 0.005, "bore": 0.025, "pressure": 600000.0,
    "efficiency": 0.85, "closing_speed": 0.2, "housing_mass": 0.81, "jaw_mass": 0.07598, "finger_mass": 0.02402,
    "arm_length": 0.1, "rated_force": 70.0, "model": "franka_hand"}


def _surface(p: np.ndarray, n: int = 600) -> np.ndarray:
    """A hull's vertices and seeded samples on its faces (a union of boxes is not convex)."""
    hull = ConvexHull(p)
    rng = np.random.default_rng(37)
    tri = p[hull.simplices[rng.integers(len(hull.simplices), size=n)]]
    w = rng.dirichlet(np.ones(3), size=n)
    return np.concatenate([p[hull.vertices], np.einsum("nk,nkj->nj", w, tri)])


_SURFACES: dict = {}


def _local(m, g: int) -> np.ndarray:
    """A collision geom's hull points in its own frame (mesh: its vertices; box: corners;
    the Rethink base's cylinder: its bounding box)."""
    corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        mid = m.geom_dataid[g]
        return m.mesh_vert[m.mesh_vertadr[mid]:m.mesh_vertadr[mid] + m.mesh_vertnum[mid]].astype(float)
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
        return corners * m.geom_size[g]
    r, h = m.geom_size[g][:2]
    return corners * [r, r, h]


def _hulls(m, d, geoms, wrist, surface: bool = False) -> dict[str, np.ndarray]:
    """Collision hull points in the wrist frame (``surface``: with samples on its faces)."""
    R, p = d.xmat[wrist].reshape(3, 3), d.xpos[wrist]
    out = {}
    for g in geoms:
        if surface:
            v = _SURFACES.get((id(m), g))
            if v is None:
                v = _SURFACES[id(m), g] = _surface(_local(m, g))
        else:
            v = _local(m, g)
        w = d.geom_xpos[g] + v @ d.geom_xmat[g].reshape(3, 3).T
        out[m.geom(g).name] = (w - p) @ R
    return out


def _inner(m, d, pads, wrist) -> tuple[float, float]:
    """x [m] of the innermost points of the two fingers (the pads' bodies), from the pads'
    tops to the tips, in the wrist frame: the pad gap is their difference."""
    out = []
    for s, p in enumerate(pads):
        top = _hulls(m, d, [p], wrist)[m.geom(p).name][:, 2].min()
        body = [i for i in range(m.ngeom) if m.geom_bodyid[i] == m.geom_bodyid[p]
                and (m.geom_contype[i] or m.geom_conaffinity[i])]
        v = np.concatenate(list(_hulls(m, d, body, wrist).values()))
        v = v[v[:, 2] >= top - 1e-9]
        out.append(v[:, 0].min() if s else v[:, 0].max())
    return out[0], out[1]


@pytest.fixture(scope="module", params=MODELS)
def mounted(request):
    g = get_gripper(request.param)
    spec = build_gripper_spec(g)
    m = spec.compile()
    return g, mount(g.model), m


def test_the_measured_spec_encloses_the_collision_hulls_at_every_opening(mounted):
    g, mnt, m = mounted
    d = mujoco.MjData(m)
    wrist = m.body("wrist").id
    geoms = [i for i in range(m.ngeom) if m.body_rootid[m.geom_bodyid[i]] == wrist
             and (m.geom_contype[i] or m.geom_conaffinity[i])]
    rows = mnt.openings
    for w in np.unique(np.concatenate([rows, 0.5 * (rows[1:] + rows[:-1])])):  # the rows and between them
        for n, q in zip(mnt.joints, mnt.joint_positions([w])[0]):
            d.qpos[m.joint(PREFIX + n).qposadr[0]] = q
        mujoco.mj_kinematics(m, d)
        c, h = g.boxes_at(float(np.clip(w, g.min_opening, g.max_opening)))
        for name, p in _hulls(m, d, geoms, wrist, surface=True).items():
            inside = np.all(np.abs(p[:, None, :] - c[None]) <= h[None] + TOL, axis=-1).any(axis=1)
            assert inside.all(), (g.name, w, name, p[~inside][:3])


def test_the_pads_sit_at_the_spec_gap_across_the_range(mounted):
    g, mnt, m = mounted
    d = mujoco.MjData(m)
    wrist = m.body("wrist").id
    pads = [m.geom(PREFIX + n).id for n in mnt.pad_geoms]
    for w in np.linspace(g.min_opening, g.max_opening, 5):
        for n, q in zip(mnt.joints, mnt.joint_positions([w])[0]):
            d.qpos[m.joint(PREFIX + n).qposadr[0]] = q
        mujoco.mj_kinematics(m, d)
        hull = _hulls(m, d, pads, wrist)
        neg, pos = (hull[m.geom(p).name] for p in pads)
        inner = _inner(m, d, pads, wrist)
        assert inner[1] - inner[0] == pytest.approx(w, abs=5e-4), g.name
        assert inner[1] == pytest.approx(w / 2, abs=5e-4)  # symmetric about the wrist axis
        for p in (neg, pos):  # the planned pad region lies on the pad at every opening
            lo, hi = g.tcp_offset(g.depth_hi), g.tcp_offset(g.depth_lo)
            assert p[:, 2].min() <= lo + 1e-6 and hi <= p[:, 2].max() + 1e-6


def test_franka_hand_through_the_model_file_path_keeps_its_spec_and_digest():
    # the maps before and after agree: a map depends on the gripper only through its spec
    assert get_gripper("franka_hand").to_dict() == FRANKA_BEFORE
    f = mount("franka_hand")
    assert f.pos == pytest.approx((0.0, 0.0, 0.02593)) and f.quat == pytest.approx((np.sqrt(0.5), 0, 0, -np.sqrt(0.5)))
    assert f.jaw_joints == ("finger_joint2", "finger_joint1") and f.actuators == ("grip",)


def test_the_2f85_pad_arc_matches_the_stepped_model_within_half_a_millimetre():
    g = get_gripper("robotiq_2f85")
    mnt = mount("robotiq_2f85")
    assert not mnt.prismatic and np.ptp(mnt.pad_z) > 0.005  # a linkage: the pads rise and fall by mm
    err = straight_line_error(g, mnt)
    assert g.arc_error == pytest.approx(np.abs(err["centre_offset"]).max(), abs=GRID)
    assert min(np.min(err["margin_upper"]), np.min(err["margin_lower"])) >= 0  # conservative at every row
    offsets = []
    spec = build_gripper_spec(g)
    spec.option.gravity = [0.0, 0.0, 0.0]
    m = spec.compile()
    d = mujoco.MjData(m)
    wrist = m.body("wrist").id
    pads = [m.geom(PREFIX + n).id for n in mnt.pad_geoms]
    acts = [m.actuator(PREFIX + a).id for a in mnt.actuators]
    d.ctrl[acts] = mnt.ctrl_open
    mujoco.mj_step(m, d, nstep=200)
    checked = 0
    for t in (0.06, 0.13, 0.21, 0.27, 0.31, 0.36):  # between the table's rows, closing from open as it was stepped
        target = mnt.ctrl_open + t * (mnt.ctrl_close - mnt.ctrl_open)
        c0 = d.ctrl[acts].copy()
        for k in range(50):
            d.ctrl[acts] = c0 + (target - c0) * (k + 1) / 50
            mujoco.mj_step(m, d)
        mujoco.mj_step(m, d, nstep=100)
        for _ in range(30):  # to rest, as the table was measured
            if np.abs(d.qvel[[m.joint(PREFIX + n).dofadr[0] for n in mnt.joints]]).max() < 1e-3:
                break
            mujoco.mj_step(m, d, nstep=50)
        hull = _hulls(m, d, pads, wrist)
        neg, pos = (hull[m.geom(p).name] for p in pads)
        inner = _inner(m, d, pads, wrist)
        gap = inner[1] - inner[0]
        if not g.min_opening <= gap <= g.max_opening:
            continue
        z = np.array([0.5 * (p[:, 2].min() + p[:, 2].max()) for p in (neg, pos)])
        assert np.abs(pad_arc(mnt, [gap])[0] - z).max() < 5e-4, (t, gap, z, pad_arc(mnt, [gap]))
        # the straight-line model's error the spec states holds for the stepped model: its
        # pad centres lie within arc_error of the nominal TCP, the stated offset at this
        # gap matches, and the planned contact region lies on both pads
        offset = z - g.nominal_tcp[2]
        assert np.abs(offset).max() <= g.arc_error + 5e-4, (gap, offset, g.arc_error)
        stated = np.array([np.interp(gap, err["openings"], c) for c in np.array(err["centre_offset"]).T])
        assert np.abs(stated - offset).max() < 5e-4, (gap, stated, offset)
        lo, hi = err["planned"]
        assert all(p[:, 2].min() <= lo + 5e-4 and hi <= p[:, 2].max() + 5e-4 for p in (neg, pos)), (gap, lo, hi)
        offsets.append(offset.mean())
        checked += 1
    assert checked >= 3
    assert np.ptp(offsets) > 1e-3  # the samples span the arc: the error changes with the opening


@pytest.mark.parametrize("name", ["rethink_gripper", "robotiq_2f85"])
def test_a_top_down_grasp_lifts_a_box_with_the_models_own_drive(name):
    g = get_gripper(name)
    scene = build_scene(object_from_shape(__import__("graspsim").Box(0.04, 0.04, 0.04)), g)
    T = grasp_pose(depth=g.depth_lo, gripper=g, grasp_point=[0, 0, 0.012], approach=[0, 0, -1], closing=[1, 0, 0])
    r = run_trials(scene, T[None], [0.04], LiftPlace(), threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS, TrialOutcome(int(r.outcome[0]))
    assert min(r.metrics["pad_force_neg"][0], r.metrics["pad_force_pos"][0]) >= 0.9 * g.grip_force


def _write(tmp_path, body: str, name: str = "thing.xml") -> str:
    p = tmp_path / name
    p.write_text(f'<mujoco model="thing"><worldbody>{body}</worldbody></mujoco>')
    return str(p)


def test_a_model_with_no_identifiable_fingers_is_one_clear_line(tmp_path):
    no_joint = _write(tmp_path, '<body name="base"><geom type="box" size="0.05 0.02 0.02"/></body>')
    with pytest.raises(GripperError, match="no fingers found: the model has no slide or hinge joint") as err:
        get_gripper(no_joint)
    assert "\n" not in str(err.value) and "thing.xml" in str(err.value) and "'root_body'" in str(err.value)
    no_actuator = _write(tmp_path, '<body name="base"><geom type="box" size="0.05 0.02 0.02"/>'
                         '<body name="f"><joint type="slide" axis="1 0 0" range="0 0.03"/>'
                         '<geom type="box" size="0.01 0.01 0.03" pos="0 0 0.05"/></body></body>', "t2.xml")
    with pytest.raises(GripperError, match="no actuator"):
        get_gripper(no_actuator)
    one_finger = tmp_path / "t3.xml"
    one_finger.write_text(
        '<mujoco><worldbody><body name="base"><geom type="box" size="0.05 0.02 0.02"/>'
        '<body name="f"><joint name="j" type="slide" axis="0 0 1" range="0 0.03"/>'
        '<geom type="box" size="0.01 0.01 0.03" pos="0 0 0.06"/></body></body></worldbody>'
        '<actuator><motor joint="j" ctrlrange="-1 1" gear="10"/></actuator></mujoco>')
    with pytest.raises(GripperError, match="pad_geoms") as err:  # moves, but nothing closes on anything
        get_gripper(str(one_finger))
    assert "\n" not in str(err.value)
    with pytest.raises(GripperError, match="unknown options"):
        load_model_gripper(no_joint, colour="red")


def test_a_copied_model_file_loads_with_its_sidecar_and_gives_the_same_spec(tmp_path):
    src = model_folder("rethink_gripper")
    shutil.copytree(src, tmp_path / "rethink")
    path = tmp_path / "rethink" / "rethink_gripper.xml"
    g = get_gripper(str(path))
    vendored = get_gripper("rethink_gripper")
    assert g.model == str(path.resolve()) and g.name == "rethink_gripper"
    assert {k: v for k, v in g.to_dict().items() if k != "model"} == \
        {k: v for k, v in vendored.to_dict().items() if k != "model"}
    (tmp_path / "rethink" / "rethink_gripper.gripper.json").write_text(json.dumps({"grip_force": 15.0, "name": "mine"}))
    g2 = get_gripper(str(path))
    assert g2.grip_force == 15.0 and g2.name == "mine"


@pytest.mark.slow
def test_gripper_model_file_through_the_cli_on_a_tiny_map(tmp_path, capsys):
    from graspsim.cli import main
    from graspsim.maps import load_map

    shutil.copytree(model_folder("rethink_gripper"), tmp_path / "g")
    model = str(tmp_path / "g" / "rethink_gripper.xml")
    f = tmp_path / "box.h5"
    assert main(["map", "box", "--x", "0.04", "--y", "0.04", "--z", "0.04", "-o", str(f), "--surface-step", "0.01",
                 "--rotation-step-deg", "22", "--gripper", model, "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["gripper"] == "rethink_gripper"
    gmap = load_map(f)
    assert gmap.meta.gripper_spec.model == str((tmp_path / "g" / "rethink_gripper.xml").resolve())
    assert main(["trial", str(f), "--sample", "6", "--min-grade", "0.7", "--threads", "1", "--no-write",
                 "--json"]) == 0  # simulates the map's own gripper: the model file, as authored
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["trials"] == 6 and s["counts"]["success"] == s["feasible"] >= 1
    (tmp_path / "g" / "rethink_gripper.xml").write_text("<mujoco><worldbody><body/></worldbody></mujoco>")
    assert main(["map", "box", "--x", "0.04", "--y", "0.04", "--z", "0.04", "-o", str(tmp_path / "b2.h5"),
                 "--gripper", model]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no fingers found" in err and not (tmp_path / "b2.h5").exists()


def test_a_urdf_gets_a_drive_from_its_effort_limit_and_lifts(tmp_path):
    # the Franka hand's URDF as shipped (pybullet's): no actuator, <mimic> couples the fingers
    shutil.copytree(model_folder("franka_hand"), tmp_path / "hand")
    (tmp_path / "hand" / "franka_hand.gripper.json").unlink()  # the sidecar is the MJCF's
    g = get_gripper(str(tmp_path / "hand" / "hand.urdf"))
    franka = get_gripper("franka_hand")
    assert g.grip_force == 20.0  # the URDF's effort limit (the MJCF's 70 N is the maker's)
    assert g.housing_size == franka.housing_size and g.finger_size[2] == franka.finger_size[2]
    assert g.max_opening == pytest.approx(0.08, abs=1e-3)  # the joints' 0-0.04 m, as pad gap
    scene = build_scene(object_from_shape(__import__("graspsim").Box(0.04, 0.04, 0.04)), g)
    T = grasp_pose(depth=g.nominal_depth, gripper=g, grasp_point=[0, 0, 0], approach=[0, 0, -1], closing=[1, 0, 0])
    r = run_trials(scene, T[None], [0.04], LiftPlace(), threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS
    assert r.metrics["pad_force_neg"][0] == pytest.approx(20.0, rel=0.05)


def test_a_model_files_database_key_and_maps_follow_its_content_not_its_path(tmp_path):
    from graspsim import Box, MapDatabase
    from graspsim.grades.models import gripper_identity
    from graspsim.maps.map_config import MapConfig

    for d in ("a", "b/deeper", "c"):
        shutil.copytree(model_folder("rethink_gripper"), tmp_path / d)
    a, b, c = (get_gripper(str(tmp_path / d / "rethink_gripper.xml")) for d in ("a", "b/deeper", "c"))
    assert a.model != b.model and a.to_dict() != b.to_dict()  # each records its own file
    cfg = MapConfig(surface_step=0.012, rotation_step=np.radians(30))
    dba, dbb = (MapDatabase(tmp_path / "db", gripper=g, config=cfg) for g in (a, b))
    box = Box(0.04, 0.04, 0.04)
    assert dba.key(box) == dbb.key(box) and gripper_identity(a) == gripper_identity(b)
    built = dba.get(box)
    assert dbb.contains(box)  # the copy finds the map the first file's database built
    served = dbb.get(box, build=False)
    assert np.array_equal(served.grade, built.grade) and len(served) == len(built) > 0
    assert served.meta.gripper_spec == b  # and it records the copy's file: its trials simulate that
    mesh = tmp_path / "c" / "meshes" / "half_round_tip.stl"
    data = bytearray(mesh.read_bytes())
    data[40] ^= 1  # one bit of the binary STL's header: the mesh's content, not its size or geometry
    mesh.write_bytes(bytes(data))
    assert MapDatabase(tmp_path / "db", gripper=c, config=cfg).key(box) != dba.key(box)
    (tmp_path / "a" / "rethink_gripper.gripper.json").write_text(json.dumps({"grip_force": 15.0}))
    assert MapDatabase(tmp_path / "db", gripper=get_gripper(a.model), config=cfg).key(box) != dbb.key(box)
