"""The robust score under the stated execution error (issue 34's E10 gap with execution
error): scene planning scores a thin object's low-profile grasps against the fitted
table at the stated error, and the clutter benchmark, the CLI and the grasp environment
plan for the execution error they execute with."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import RobustConfig

FAST = MapConfig(surface_step=0.005, rotation_step=math.radians(22))


def _flat_cloud(rng: np.random.Generator, n: int = 3000, thick: float = 0.006) -> np.ndarray:
    """A ``thick`` x 30 x 50 mm box lying flat on the table z = 0: its top and sides, 0.5 mm noise."""
    dims = np.array([0.05, 0.03, thick])
    pts = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            if axis == 2 and sign < 0:
                continue  # the table hides the bottom
            k = max(20, int(n * np.prod(np.delete(dims, axis)) / 0.0033))
            p = (rng.random((k, 3)) - 0.5) * dims
            p[:, axis] = sign * 0.5 * dims[axis]
            pts.append(p)
    p = np.concatenate(pts) + [0.0, 0.0, 0.5 * thick]
    return p + rng.normal(0.0, 0.0005, p.shape)


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    return MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)


def _scene_plan(db, cloud, **robust):
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import SceneConfig

    base = SceneConfig(workers=1)
    cfg = replace(base, planner=replace(base.planner, robust=replace(base.planner.robust, **robust)))
    return plan_scene(cloud, db=db, rng=np.random.default_rng(0), config=cfg)


def _best(sp) -> float:
    return max((g.score for g in sp.grasps), default=0.0)


def test_scene_planning_scores_a_flat_box_against_the_table_under_the_stated_error(db):
    """The E10 diagnosis pinned: a thin box lying flat (9 mm: a scene's table band takes
    6 mm) gets only low-profile grasps,
    and their robust score counts the perturbations that drive the fingers into the fitted
    table (without the table term they would score far higher) at the stated error (a
    smaller stated error, a higher score)."""
    rng = np.random.default_rng(3)
    xy = np.stack(np.meshgrid(np.arange(-0.1, 0.1, 0.004), np.arange(-0.1, 0.1, 0.004)), -1).reshape(-1, 2)
    table = np.column_stack([xy, rng.normal(0.0, 0.0005, len(xy))])
    box = _flat_cloud(rng, thick=0.009)
    cloud = np.concatenate([table[np.any(np.abs(xy) > [0.027, 0.017], axis=1)], box])
    sp = _scene_plan(db, cloud)
    n, h = np.asarray(sp.table.normal), sp.table.height
    T = np.array([g.T_world_wrist for g in sp.grasps])
    low = db.gripper.lowest_along(np.einsum("nji,j->ni", T[:, :3, :3], n), T[:, :3, 3] @ n - h,
                                 np.array([g.opening for g in sp.grasps]))
    assert len(low) and np.all(low < sp.table.clearance)  # low-profile grasps only
    stated = _best(sp)
    assert 0.0 < stated < 0.7  # fragile: fingertips 0.5 mm above the table, 3 mm / 2 deg error
    assert _best(_scene_plan(db, cloud, terms=("cloud", "primitives", "pads", "force_closure"))) > stated
    assert _best(_scene_plan(db, cloud, position_sigma=0.001, rotation_sigma=math.radians(0.5))) > stated


def test_clutter_plans_for_the_execution_error_it_executes():
    from graspsim.sim.noise import ExecutionNoise
    from graspsim.tabletop.clutter import ClutterConfig

    arm = ExecutionNoise(0.005, math.radians(3.0))
    robust = ClutterConfig(execution=arm).planning.planner.robust
    assert (robust.position_sigma, robust.rotation_sigma) == (0.005, math.radians(3.0))
    assert ClutterConfig(execution=arm).to_dict()["robust_sigma"] == [0.005, math.radians(3.0)]
    default = RobustConfig()
    for cfg in (ClutterConfig(), ClutterConfig(execution=arm, plan_for_execution=False)):
        r = cfg.planning.planner.robust
        assert (r.position_sigma, r.rotation_sigma) == (default.position_sigma, default.rotation_sigma)
    with pytest.raises(InvalidParameterError, match="plan_for_execution"):
        ClutterConfig(plan_for_execution="yes")
    for bad in (0, -1, 1.5):  # the config's other checks still run
        with pytest.raises(InvalidParameterError, match="max_attempts"):
            ClutterConfig(max_attempts=bad)


def test_the_clutter_episode_plans_with_the_execution_error(monkeypatch):
    import graspsim.tabletop.clutter as clutter
    from graspsim.sim.noise import ExecutionNoise
    from graspsim.tabletop.table_scene import make_scene

    seen = []

    class Planned(Exception):
        pass

    def fake_plan_scene(points, *, config, **kw):
        seen.append(config)
        raise Planned

    monkeypatch.setattr(clutter, "plan_scene", fake_plan_scene)
    scene = make_scene(1, "packed", 0, object_set="primitives")
    ep = clutter.ClutterEpisode(scene, db=None, rng=np.random.default_rng(0),
                                config=clutter.ClutterConfig(execution=ExecutionNoise(0.006, math.radians(4.0))))
    try:
        with pytest.raises(Planned):
            ep.observe()
    finally:
        ep.close()
    assert seen[0].planner.robust.position_sigma == 0.006
    assert seen[0].planner.robust.rotation_sigma == math.radians(4.0)


def test_cli_noise_takes_the_sigmas_and_refuses_bad_ones():
    from argparse import Namespace

    from graspsim.cli.scene_cmd import _execution

    def ask(noise, pos=None, rot=None):
        return _execution(Namespace(noise=noise, noise_pos=pos, noise_rot_deg=rot))

    assert ask(False) is None
    e = ask(True)
    assert (e.position_sigma, e.rotation_sigma) == (RobustConfig().position_sigma, RobustConfig().rotation_sigma)
    e = ask(True, 0.005, 3.0)
    assert e.position_sigma == pytest.approx(0.005) and e.rotation_sigma == pytest.approx(math.radians(3.0))
    for bad in ((True, -0.001, None), (True, None, float("nan")), (True, 0.5, None), (False, 0.005, None)):
        with pytest.raises(InvalidParameterError, match="--noise"):
            ask(*bad)


def test_the_grasp_environment_plans_for_its_execution_error():
    from graspsim.envs.env_config import EnvConfig

    assert EnvConfig(position_noise=0.005, rotation_noise=0.05).robust_sigmas() == {
        "position_sigma": 0.005, "rotation_sigma": 0.05}
    assert EnvConfig(position_noise=0.0, rotation_noise=0.0).robust_sigmas() == {}



def test_the_grasp_environment_planner_gets_its_execution_error(tmp_path):
    import gymnasium as gym

    from graspsim.envs import GRASP_SELECT_ID

    env = gym.make(GRASP_SELECT_ID, db_root=str(tmp_path), map_config=FAST, n_candidates=4, cloud_size=64,
                   pool_size=120, position_noise=0.005, rotation_noise=0.05).unwrapped
    try:
        robust = env.planner_config.robust
        assert (robust.position_sigma, robust.rotation_sigma) == (0.005, 0.05)
    finally:
        env.close()
