"""Clutter removal by the arm (``graspsim scene --robot panda``): a small scene cleared by
the Panda with its causes recorded, a grasp whose approach passes through a neighbour
refused (approach_collision) and never executed, an episode whose grasps the arm reaches
none of stopped ``unreachable``, and the environment taking the arm with any gripper.

A scripted planner (the clutter benchmark's planner interface) proposes fixed grasps on
boxes whose poses the test sets, so nothing here depends on map generation."""

import math

import numpy as np
import pytest
from hand_made import grasp_pose

from graspsim.cli import main
from graspsim.grippers import get_gripper
from graspsim.primitives import Box
from graspsim.robots import PANDA, CapabilityConfig
from graspsim.sim.outcomes import TrialOutcome
from graspsim.tabletop.clutter import ClutterConfig, ClutterRobot, run_clutter
from graspsim.tabletop.planners import Proposals
from graspsim.tabletop.scene_objects import ObjectSpec
from graspsim.tabletop.table_scene import PlacedObject, TableScene

FRANKA = get_gripper("franka_hand")
LOW = ObjectSpec("primitive", "box", Box(0.05, 0.05, 0.05).to_dict())
TALL = ObjectSpec("primitive", "box", Box(0.04, 0.04, 0.2).to_dict())


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    """The Panda at its default base; a smaller capability map than the default (200 000
    samples), cached in the test's folder: no test reads or writes the user's cache."""
    return ClutterRobot(capability=CapabilityConfig(samples=200_000), cache_dir=tmp_path_factory.mktemp("reach"))


def _scene(*objects) -> TableScene:
    """Boxes standing upright: (spec, x, y) each."""
    placed = tuple(PlacedObject(spec, (x, y, 0.025 if spec is LOW else 0.1), (1, 0, 0, 0)) for spec, x, y in objects)
    return TableScene(0, "packed", "primitives", placed)


def _grasp(x, y, z, approach=(0.0, 0.0, -1.0), closing=(0.0, 1.0, 0.0)) -> np.ndarray:
    a = np.asarray(approach, float) / np.linalg.norm(approach)
    c = np.asarray(closing, float)
    c = c - a * (a @ c)
    T = grasp_pose(depth=FRANKA.nominal_depth, gripper=FRANKA, grasp_point=[0, 0, 0], approach=a,
                   closing=c / np.linalg.norm(c))
    T[:3, 3] += [x, y, z]
    return T


#: top-down on the low box at the origin; tilted 30 deg towards +x (from above the arm's side)
TOP = _grasp(0.0, 0.0, 0.025)
TILTED = _grasp(0.0, 0.0, 0.025, approach=(0.5, 0.0, -math.sqrt(0.75)))


def _scripted(grasps):
    """A planner proposing ``grasps`` ((T, score) each, best first) whose object is still
    seen: points of the cloud above the table within 2 cm of the grasp point's x, y."""
    def plan(obs):
        up = obs.cloud[obs.cloud[:, 2] > 0.01]
        keep = [(T, s) for T, s in grasps if len(up) and np.min(np.linalg.norm(
            up[:, :2] - FRANKA.grasp_point_from_wrist(T[:3, 3], T[:3, 2], FRANKA.nominal_depth)[:2], axis=1)) < 0.02]
        return Proposals(np.array([T for T, _ in keep]).reshape(-1, 4, 4), np.full(len(keep), 0.07),
                         np.array([s for _, s in keep]))

    return plan


def _run(scene, grasps, robot, **kw):
    cfg = ClutterConfig(planner=_scripted(grasps), planner_name="scripted", robot=robot, depth_noise=None, **kw)
    return run_clutter(scene, db=_Db(), rng=np.random.default_rng(0), config=cfg)


class _Db:
    gripper = FRANKA


def test_the_arm_clears_a_two_box_scene_with_its_record(robot):
    scene = _scene((LOW, 0.0, 0.0), (LOW, 0.05, 0.15))
    r = _run(scene, [(TOP, 0.9), (_grasp(0.05, 0.15, 0.025), 0.8)], robot)
    assert r.stop == "cleared" and r.removed == 2 and len(r.attempts) == 2 and r.successes == 2
    assert r.robot["robot"]["name"] == "panda" and r.robot["base"] == [-0.5, 0.0, 0.0]
    for a in r.attempts:
        assert a.cause == "success" and a.outcome["reach"] == "reachable"
        assert a.outcome["reach_lin"] < 0.005 and a.outcome["approach_push"] < 0.005
        assert a.outcome["lift_height"] > 0.05
        assert a.reach["first_cut"] >= 1 and a.reach["checked"] >= 1 and a.reach["refused"] == []
    d = r.to_dict()
    assert d["robot"]["exact"] == robot.exact and d["steps"][0]["reach"]["chosen"] == 0


def test_the_camera_sees_the_arms_scene_as_the_floating_grippers():
    """Paired runs start from the same depth frames: the arm is hidden and its scene
    renders with the floating gripper's depth range."""
    from graspsim.geometry.camera import rig

    scene = _scene((LOW, 0.0, 0.0), (TALL, 0.05, 0.15), (LOW, -0.1, 0.05))
    cam = rig(1)[0]
    floating, arm = scene.sim(gripper=FRANKA), scene.sim(gripper=FRANKA, robot=PANDA)
    a, b = floating.render(cam), arm.render(cam)
    floating.close()
    arm.close()
    assert np.array_equal(a.depth, b.depth) and np.array_equal(a.labels, b.labels)


def test_a_grasp_whose_approach_passes_through_a_neighbour_is_refused_never_executed(robot):
    # the tall box stands where the tilted grasp's gripper is at its pre-grasp, clear of it at the grasp
    crowded = _scene((LOW, 0.0, 0.0), (TALL, -0.12, 0.08))
    sim = crowded.sim(gripper=FRANKA, robot=PANDA)
    plan = sim.plan_arm(TILTED, 0.07)
    assert plan.outcome is TrialOutcome.APPROACH_COLLISION and plan.stage == "pre_grasp"
    assert plan.check.contacts["gripper_scene"] > 0.005
    free = _scene((LOW, 0.0, 0.0), (TALL, 0.0, 0.3)).sim(gripper=FRANKA, robot=PANDA)
    assert free.plan_arm(TILTED, 0.07).outcome is None  # the same grasp without the neighbour there
    a = free.qadr[1]
    free.data.qpos[a:a + 2] = (-0.12, 0.08)  # the neighbour moved there (as a grasp may push it): checked where it lies
    assert free.plan_arm(TILTED, 0.07).outcome is TrialOutcome.APPROACH_COLLISION
    # in an episode: the refused grasp is recorded and the next best executed instead
    r = _run(crowded, [(TILTED, 0.9), (TOP, 0.5)], robot, max_attempts=1)
    (a,) = r.attempts
    assert a.reach["refused"] == [{"rank": 0, "cause": "approach_collision", "stage": "pre_grasp",
                                   "reach": "scene"}]
    assert a.reach["chosen"] == 1 and np.allclose(a.outcome["T_world_wrist"], TOP)
    # offered nothing else, the arm executes nothing: the episode stops 'unreachable'
    r = _run(crowded, [(TILTED, 0.9)], robot)
    assert r.attempts == () and r.stop == "unreachable" and r.left[0] == "unreachable"


def test_robot_base_without_an_arm_is_one_line(capsys, tmp_path):
    code = main(["scene", "--robot-base", "0", "0", "0", "--objects", "1", "--db", str(tmp_path / "db")])
    err = capsys.readouterr().err
    assert code == 2 and "--robot-base needs --robot panda" in err and len(err.strip().splitlines()) == 1


def test_the_clutter_env_takes_the_arm_with_any_gripper():
    from graspsim.envs.clutter_config import ClutterEnvConfig
    from graspsim.errors import InvalidParameterError

    assert ClutterEnvConfig(robot="panda").to_dict()["gripper"] == "festo_hgpl_25_60_a"  # spec-built, on the flange
    with pytest.raises(InvalidParameterError, match="no_such_gripper"):
        ClutterEnvConfig(robot="panda", gripper="no_such_gripper")
    with pytest.raises(InvalidParameterError, match="robot 'ur5' unknown"):
        ClutterEnvConfig(robot="ur5", gripper="franka_hand")
    c = ClutterEnvConfig(robot="panda", gripper="franka_hand", robot_base=(-0.45, 0.1, 0.2))
    assert c.to_dict()["robot"] == "panda" and c.to_dict()["robot_base"] == [-0.45, 0.1, 0.2]


@pytest.mark.slow
def test_the_clutter_env_steps_with_the_arm(tmp_path, monkeypatch):
    import gymnasium as gym

    import graspsim  # noqa: F401  (registers the environments)
    from graspsim.envs import CLUTTER_CLEAR_ID
    from graspsim.maps.map_config import MapConfig

    monkeypatch.setenv("GRASPSIM_CACHE_DIR", str(tmp_path / "cache"))  # the capability map: not the user's cache
    fast = MapConfig(surface_step=0.01, rotation_step=math.radians(22))
    env = gym.make(CLUTTER_CLEAR_ID, n_objects=2, kind="packed", object_set="primitives", db_root=str(tmp_path / "db"),
                   map_config=fast, n_candidates=6, cloud_size=256, gripper="franka_hand", robot="panda").unwrapped
    env.reset(seed=5)
    assert env.episode.sim.robot is PANDA
    look = env.episode.last  # the arm's choice: the best-ranked candidate its check found a plan for
    act = next(i for i, g in enumerate(look.candidates[:6]) if g is look.best)
    obs, r, term, trunc, info = env.step(act)
    a = env.episode.attempts[0]
    assert r == float(info["success"]) and a.reach is not None and a.reach["checked"] >= 1
    assert info["outcome"] == a.cause and (a.cause == "success") == info["success"]
    env.close()
