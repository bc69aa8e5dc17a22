"""The clearance pre-check of the robust-scoring budget (``PlannerConfig.clear_first``,
:func:`graspsim.planning.observed.first_clear`): the budget goes to the best-graded grasps
whose gripper holds no observed point -- a neighbour's -- and only grasps the robust score
would give 0 are passed over."""

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.grippers.spec import HGPL_25_60_A as G
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.maps.robust import RobustConfig, score_map
from graspsim.planning.observed import clear_of_cloud, first_clear
from graspsim.planning.planner import PlannerConfig, plan_stream
from graspsim.primitives import Cylinder, synthetic_cloud
from graspsim.transforms import make_transform

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))
ROBUST = RobustConfig(samples=8)


@pytest.fixture(scope="module")
def cylinder_map():
    from graspsim.maps.generate import generate_fs_map

    return generate_fs_map(Cylinder(0.025, 0.1), G, config=FAST)


def _wall(x: float, rng, n: int = 1500) -> np.ndarray:
    """A neighbour: a slab of points at x [m] (object frame), a board standing beside the object."""
    return np.column_stack([x + rng.uniform(0, 0.004, n), rng.uniform(-0.08, 0.08, n), rng.uniform(-0.08, 0.08, n)])


def test_a_grasp_through_a_neighbour_is_cut_and_a_free_one_kept(cylinder_map):
    m = cylinder_map
    rng = np.random.default_rng(0)
    wall = _wall(0.04, rng)  # 15 mm off the cylinder's side: a finger approaching there goes through it
    order = np.argsort(-m.grade, kind="stable")
    n = 40
    rows, checked = first_clear(m, order, n, wall, ROBUST, G)
    head = order[:1000]  # the best-graded rows, where the first n free ones lie
    free, _ = clear_of_cloud(m, head, wall, replace(ROBUST, openings=ROBUST.openings + ROBUST.unseen_openings), G)
    assert len(rows) == n and (~free).any() and free.sum() >= n  # some grasps go through the wall, others not
    # the first n free rows in the grade order, found without checking the whole map
    assert np.array_equal(rows, head[free][:n])
    assert checked <= len(head) and np.array_equal(order[:checked][free[:checked]], rows)  # none clear left over
    passed = np.setdiff1d(order[:checked], rows)
    assert len(passed) > 0  # the wall cut some of the best-graded grasps
    # what was passed over is exactly what the robust score gives 0 (a pose holding a point at every opening)
    scored = score_map(m, wall, ROBUST, rows=order[:checked], gripper=G)
    assert np.all(scored.robust[passed] == 0)
    assert np.any(scored.robust[rows] > 0)
    # no neighbour near: nothing is passed over
    far = _wall(0.5, rng)
    rows_far, checked_far = first_clear(m, order, n, far, ROBUST, G)
    assert np.array_equal(rows_far, order[:n]) and checked_far == n
    assert first_clear(m, order, 0, wall, ROBUST, G)[0].size == 0


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Cylinder(0.025, 0.1)])
    return d


T = make_transform(np.eye(3), [0.4, -0.1, 0.25])
BASE = PlannerConfig(robust=replace(ROBUST, top=30), features=None, clear_observed=False)


def _run(db, cloud, obstacles, first: bool):
    out = list(plan_stream(cloud.points, db=db, rng=np.random.default_rng(2), obstacles=obstacles,
                           config=replace(BASE, clear_first=first), scored_only=True))
    return out[-1]


def test_the_budget_goes_to_grasps_clear_of_a_neighbour(db):
    """A cylinder with a board standing against one side: the best-graded grasps close
    through the board. With ``clear_first`` the same scoring budget finds more grasps that
    can score, none of the grasps offered holds a board point, and each passed-over grasp
    is counted."""
    rng = np.random.default_rng(1)
    cloud = synthetic_cloud(Cylinder(0.025, 0.1), rng, resolution=0.004, noise=0.0003, T_world_obj=T)
    board = _wall(0.03, rng, 3000) + T[:3, 3]

    def run(first: bool):
        return _run(db, cloud, board, first)

    before, after = run(False), run(True)
    good = [int(np.sum(r.map.robust > 0)) for r in (before, after)]
    assert good[1] > good[0]
    rec = after.map.meta.extra["clear_first"]
    assert rec["passed_over"] > 0 and rec["checked"] >= rec["passed_over"]
    assert "clear_first" not in before.map.meta.extra
    m = after.map
    board_obj = (board - after.T_cloud_obj[:3, 3]) @ after.T_cloud_obj[:3, :3]
    scored = np.flatnonzero(np.isfinite(m.robust))
    wide = replace(ROBUST, openings=ROBUST.openings + ROBUST.unseen_openings)
    assert np.all(clear_of_cloud(m, scored, board_obj, wide, G)[0])


def test_a_part_with_no_clear_grasp_is_checked_only_down_to_the_span(db):
    """Boards on every side and above: no grasp clears. The check stops CLEAR_FIRST_SPAN x
    the budget down the part's grade order (not at the end of its maps), and nothing is scored."""
    from graspsim.planning.planner import CLEAR_FIRST_SPAN

    rng = np.random.default_rng(4)
    cloud = synthetic_cloud(Cylinder(0.025, 0.1), rng, resolution=0.004, noise=0.0003, T_world_obj=T)
    cage = [_wall(0.03, rng, 3000), -_wall(0.03, rng, 3000)]
    cage += [b[:, [1, 0, 2]] for b in cage] + [b[:, [1, 2, 0]] for b in cage]  # the other sides, top and bottom
    res = _run(db, cloud, np.concatenate(cage) + T[:3, 3], True)
    rec = res.map.meta.extra["clear_first"]
    assert rec["span_reached"] == 1 and rec["checked"] == CLEAR_FIRST_SPAN * BASE.robust.top
    assert rec["passed_over"] == rec["checked"] and not np.isfinite(res.map.robust).any()
