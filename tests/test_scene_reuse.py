"""Plan reuse between frames of a scene: an unchanged segment keeps its plan, a moved
one (and its neighbours, which now meet new points) is planned again, an executed
grasp is not offered twice."""

import math
from dataclasses import replace

import numpy as np
import pytest

from graspsim.errors import InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.map_config import MapConfig
from graspsim.planning.scene import plan_scene
from graspsim.planning.scene_config import SceneConfig
from graspsim.planning.scene_reuse import drop_grasp, near_pose, nothing_new, same_points
from graspsim.primitives import Box, Cylinder, Sphere
from graspsim.primitives.clouds import table_scene_cloud

FAST = MapConfig(surface_step=0.008, rotation_step=math.radians(22))
SHAPES = [Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.12), Sphere(0.035)]
XY = np.array([[-0.11, 0.0], [0.0, 0.0], [0.11, 0.0]])


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = MapDatabase(tmp_path_factory.mktemp("db"), config=FAST)
    d.build([Box(0.06, 0.06, 0.06), Cylinder(0.02, 0.2), Sphere(0.035)])
    return d


def _frame(keep, xy, seed):
    """The scene's cloud with the objects ``keep`` at ``xy``, fresh sensor noise."""
    pts, truth, _ = table_scene_cloud([SHAPES[k] for k in keep], xy[list(keep)], np.random.default_rng(seed),
                                      noise=0.0007)
    return pts, truth


def _segment_of(sp, truth, k):
    lab = sp.perception.labels[(truth == k) & (sp.perception.labels >= 0)]
    return int(np.bincount(lab).argmax())


def test_unchanged_segments_keep_their_plan_moved_ones_are_planned_again(db):
    cfg = SceneConfig()
    pts, truth = _frame((0, 1, 2), XY, 1)
    sp1 = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=cfg)
    assert [p.status for p in sp1.segments] == ["planned"] * 3 and sp1.best is not None
    # the same scene, new noise: every segment reused, the same grasps
    pts2, _ = _frame((0, 1, 2), XY, 2)
    sp2 = plan_scene(pts2, db=db, rng=np.random.default_rng(1), config=cfg, previous=sp1)
    assert [p.status for p in sp2.segments] == ["reused"] * 3
    assert [g.T_world_wrist.tolist() for g in sp2.grasps] == [g.T_world_wrist.tolist() for g in sp1.grasps]
    assert sp2.timing["plan"] < 0.5 * sp1.timing["plan"] + 0.05
    # the grasp executed (and failed) is not offered again, nor its near twins
    T = sp1.best.T_world_wrist
    twins = [g for g in sp1.grasps if near_pose(T, g.T_world_wrist)]
    prev = replace(sp1, memory=drop_grasp(sp1.memory, T))
    sp3 = plan_scene(pts2, db=db, rng=np.random.default_rng(1), config=cfg, previous=prev)
    assert len(sp3.grasps) == len(sp1.grasps) - len(twins) and len(twins) >= 1
    assert not any(near_pose(T, g.T_world_wrist) for g in sp3.grasps)
    # the sphere picked: box and cylinder unchanged (an obstacle gone frees space only)
    pts4, truth4 = _frame((0, 1), XY, 3)
    sp4 = plan_scene(pts4, db=db, rng=np.random.default_rng(2), config=cfg, previous=sp1)
    assert [p.status for p in sp4.segments] == ["reused"] * 2
    # the cylinder pushed 2 cm towards the box: both meet new points and are planned again
    moved = XY.copy()
    moved[1, 0] -= 0.02
    pts5, truth5 = _frame((0, 1), moved, 4)
    sp5 = plan_scene(pts5, db=db, rng=np.random.default_rng(3), config=cfg, previous=sp4)
    assert sp5.segments[_segment_of(sp5, truth5, 1)].status == "planned"
    assert sp5.segments[_segment_of(sp5, truth5, 0)].status == "planned"


def test_lazy_planning_plans_the_highest_objects_until_a_grasp_is_good_enough(db):
    """``SceneConfig.good_enough``: segments planned highest first, two at a time, until a
    grasp reaches the score; the rest "deferred" (no grasps), planned by a later frame
    once the planned ones are gone. The planned segments' grasps are the full plan's.
    Mutation caught: the rest planned anyway (no "deferred")."""
    pts, truth = _frame((0, 1, 2), XY, 1)
    full = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=SceneConfig())
    lazy = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=SceneConfig(good_enough=0.5))
    box, cyl, ball = (_segment_of(lazy, truth, k) for k in range(3))  # 6, 12 and 7 cm high
    assert full.best.score >= 0.5
    assert [lazy.segments[k].status for k in (cyl, ball, box)] == ["planned", "planned", "deferred"]
    assert lazy.segments[box].primitives and not any(g.segment == box for g in lazy.grasps)
    same = [g for g in full.grasps if g.segment != box]
    assert [g.T_world_wrist.tolist() for g in lazy.grasps] == [g.T_world_wrist.tolist() for g in same]
    # planned in this process: the same (on workers the box's plan may start ahead, and is given up)
    here = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=SceneConfig(good_enough=0.5, workers=1))
    assert [(p.status, p.primitives, p.scored) for p in here.segments] == [
        (p.status, p.primitives, p.scored) for p in lazy.segments]
    assert [(g.T_world_wrist.tobytes(), g.score) for g in here.grasps] == [
        (g.T_world_wrist.tobytes(), g.score) for g in lazy.grasps]
    # the cylinder and the ball picked: the box is planned now
    pts2, truth2 = _frame((0,), XY, 2)
    sp2 = plan_scene(pts2, db=db, rng=np.random.default_rng(1), config=SceneConfig(good_enough=0.5), previous=lazy)
    assert [p.status for p in sp2.segments] == ["planned"] and sp2.best is not None
    for bad in (0.0, 1.5, True):
        with pytest.raises(InvalidParameterError, match="good_enough"):
            SceneConfig(good_enough=bad)


def test_lazy_planning_aims_a_segment_at_good_enough(db):
    """In a lazily planned scene a segment's planning goes on past ``enough`` grasps
    scoring > 0 until one reaches ``good_enough`` or its scoring budget is spent. With an
    aim no grasp of this scene reaches, every segment spends its whole budget, where the
    same budget without an aim stops at the first batch holding a grasp > 0.
    Mutation caught: the aim ignored (planning stops at ``enough``)."""
    pts, _ = _frame((0, 1, 2), XY, 1)
    budget = dict(enough=1, per_segment=60)
    full = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=SceneConfig(**budget))
    aimed = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=SceneConfig(**budget, good_enough=1.0))
    assert max(g.score for g in aimed.grasps) < 1.0  # the aim is out of reach here
    assert [p.status for p in aimed.segments] == ["planned"] * 3
    for a, f in zip(aimed.segments, full.segments):
        assert a.scored >= 60 * len(a.primitives) and f.scored < a.scored


def test_lazy_planning_plans_a_reused_segment_again_when_under_the_aim_and_freed(db):
    """A lazily planned scene reuses an unchanged segment's remembered grasps while the
    scene around it stays as it was (new sensor noise), even when they are under
    ``good_enough``; once a neighbour is gone, remembered grasps under the aim (scored
    against the neighbour: lower bounds) are planned again, and grasps that reach it are
    kept. Without an aim (``good_enough`` None) the segments are reused as before.
    Mutation caught: a freed segment under the aim reused."""
    pts, truth = _frame((0, 1, 2), XY, 1)
    cfg = SceneConfig(good_enough=1.0)  # out of reach: every segment planned, every one under it
    sp1 = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=cfg)
    assert [p.status for p in sp1.segments] == ["planned"] * 3 and sp1.best.score < 1.0
    pts2, _ = _frame((0, 1, 2), XY, 2)  # new noise, nothing gone: reused
    sp2 = plan_scene(pts2, db=db, rng=np.random.default_rng(1), config=cfg, previous=sp1)
    assert [p.status for p in sp2.segments] == ["reused"] * 3
    pts3, truth3 = _frame((0, 1), XY, 3)  # the sphere picked: the cylinder beside it freed, under the aim
    sp3 = plan_scene(pts3, db=db, rng=np.random.default_rng(2), config=cfg, previous=sp1)
    box, cyl = (_segment_of(sp3, truth3, k) for k in range(2))
    assert sp3.segments[cyl].status == "planned"
    assert sp3.segments[box].status == "reused"  # the sphere stood beyond the box's reach: nothing gone there
    met = plan_scene(pts3, db=db, rng=np.random.default_rng(2), config=replace(cfg, good_enough=0.05),
                     previous=sp1)  # the remembered grasps reach this aim: kept
    assert met.segments[cyl].status == "reused"
    off = plan_scene(pts3, db=db, rng=np.random.default_rng(2), config=replace(cfg, good_enough=None),
                     previous=sp1)
    assert [p.status for p in off.segments] == ["reused"] * 2


def test_drop_grasp_removes_the_executed_pose_and_its_near_twins():
    from scipy.spatial.transform import Rotation

    from graspsim.planning.scene import SceneGrasp
    from graspsim.planning.scene_reuse import SegmentMemory
    from graspsim.transforms import make_transform

    def g(dx, deg):
        return SceneGrasp(0, make_transform(Rotation.from_euler("z", deg, degrees=True).as_matrix(), [dx, 0, 0]),
                          0.05, 0.9, 0.9, 0.01)

    mem = (SegmentMemory(np.zeros((1, 3)), None, "", None, None, None,
                         (g(0, 0), g(0.005, 10), g(0.02, 0), g(0, 40))),)
    (kept,) = drop_grasp(mem, g(0, 0).T_world_wrist)
    yaw = [round(float(np.degrees(np.arctan2(x.T_world_wrist[1, 0], x.T_world_wrist[0, 0])))) for x in kept.grasps]
    assert [float(x.T_world_wrist[0, 3]) for x in kept.grasps] == [0.02, 0.0] and yaw == [0, 40]


def test_same_points_and_nothing_new_tolerances():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 0.05, (400, 3))
    assert same_points(a, a + rng.normal(0, 0.001, a.shape), tol=0.005)
    assert not same_points(a, a + (0.01, 0, 0), tol=0.005)  # moved 1 cm
    assert not same_points(a, a[:300], tol=0.005)  # a quarter gone
    assert nothing_new(a, a[:200], tol=0.005)  # points gone: nothing new
    patch = rng.uniform(0, 0.01, (20, 3)) + 0.06  # a new surface: 20 points within 1 cm
    assert not nothing_new(a[:200], np.concatenate([a[:200], patch]), tol=0.005)
    speckle = rng.uniform(0.06, 0.3, (30, 3))  # 30 isolated points: the sensor's speckle
    assert nothing_new(a[:200], np.concatenate([a[:200], speckle]), tol=0.005)
    assert nothing_new(None, None, tol=0.005) and not nothing_new(None, a, tol=0.005)


def _in_fingers(gripper, T, opening, P):
    """(K,) whether points P (K, 3) lie in the finger boxes of wrist pose T at pad gap opening."""
    b = gripper.collision_boxes()
    q = (P - T[:3, 3]) @ T[:3, :3]
    inside = np.zeros(len(P), bool)
    for name, c, h, s in zip(b.names, b.centers, b.half_extents, b.x_sign):
        if name.startswith("finger"):
            inside |= np.all(np.abs(q - (c + [s * 0.5 * opening, 0.0, 0.0])) <= h + 1e-9, axis=1)
    return inside


def test_felt_volume_is_the_finger_volume_behind_the_seen_surface_above_the_table():
    """A wall of observed points at z = 0.18 seen from above, the fingers of a top-down
    pose through it, the table at z = 0.16: the felt points are the fingers' volume between
    the table and the wall (less the tolerance), none above the wall (seen free) or under
    the table, spread so densely that no point of that volume is farther than half a step's
    diagonal from one. Bad input: one line naming what is valid."""
    from graspsim.grippers import HGPL_25_60_A as g
    from graspsim.maps.occlusion import FELT_STEP, ViewDepth, felt_volume

    x = np.linspace(-0.1, 0.1, 101)
    wall = np.stack(np.meshgrid(x, x, [0.18], indexing="ij"), axis=-1).reshape(-1, 3)
    view = ViewDepth(wall, np.array([0.0, 0.0, 1.0]))
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [0.0, 0.0, 0.30]  # the fingers from z = 0.145 to 0.225
    felt = felt_volume(g, T, 0.02, view, ((0.0, 0.0, 1.0), 0.16))
    assert len(felt) > 100 and _in_fingers(g, T, 0.02, felt).all()
    assert felt[:, 2].min() > 0.16 and felt[:, 2].max() < 0.18 - view.tolerance + 1e-9
    assert (felt[:, 0] < 0).any() and (felt[:, 0] > 0).any()  # both fingers
    rng = np.random.default_rng(0)
    probe = rng.uniform([-0.03, -0.01, 0.161], [0.03, 0.01, 0.18 - view.tolerance - 0.001], (4000, 3))
    probe = probe[_in_fingers(g, T, 0.02, probe)]
    gap = np.linalg.norm(probe[:, None] - felt[None], axis=2).min(axis=1)
    assert len(probe) > 500 and gap.max() <= 0.5 * FELT_STEP * math.sqrt(3) + 1e-9
    assert len(felt_volume(g, T, 0.02, view)) > len(felt)  # no table: below 0.16 too
    for bad, what in ((dict(opening=-0.01), "opening"), (dict(step=0.0), "step"),
                      (dict(T_wrist=np.full((4, 4), np.nan)), "T_wrist")):
        args = {"T_wrist": T, "opening": 0.02, **bad}
        with pytest.raises(InvalidParameterError, match=what):
            felt_volume(g, args.pop("T_wrist"), args.pop("opening"), view, **args)


def test_felt_points_keep_a_scene_plan_clear_of_them_and_replan_their_segment(db):
    """``plan_scene(felt=...)``: the finger volume of the best grasp of a plan handed back
    as felt points: its segment is planned again (not reused), and no grasp of the new
    plan with a score > 0 has a felt point in its fingers, where the first plan's best had
    them all. Bad felt: one line, nothing planned.
    Mutation caught: felt ignored (the best grasp reused)."""
    from graspsim.maps.occlusion import felt_volume

    cfg = SceneConfig()
    pts, truth = _frame((0, 1, 2), XY, 1)
    sp1 = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=cfg)
    best = sp1.best
    g = db.gripper

    class Everywhere:  # a view in which all of the fingers' volume is unseen
        def occluded(self, P):
            return np.ones(len(P), bool)

    felt = felt_volume(g, best.T_world_wrist, best.opening, Everywhere())
    assert _in_fingers(g, best.T_world_wrist, best.opening, felt).all()
    sp2 = plan_scene(pts, db=db, rng=np.random.default_rng(0), config=cfg, previous=sp1, felt=felt)
    k = best.segment
    assert sp2.segments[k].status == "planned"
    live = [x for x in sp2.grasps if x.score > 0]
    assert live and not any(_in_fingers(g, x.T_world_wrist, x.opening, felt).any() for x in live)
    for bad in (np.zeros((4, 2)), np.full((2, 3), np.nan), "felt"):
        with pytest.raises(InvalidParameterError, match="felt must be finite points"):
            plan_scene(pts, db=db, rng=np.random.default_rng(0), config=cfg, felt=bad)
