"""The arm (graspsim.robots): IK round trips through the arm's own forward kinematics, the
workspace's edge, approaches through the table, the capability map, and grasps executed
by the arm's servos -- with what the reachability check refuses counted, never executed."""

import math

import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.errors import InvalidParameterError
from graspsim.grippers import get_gripper
from graspsim.primitives import Box
from graspsim.robots import (
    PANDA,
    ArmKinematics,
    ArmLiftPlace,
    CapabilityConfig,
    Reach,
    base_transform,
    build_arm_scene,
    build_robot_model,
    capability_map,
    check_reach,
    run_arm_trials,
)
from graspsim.robots.capability import ChainFK
from graspsim.robots.reach import pose_error
from graspsim.sim import TrialOutcome, object_from_shape

FRANKA = get_gripper("franka_hand")
FESTO = get_gripper("festo_hgpl_25_60_a")  # simulated from its spec: the harness's box model
TOP_DOWN = dict(grasp_point=[0, 0, 0], approach=[0, 0, -1], closing=[1, 0, 0])


@pytest.fixture(scope="module")
def robot():
    return build_robot_model(PANDA, FRANKA)


@pytest.fixture(scope="module")
def kin(robot):
    return ArmKinematics(robot, PANDA)


def _pose(x, z, tilt_deg):
    """A wrist pose at (x, 0, z) approaching along +x tilted up by ``tilt_deg``, jaws
    closing along y."""
    t = math.radians(tilt_deg)
    a = np.array([math.cos(t), 0.0, math.sin(t)])
    xw = np.array([0.0, 1.0, 0.0])
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = xw, np.cross(a, xw), a, [x, 0.0, z]
    return T


def test_ik_reaches_poses_the_arms_forward_kinematics_produced(kin):
    rng = np.random.default_rng(7)
    for _ in range(12):
        q = rng.uniform(kin.lower, kin.upper)
        T = kin.fk(q)
        for seed in (None, *kin.spread_seeds()):  # solved from elsewhere, not from q
            r = kin.ik(T, seed)
            if r.ok:
                break
        assert r.ok and kin.within_limits(r.q)
        lin, ang = pose_error(kin.fk(r.q), T)
        assert lin <= 1e-3 and ang <= math.radians(1.0)


def test_a_pose_outside_the_workspace_is_flagged(kin, robot, tmp_path):
    far = _pose(1.2, 0.3, 0.0)  # 1.7 m from the base: the Panda reaches ~0.86 m
    assert check_reach(kin, far).reach is Reach.NO_IK
    cmap = capability_map(robot, PANDA, base_transform(), CapabilityConfig(samples=40_000), cache_dir=tmp_path)
    ok, seed = cmap.lookup(far[None])
    assert not ok[0] and np.isnan(seed[0]).all()
    # the wrist poses of the map's own samples, placed by MuJoCo, are in reach and seed the IK
    inside = np.stack([kin.fk(q) for q in cmap.q[::500]])
    ok, seed = cmap.lookup(inside)
    assert ok.all() and np.isfinite(seed).all()


def test_an_approach_through_the_table_is_rejected(kin):
    # the same grasp is reachable on its own; approached from 0.3 m back along its
    # axis, tilted 20 deg up, the pre-grasp lies in the table
    T = _pose(0.1, 0.10, 20.0)
    assert check_reach(kin, T, approach=0.0).ok
    r = check_reach(kin, T, approach=0.3)
    assert r.reach is Reach.TABLE and r.stage in ("pre_grasp", "approach")
    assert check_reach(kin, _pose(0.1, 0.10, 0.0), approach=0.3).ok  # level: clear


def _side_pose(x, z, tilt_deg):
    """A wrist pose at (x, 0, z) approaching along +x tilted up by ``tilt_deg``, the jaws
    closing in the vertical plane (the closing axis upright, tilted back by the same)."""
    t = math.radians(tilt_deg)
    a, xw = np.array([math.cos(t), 0.0, math.sin(t)]), np.array([-math.sin(t), 0.0, math.cos(t)])
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = xw, np.cross(a, xw), a, [x, 0.0, z]
    return T


def test_the_reach_check_sees_the_festos_housing():
    """The Festo on the flange: its housing (180 mm along the closing axis) is in the
    arm's collision checks. Jaws upright, approached 10 deg up: the grasp 0.10 m up is
    clear, but its pre-grasp 0.1 m back sits 17 mm lower and puts the housing's lower
    end (90 mm below the axis) into the table, while the arm, the jaws and the fingers
    stay clear."""
    m = build_robot_model(PANDA, FESTO)
    kin = ArmKinematics(m, PANDA)
    # link5's convex hull reaches over the flange: its contacts with the housing (on the
    # wrist body itself) are excluded as with a model file's bodies, not seen as self-collisions
    pair = (m.body("arm/link5").id << 16) + m.body("wrist").id
    assert pair in set(m.exclude_signature.tolist())
    T = _side_pose(0.1, 0.10, 10.0)
    assert check_reach(kin, T, approach=0.0).ok
    r = check_reach(kin, T, approach=0.1)
    assert r.reach is Reach.TABLE and r.stage == "pre_grasp"
    assert r.contacts["arm_table"] == 0.0
    t = math.radians(10.0)
    housing = FESTO.collision_boxes().half_extents[FESTO.collision_boxes().names.index("housing")]
    lowest = 0.10 - 0.1 * math.sin(t) - housing[0] * math.cos(t)  # the housing's lower edge at the pre-grasp
    assert r.contacts["gripper_table"] == pytest.approx(-lowest, abs=1e-3)
    assert check_reach(kin, _side_pose(0.1, 0.125, 10.0), approach=0.1).ok  # higher: the housing clears


def test_the_chain_fk_is_mujocos_and_the_map_is_cached_by_content(kin, robot, tmp_path):
    fk = ChainFK(robot, PANDA)
    q = np.random.default_rng(3).uniform(kin.lower, kin.upper, (16, 7))
    T, _ = fk(q)
    B = base_transform()
    assert max(np.abs(B @ T[i] - kin.fk(q[i])).max() for i in range(16)) < 1e-9
    cfg = CapabilityConfig(samples=20_000)
    a = capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)
    assert len(list(tmp_path.iterdir())) == 1
    b = capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)  # read back
    assert a.key == b.key and np.array_equal(a.cells, b.cells) and np.allclose(a.q, b.q, atol=1e-6)
    c = capability_map(robot, PANDA, B, CapabilityConfig(samples=20_000, voxel=0.08), cache_dir=tmp_path)
    assert c.key != a.key and len(list(tmp_path.iterdir())) == 2


def test_a_cached_map_is_read_once_per_process_until_its_file_changes(robot, tmp_path):
    """A clutter run asks for the map once per episode: the second read shares the first's
    (read-only) arrays; a file rewritten since is read again."""
    import os

    B = base_transform()
    cfg = CapabilityConfig(samples=20_000)
    capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)  # built and written
    a = capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)
    b = capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)
    assert b.cells is a.cells and b.q is a.q and not a.cells.flags.writeable and not a.q.flags.writeable
    (path,) = tmp_path.iterdir()
    with np.load(path) as z:
        shape, flat, q = z["shape"], z["flat"], z["q"]
    keep = slice(0, len(flat) // 2)  # another content under the same name, an older time stamp
    np.savez_compressed(path, shape=shape, flat=flat[keep], q=q[keep])
    os.utime(path, ns=(1, 1))
    c = capability_map(robot, PANDA, B, cfg, cache_dir=tmp_path)
    assert c.cells is not a.cells and (c.cells >= 0).sum() < (a.cells >= 0).sum()


@pytest.fixture(scope="module")
def box_scene():
    return build_arm_scene(object_from_shape(Box(0.05, 0.05, 0.05)), FRANKA)


def test_the_arm_lifts_a_box_by_a_known_good_grasp(box_scene):
    T = grasp_pose(depth=FRANKA.nominal_depth, gripper=FRANKA, **TOP_DOWN)
    r = run_arm_trials(box_scene, T[None], [0.05], threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS
    assert r.metrics["lift_height"][0] == pytest.approx(0.12, abs=0.005)
    assert r.metrics["reach_lin"][0] < 0.002 and r.metrics["approach_push"][0] < 0.002
    assert r.metrics["reach"][0] == Reach.REACHABLE
    for k in ("pad_force_neg", "pad_force_pos"):
        assert r.metrics[k][0] == pytest.approx(70.0, rel=0.05)


def test_the_arm_lifts_a_box_with_the_festo_simulated_from_its_spec():
    """The spec-built Festo on the flange: the floating harness's box model (the same
    jaws, valve and pads), driven as there, lifts the box by the same known-good grasp."""
    scene = build_arm_scene(object_from_shape(Box(0.05, 0.05, 0.05)), FESTO)
    m = scene.model
    assert m.actuator(0).name == "grip" and m.body(int(m.geom("housing").bodyid[0])).name == "wrist"
    assert m.body(int(m.body("wrist").parentid[0])).name == "arm/link7"  # on the flange, no free joint of its own
    T = grasp_pose(depth=FESTO.nominal_depth, gripper=FESTO, **TOP_DOWN)
    r = run_arm_trials(scene, T[None], [0.05], threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.SUCCESS
    assert r.metrics["lift_height"][0] == pytest.approx(0.12, abs=0.005)
    assert r.metrics["reach_lin"][0] < 0.002 and r.metrics["approach_push"][0] < 0.002
    for k in ("pad_force_neg", "pad_force_pos"):
        assert r.metrics[k][0] == pytest.approx(FESTO.grip_force, rel=0.05)


def test_a_gripper_given_as_a_spec_json_goes_on_the_flange_as_specified(tmp_path):
    from dataclasses import replace

    f = tmp_path / "wide.json"
    f.write_text(replace(FESTO, name="wide", housing_size=(0.24, 0.05, 0.06), finger_size=(0.01, 0.02, 0.1)).to_json())
    g = get_gripper(str(f))
    m = build_robot_model(PANDA, g)
    boxes = g.collision_boxes()
    for name in ("housing", "finger_pos"):
        i = boxes.names.index(name)
        assert np.allclose(m.geom(name).size, boxes.half_extents[i]) and np.allclose(m.geom(name).pos, boxes.centers[i])
    kin = ArmKinematics(m, PANDA)  # the wrist frame is the flange: the same pose as the Festo's
    assert np.allclose(kin.fk(PANDA.home), ArmKinematics(build_robot_model(PANDA, FESTO), PANDA).fk(PANDA.home))


def test_an_unreachable_grasp_is_counted_a_failure_never_executed():
    far = build_arm_scene(object_from_shape(Box(0.05, 0.05, 0.05)), FRANKA, base=(-1.4, 0.0, 0.0))
    T = grasp_pose(depth=FRANKA.nominal_depth, gripper=FRANKA, **TOP_DOWN)
    r = run_arm_trials(far, T[None], [0.05], threads=1)
    assert TrialOutcome(int(r.outcome[0])) is TrialOutcome.UNREACHABLE
    assert np.isnan(r.metrics["lift_height"][0]) and r.simulated_seconds == 0.0  # not executed
    assert r.feasible == 1 and r.success_rate == 0.0  # in the denominator
    assert r.extra["plan"]["reach"] == {"no_ik": 1}


def test_bad_robot_settings_are_refused():
    with pytest.raises(InvalidParameterError, match="unknown robot"):
        from graspsim.robots import get_arm

        get_arm("ur5")
    with pytest.raises(InvalidParameterError, match="x, y"):
        base_transform((0.1, 0.2))
    with pytest.raises(InvalidParameterError, match="must be >= 0"):
        ArmLiftPlace(approach=-0.1)
    with pytest.raises(InvalidParameterError, match=r"^ArmLiftPlace\.step must be > 0, got 0"):
        ArmLiftPlace(step=0.0)
    with pytest.raises(InvalidParameterError, match=r"^CapabilityConfig\.extent must be > voxel \(0\.05 m\)"):
        CapabilityConfig(extent=0.01)
    with pytest.raises(InvalidParameterError, match=r"^CapabilityConfig\.samples must be an integer >= 1, got 0$"):
        CapabilityConfig(samples=0)


@pytest.mark.slow
def test_trial_robot_panda_runs_a_maps_top_grasps_through_the_arm(tmp_path, monkeypatch, capsys):
    """``graspsim trial --robot panda``: the floating gripper's start collisions, the arm's
    executions of the rest, results stored apart from the floating gripper's."""
    import json

    from graspsim.cli import main
    from graspsim.maps import read_sim_results

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))  # the capability map: not the user's cache
    f = tmp_path / "box.h5"
    assert main(["map", "box", "--x", "0.05", "--y", "0.05", "--z", "0.05", "-o", str(f), "--surface-step", "0.02",
                 "--rotation-step-deg", "45", "--gripper", "franka_hand", "--json"]) == 0
    capsys.readouterr()
    assert main(["trial", str(f), "--top", "6", "--threads", "2", "--no-write", "--json"]) == 0
    floating = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert main(["trial", str(f), "--top", "6", "--threads", "2", "--robot", "panda", "--json"]) == 0
    arm = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert arm["robot"] == "panda" and arm["trials"] == 6
    assert arm["start_collisions"] == floating["start_collisions"] and arm["feasible"] == floating["feasible"]
    assert arm["counts"]["success"] >= 1 and sum(arm["counts"].values()) == 6
    stored = read_sim_results(f, arm["written_to"])
    assert arm["written_to"].endswith("mujoco_arm_lift_place") and stored["info"]["scene"]["robot"]["name"] == "panda"
    # flags the arm does not take, and a base without an arm: one line, exit 2
    for extra, message in ((["--protocol", "tug"], "--protocol tug is not available with --robot panda"),
                           (["--robot-base", "0", "0", "0"], "--robot-base needs --robot panda")):
        robot = [] if "--robot-base" in extra else ["--robot", "panda"]
        assert main(["trial", str(f), "--top", "1", "--no-write", *robot, *extra]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
