"""Table-top scenes: seeded drawing, settling, save/load, rendering with object labels,
grasp execution among neighbours, removal."""

import json

import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.errors import GraspsimError, InvalidParameterError
from graspsim.geometry.camera import Camera, Intrinsics, backproject, look_at
from graspsim.grippers.spec import HGPL_25_60_A
from graspsim.primitives import Box
from graspsim.sim import TrialOutcome
from graspsim.tabletop.depth_noise import DepthNoise
from graspsim.tabletop.scene_objects import ObjectSpec, draw_object, narrowest_extent
from graspsim.tabletop.scene_sim import SceneSim
from graspsim.tabletop.table_scene import footprint_gaps, load_scene, make_scene, save_scene
from graspsim.transforms import make_transform

BOX = ObjectSpec("primitive", "box", Box(0.06, 0.06, 0.06).to_dict())


def _at(x, y):
    return make_transform(np.eye(3), [x, y, 0.03])


def _top_down(T_world_obj, closing=(1, 0, 0)):
    return T_world_obj @ grasp_pose([0, 0, 0], [0, 0, -1], closing)


@pytest.fixture(scope="module")
def gl():
    import mujoco

    m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='.1'/></worldbody></mujoco>")
    try:
        mujoco.Renderer(m, 8, 8).close()
    except Exception as err:
        pytest.skip(f"no headless OpenGL: {err}")


@pytest.mark.parametrize("kind", ["pile", "packed"])
def test_make_scene_is_deterministic_and_reloads(kind, tmp_path):
    a = make_scene(5, kind, seed=4)
    b = make_scene(5, kind, seed=4)
    c = make_scene(5, kind, seed=5)
    assert json.dumps(a.to_dict()) == json.dumps(b.to_dict())
    assert json.dumps(a.to_dict()) != json.dumps(c.to_dict())
    assert len(a.objects) == 5 and a.kind == kind
    for o in a.objects:  # settled on the table, inside its region
        assert o.pos[2] > 0 and np.all(np.abs(o.pos[:2]) < 0.3)
    save_scene(a, tmp_path / "s.json")
    back = load_scene(tmp_path / "s.json")
    assert json.dumps(back.to_dict()) == json.dumps(a.to_dict())
    s1, s2 = a.sim(), back.sim()
    assert np.array_equal(s1.data.qpos, s2.data.qpos)
    s1.settle(max_time=0.5)
    s2.settle(max_time=0.5)  # the same MuJoCo scene: it evolves identically, and stays put
    assert np.array_equal(s1.data.qpos, s2.data.qpos)
    assert max(np.linalg.norm(s1.pose(k)[:3, 3] - o.pos) for k, o in enumerate(a.objects)) < 0.005


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_packed_scenes_keep_a_centimetre_gap(seed):
    s = make_scene(6, "packed", seed=seed)
    assert footprint_gaps(s).min() >= 0.01
    for o in s.objects:  # upright: the object frame's z still points up
        assert o.T_world_obj[2, 2] > 0.95 or o.spec.name == "ball_with_tab"


def test_objects_fit_the_gripper():
    rng = np.random.default_rng(0)
    limit = HGPL_25_60_A.max_opening - 2 * HGPL_25_60_A.approach_clearance
    names = set()
    for _ in range(40):
        spec = draw_object(rng, "mixed")
        names.add(spec.source)
        assert narrowest_extent(spec.sim_object()) <= limit
    assert names == {"primitive", "analog", "mesh"}


def test_bad_scene_requests_rejected(tmp_path):
    with pytest.raises(InvalidParameterError):
        make_scene(0, "pile")
    with pytest.raises(InvalidParameterError, match="pile"):
        make_scene(3, "heap")
    with pytest.raises(InvalidParameterError):
        make_scene(3, "pile", object_set="tools")
    (tmp_path / "bad.json").write_text('{"format": "something else"}')
    with pytest.raises(GraspsimError):
        load_scene(tmp_path / "bad.json")
    with pytest.raises(GraspsimError):
        load_scene(tmp_path / "missing.json")


def test_top_down_grasp_lifts_a_lone_box_and_removes_it():
    sim = SceneSim([(BOX, _at(0, 0)), (BOX, _at(0, 0.2))])
    out = sim.execute(_top_down(_at(0, 0)), 0.07, target=0)
    assert out.outcome == TrialOutcome.SUCCESS and out.picked == 0 and out.lift_height > 0.1
    assert sim.objects_left() == [1]
    assert np.linalg.norm(sim.pose(1)[:3, 3] - [0, 0.2, 0.03]) < 0.002  # the other one stays put
    with pytest.raises(InvalidParameterError):
        sim.execute(_top_down(_at(0, 0)), 0.07, target=0)  # gone
    # a grasp where the box was now closes on nothing, also on an empty table
    assert sim.execute(_top_down(_at(0, 0)), 0.07).outcome == TrialOutcome.NO_CONTACT
    sim.remove(1)
    assert sim.objects_left() == [] and sim.execute(_top_down(_at(0, 0)), 0.07).outcome == TrialOutcome.NO_CONTACT
    with pytest.raises(InvalidParameterError):
        sim.remove(1)


def test_finger_hitting_a_neighbour_is_a_start_collision_with_it():
    sim = SceneSim([(BOX, _at(0, 0)), (BOX, _at(0.07, 0))])  # 1 cm apart along x
    before = sim.data.qpos.copy()
    out = sim.execute(_top_down(_at(0, 0), closing=(1, 0, 0)), 0.07, target=0)
    assert out.outcome == TrialOutcome.START_COLLISION
    assert out.cause == "start_collision_neighbour" and out.collided == (1,) and out.penetration > 0.001
    assert np.array_equal(sim.data.qpos, before)  # nothing simulated, nothing moved
    # closing across the gap instead clears the neighbour and lifts the box
    ok = sim.execute(_top_down(_at(0, 0), closing=(0, 1, 0)), 0.07, target=0)
    assert ok.outcome == TrialOutcome.SUCCESS and ok.picked == 0


def test_table_and_target_collisions_are_told_apart():
    sim = SceneSim([(BOX, _at(0, 0))])
    low = _at(0, 0) @ grasp_pose([0, 0, -0.02], [0, 0, -1], [0, 1, 0], depth=0.04)
    out = sim.execute(low, 0.07, target=0)
    assert out.cause == "start_collision_table" and out.collided == ("table",)
    narrow = sim.execute(_top_down(_at(0, 0)), 0.04, target=0)  # jaws inside the box
    assert narrow.cause == "start_collision_target" and narrow.collided == (0,)
    assert sim.execute(_top_down(_at(0, 0)), 0.07, commit=False).picked == 0
    assert sim.objects_left() == [0]  # commit=False changes nothing


def test_a_start_collision_with_target_and_neighbour_is_labelled_both():
    sim = SceneSim([(BOX, _at(0, 0)), (BOX, _at(0.07, 0))])  # 1 cm apart along x
    # between the boxes, jaws 4 cm open along x: one finger in each box
    both = sim.execute(_top_down(_at(0.035, 0)), 0.04, target=0)
    assert both.cause == "start_collision_both" and set(both.collided) >= {0, 1}
    assert sim.execute(_top_down(_at(0.035, 0)), 0.04, target=1).cause == "start_collision_both"
    assert sim.execute(_top_down(_at(0, 0)), 0.04, target=0).cause == "start_collision_target"
    # where: one finger in each box (the diagnosis of a start collision; nothing simulated)
    deep = {k: v for k, v in sim.overlaps(_top_down(_at(0.035, 0)), 0.04).items() if v > 0.001}
    parts = {what: name for name, what in deep}
    assert set(parts) == {0, 1} and parts[0] != parts[1] and all("finger" in n for n in parts.values())


def test_collision_kind_tells_every_combination_apart():
    from graspsim.tabletop.scene_sim import collision_kind

    assert collision_kind(("table",), 0) == "table"
    assert collision_kind((0,), 0) == collision_kind((0, "table"), 0) == "target"
    assert collision_kind((0, 2), 0) == collision_kind((2, 0, "table"), 0) == "both"
    assert collision_kind((2,), 0) == collision_kind((2, 3, "table"), 0) == "neighbour"
    assert collision_kind((2,), None) == "object"


def test_execution_is_deterministic():
    outs = []
    for _ in range(2):
        sim = make_scene(4, "pile", seed=2).sim()
        k = 0
        T = sim.pose(k) @ grasp_pose([0, 0, 0], [0, 0, -1], [1, 0, 0])
        outs.append((sim.execute(T, 0.1, target=k).to_dict(), sim.data.qpos.copy()))
    assert outs[0][0] == outs[1][0] and np.array_equal(outs[0][1], outs[1][1])


def test_render_labels_match_the_objects(gl):
    scene = make_scene(5, "packed", seed=3)
    sim = scene.sim()
    cam = Camera(Intrinsics(320, 240, 170.0, 170.0, 159.5, 119.5), look_at([0.0, -0.35, 0.55], [0, 0, 0]))
    f = sim.render(cam)
    assert set(np.unique(f.labels)) == {-1, 0, 1, 2, 3, 4}
    v = backproject(f)
    w = v.world()
    for k in range(5):  # every labelled point lies near its own object, and above the table
        pts = w[v.labels == k]
        c = sim.pose(k)[:3, 3]
        assert len(pts) > 50 and np.all(pts[:, 2] > -1e-4)
        assert np.linalg.norm(pts.mean(0)[:2] - c[:2]) < 0.05
    table = v.labels == -1
    assert np.abs(w[table, 2]).max() < 1e-3
    sim.remove(2)
    g = sim.render(cam, noise=DepthNoise(), rng=np.random.default_rng(0))
    assert 2 not in set(np.unique(g.labels)) and set(np.unique(g.labels)) >= {0, 1, 3, 4}
    sim.close()


@pytest.mark.parametrize("robot", [False, True])
def test_a_model_file_grippers_markers_stay_out_of_the_depth_image(gl, robot):
    """The camera sees the table and the objects only: the Robotiq 2F-85's model carries a
    grip-site cylinder metres long, which stood over the table as a rod of points (planned
    as an object, grasped at nothing); with the arm too."""
    from graspsim.grippers import get_gripper
    from graspsim.robots import PANDA

    kw = {"robot": PANDA} if robot else {}
    sim = SceneSim([(BOX, _at(0.1, 0.1))], gripper=get_gripper("robotiq_2f85"), **kw)
    cam = Camera(Intrinsics(320, 240, 170.0, 170.0, 159.5, 119.5), look_at([0.0, -0.35, 0.55], [0, 0, 0]))
    v = backproject(sim.render(cam))
    w = v.world()
    ok = np.all(np.isfinite(w), axis=1)
    assert np.abs(w[ok & (v.labels == -1), 2]).max() < 1e-3  # nothing but the table unlabelled
    assert (v.labels == 0).sum() > 50
    sim.close()


def test_execution_noise_is_seeded_and_width_sets_the_opening():
    from graspsim.sim import ExecutionNoise

    T = _top_down(_at(0, 0))
    runs = []
    for seed in (7, 7, 8):
        sim = SceneSim([(BOX, _at(0, 0))])
        out = sim.execute(T, width=0.06, target=0, noise=ExecutionNoise(), rng=np.random.default_rng(seed))
        runs.append(out)
    assert runs[0].to_dict() == runs[1].to_dict() and runs[0].extra["T_world_wrist"] != runs[2].extra["T_world_wrist"]
    assert runs[0].extra["opening"] == pytest.approx(0.06 + 2 * HGPL_25_60_A.approach_clearance)
    assert not np.allclose(runs[0].extra["T_world_wrist"], T)
    assert runs[0].outcome == TrialOutcome.SUCCESS  # this draw (seed 7) still picks the box
    with pytest.raises(InvalidParameterError):
        SceneSim([(BOX, _at(0, 0))]).execute(T, 0.07, width=0.06)


def test_the_bin_holds_a_rolling_ball_until_opened():
    from graspsim.primitives import Sphere

    ball = ObjectSpec("primitive", "sphere", Sphere(0.03).to_dict())
    xs = []
    for walls in (0.1, None):
        sim = SceneSim([(ball, make_transform(np.eye(3), [0, 0, 0.03]))], bin=walls)
        sim.data.qvel[sim.dadr[0]] = 1.0  # rolling along +x at 1 m/s
        sim.settle(max_time=1.0)
        xs.append(sim.pose(0)[0, 3])
        assert sim.outside(0.12) == ([] if walls else [0])
    assert xs[0] < 0.1 and xs[1] > 0.15


@pytest.mark.parametrize("seed", [0, 1])
def test_ten_object_piles_settle_on_the_table(seed):
    s = make_scene(10, "pile", seed=seed)
    pos = np.array([o.pos for o in s.objects])
    assert len(pos) == 10 and np.abs(pos[:, :2]).max() <= 0.35 and pos[:, 2].min() > 0


def test_a_grasp_can_be_pictured_without_touching_the_scene(gl):
    sim = SceneSim([(BOX, _at(0, 0)), (BOX, _at(0, 0.15))])
    cam = Camera(Intrinsics(160, 120, 90.0, 90.0, 79.5, 59.5), look_at([0.0, -0.45, 0.5], [0, 0, 0.05]))
    before = sim.data.qpos.copy()
    plain = sim.render(cam)
    shown = sim.render(cam, gripper_at=(_top_down(_at(0, 0)), 0.07), rgb=True)
    assert np.array_equal(sim.data.qpos, before)
    grip = np.isin(shown.segmentation, sim.gripper_geoms)
    assert grip.sum() > 50 and not np.isin(plain.segmentation, sim.gripper_geoms).any()
    assert np.all(shown.labels[grip] == -1) and shown.rgb.shape == (120, 160, 3)
    assert np.array_equal(sim.render(cam).depth, plain.depth)  # hidden again


def test_picking_another_object_than_the_target_says_so():
    sim = SceneSim([(BOX, _at(0, 0)), (BOX, _at(0, 0.2))])
    out = sim.execute(_top_down(_at(0, 0)), 0.07, target=1)
    assert out.outcome == TrialOutcome.SUCCESS and out.picked == 0 and out.cause == "success_other_object"


def test_every_object_of_a_packed_scene_can_be_lifted_from_above():
    """A physically sound scene: each object, at its settled pose, comes up with a plain
    top-down grasp across a narrow horizontal extent: the first closing direction (narrowest
    first) whose fingers clear the neighbours (1 cm gaps are narrower than a finger and its
    clearance, so some directions hit them) lifts it."""
    scene = make_scene(5, "packed", seed=0)
    sim = scene.sim()
    g = HGPL_25_60_A
    for k in range(5):
        T = sim.pose(k)
        v = np.asarray(sim.sim_objects[k].surface.vertices) @ T[:3, :3].T + T[:3, 3]
        dirs = [np.array([np.cos(a), np.sin(a), 0.0]) for a in np.linspace(0, np.pi, 12, endpoint=False)]
        top = v[:, 2].max()
        grasp_point = np.array([*v[:, :2].mean(0), top - min(0.03, top - 0.005)])
        outs = []
        for x in sorted(dirs, key=lambda d: np.ptp(v[:, :2] @ d[:2])):
            R = np.stack([x, np.cross([0, 0, -1.0], x), [0, 0, -1.0]], 1)
            Tw = make_transform(R, grasp_point - R @ g.nominal_tcp)
            outs.append(sim.execute(Tw, width=float(np.ptp(v[:, :2] @ x[:2])), target=k, commit=False))
            if outs[-1].outcome != TrialOutcome.START_COLLISION:
                break
        assert outs[-1].outcome == TrialOutcome.SUCCESS and outs[-1].picked == k, (k, sim.specs[k].name, outs[-1])
        assert all(o.cause == "start_collision_neighbour" for o in outs[:-1])


def test_object_view_sees_the_object_where_it_stands(gl):
    from graspsim.geometry.camera import rig
    from graspsim.tabletop.table_scene import object_view

    cam = rig(1, Intrinsics(320, 240, 170.0, 170.0, 159.5, 119.5), distance=0.5)[0]
    pts, T = object_view(BOX, cam)
    local = (pts - T[:3, 3]) @ T[:3, :3]
    assert len(pts) > 500 and np.abs(local).max() < 0.03 + 1e-3  # on the 6 cm box
    assert np.mean(np.isclose(np.abs(local).max(1), 0.03, atol=1e-3)) > 0.99  # on its faces
    noisy, _ = object_view(BOX, cam, noise=DepthNoise(), rng=np.random.default_rng(0))
    assert 0.5 * len(pts) < len(noisy) <= len(pts)
