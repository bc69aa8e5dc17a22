"""The clutter protocol's bookkeeping on a scripted scene (no rendering, no planning):
a grasp that lifts another object than its target is no success; first-frame and
later-frame planning times are reported apart."""

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

import graspsim.tabletop.clutter as clutter
from graspsim.geometry.camera import rig
from graspsim.sim.outcomes import TrialOutcome
from graspsim.tabletop.clutter import OTHER, ClutterConfig, run_clutter, summarize
from graspsim.tabletop.scene_sim import SceneOutcome


@dataclass
class _Sim:
    picks: list  # the object each grasp lifts, in order (None: the grasp fails)
    left: set

    def objects_left(self):
        return sorted(self.left)

    def outside(self):
        return []

    def render(self, cam, **kw):
        return "frame"

    def execute(self, T, opening, *, target, noise, rng, plan=None):
        picked = self.picks.pop(0)
        if picked is None:
            return SceneOutcome(TrialOutcome.NO_CONTACT, None, target, "no_contact")
        self.left.discard(picked)
        cause = OTHER if picked != target else "success"
        return SceneOutcome(TrialOutcome.SUCCESS, picked, target, cause)

    def close(self):
        pass


class _Scene:
    def __init__(self, picks):
        self.objects = [SimpleNamespace(name=n) for n in ("box", "can", "cup")]
        self.picks = picks

    def sim(self, **arm):  # with an arm (robot, base): the same scripted simulation
        return _Sim(list(self.picks), {0, 1, 2})


class _View:
    labels = np.array([0] * 50 + [1] * 50 + [2] * 50)  # the truth of each point

    def world(self):
        return np.zeros((150, 3))


@dataclass
class _Per:
    indices: np.ndarray
    segment: np.ndarray
    n_segments: int


@dataclass
class _Best:
    segment: int
    T_world_wrist: np.ndarray
    opening: float = 0.05
    score: float = 0.9


@dataclass
class _Plan:
    perception: _Per
    grasps: tuple
    timing: dict
    memory: tuple = ()
    segments: tuple = tuple(SimpleNamespace(status="planned") for _ in range(3))  # none "deferred"


def _at(x: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x
    return T


def _scripted(monkeypatch, targets, poses=None):
    """plan_scene ranks first a grasp on the segment of the next target in ``targets``
    (at the next pose of ``poses``, default: a new pose each frame), then a grasp at
    x = 1 m on the same segment."""
    order = list(targets)
    where = list(poses) if poses is not None else [0.1 * k for k in range(len(order))]

    def plan(points, *, db, rng, config, labels, previous, viewpoint, felt=None):
        truth = _View.labels
        k = order.pop(0)
        grasps = (_Best(k, _at(where.pop(0))), _Best(k, _at(1.0), score=0.5))
        return _Plan(_Per(np.arange(150), truth.copy(), 3), grasps, {"total": 0.0})

    monkeypatch.setattr(clutter, "plan_scene", plan)
    monkeypatch.setattr(clutter, "backproject", lambda frame: _View())


def test_a_grasp_lifting_another_object_is_counted_apart_not_as_a_success(monkeypatch):
    # aimed at 0, lifted 1 (other); aimed at 0, lifted 0; aimed at 2, failed; aimed at 2, lifted 2
    _scripted(monkeypatch, [0, 0, 2, 2])
    r = run_clutter(_Scene([1, 0, None, 2]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None))
    assert [a.success for a in r.attempts] == [False, True, False, True]
    assert [a.cause for a in r.attempts] == [OTHER, "success", "no_contact", "success"]
    assert r.successes == 2 and r.other_objects == 1 and r.grasp_success_rate == 0.5
    assert r.removed == 3 and r.declutter_rate == 1.0 and r.stop == "cleared"
    assert r.names == ("box", "can", "cup") and r.left == {}  # cleared: nothing left to explain
    s = summarize([r])
    assert s["per_object"]["box"] == {"placed": 1, "removed": 1, "grasps": 2, "lifted": 1, "failed": {OTHER: 1},
                                      "left": {}}
    assert s["successes"] == 2 and s["attempts"] == 4 and s["grasp_success_rate"] == 0.5
    assert s["other_objects"] == 1 and s["failure_causes"] == {OTHER: 1, "no_contact": 1}
    p = s["planning_s"]
    assert p["count"] == 4 and p["first_frame"]["count"] == 1 and p["later_frames"]["count"] == 3


def test_another_object_lifted_is_no_failure_in_a_row(monkeypatch):
    # failed, then another object lifted, then failed: not two failures in a row
    _scripted(monkeypatch, [0, 0, 0, 0])
    r = run_clutter(_Scene([None, 1, None, 0]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, max_attempts=4))
    assert len(r.attempts) == 4 and r.successes == 1 and r.other_objects == 1


def test_a_failed_grasp_is_not_tried_again(monkeypatch):
    """The planner ranks the same pose first after it failed (an unchanged scene): the
    protocol takes the next grasp instead (here at x = 1 m), so one failure does not
    become two in a row."""
    _scripted(monkeypatch, [0, 0], poses=[0.0, 0.002])  # the second frame offers a 2 mm twin first
    r = run_clutter(_Scene([None, 0]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, max_attempts=2, reuse=False))
    assert [a.cause for a in r.attempts] == ["no_contact", "success"]
    assert [a.score for a in r.attempts] == [0.9, 0.5]  # the second grasp was the x = 1 m one


def test_near_pose_is_the_same_contacts_whatever_the_approach():
    from scipy.spatial.transform import Rotation

    from graspsim.planning.scene_reuse import near_pose

    def pose(axis, deg, x=0.3):
        T = _at(x)
        T[:3, :3] = Rotation.from_euler(axis, deg, degrees=True).as_matrix()
        return T

    T = _at(0.3)
    assert near_pose(T, pose("z", 180))  # jaws swapped: the same grasp
    assert near_pose(T, pose("x", 40))  # the approach turned about the closing axis, wrists at the contacts
    assert not near_pose(T, pose("x", 40), reach=0.1)  # ... 10 cm out along the approach the points part
    assert not near_pose(T, pose("z", 60))  # another closing direction
    assert near_pose(T, _at(0.31)) and not near_pose(T, _at(0.32))


def test_a_frame_whose_reused_plans_offer_nothing_is_planned_afresh(monkeypatch):
    """Reused plans keep the scores they had (a grasp blocked by an object since lifted
    stays at 0): when they leave no grasp, the frame is planned again without them
    before the episode stops for want of a grasp."""
    calls, views = [], []

    def plan(points, *, db, rng, config, labels, previous=None, viewpoint=None, felt=None):
        calls.append(previous is not None)
        views.append(viewpoint)
        truth = _View.labels
        k = 3 - len(_View.left)
        grasps = () if previous is not None else (_Best(k, _at(0.1 * len(calls))),)
        return _Plan(_Per(np.arange(150), truth.copy(), 3), grasps, {"total": 0.0})

    monkeypatch.setattr(clutter, "plan_scene", plan)
    monkeypatch.setattr(clutter, "backproject", lambda frame: _View())
    scene = _Scene([0, 1, 2])
    sim = scene.sim()
    _View.left = sim.left
    scene.sim = lambda: sim
    r = run_clutter(scene, db=None, rng=np.random.default_rng(0), config=ClutterConfig(depth_noise=None))
    assert r.successes == 3 and r.stop == "cleared"
    assert calls == [False, True, False, True, False]  # frames 2 and 3: reused plans first, then afresh
    eye = rig(1)[0].T_world_camera[:3, 3]  # every plan knows where the camera was (the occluded space)
    assert len(views) == 5 and all(v is not None and np.allclose(v, eye) for v in views)


def test_an_object_whose_planned_grasps_all_failed_is_left_excluded_not_no_grasp(monkeypatch):
    """Its two grasps failed (the second frame offers the first again, which is not tried):
    the third look has none left to try. It had grasps planned: "excluded"; the objects
    that had none: "no_grasp"."""
    _scripted(monkeypatch, [0, 0, 0], poses=[0.0, 0.0, 0.0])
    r = run_clutter(_Scene([None, None]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, max_failures=3, reuse=False))
    assert [a.score for a in r.attempts] == [0.9, 0.5] and r.stop == "no_grasp"
    assert r.left == {0: "excluded", 1: "no_grasp", 2: "no_grasp"}


def test_a_lazy_look_whose_planned_grasps_are_spent_plans_every_object(monkeypatch):
    """``ClutterConfig.good_enough``: the look plans the highest objects only (the others
    "deferred"); when its planned grasps are all spent (here: the one failed grasp's
    twin), the same look plans every object (``good_enough`` None) before the episode
    stops for want of a grasp. An object still deferred when the episode stops was not
    tried (not "no_grasp"). Mutation caught: no fallback (the episode stopped no_grasp)."""
    asked = []

    def plan(points, *, db, rng, config, labels, previous=None, viewpoint=None, felt=None):
        asked.append(config.good_enough)
        truth = _View.labels
        if config.good_enough is None:  # every object planned: a grasp on object 1 too
            grasps, status = (_Best(0, _at(0.0)), _Best(1, _at(0.5), score=0.8)), ("planned",) * 3
        else:  # lazily: object 0 only, at the pose that failed
            grasps, status = (_Best(0, _at(0.0)),), ("planned", "deferred", "deferred")
        segs = tuple(SimpleNamespace(status=s) for s in status)
        return _Plan(_Per(np.arange(150), truth.copy(), 3), grasps, {"total": 0.0}, segments=segs)

    monkeypatch.setattr(clutter, "plan_scene", plan)
    monkeypatch.setattr(clutter, "backproject", lambda frame: _View())
    r = run_clutter(_Scene([None, 1]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, reuse=False, max_attempts=2))
    assert asked == [0.9, 0.9, None]  # the second look: lazily, then every object
    assert [a.cause for a in r.attempts][:2] == ["no_contact", "success"] and r.attempts[1].target == 1
    asked.clear()
    r = run_clutter(_Scene([None]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, reuse=False, max_attempts=1))
    assert r.stop == "max_attempts" and r.left == {0: "not_tried", 1: "not_tried", 2: "not_tried"}


def test_a_lazy_look_whose_planned_grasps_the_arm_cannot_reach_plans_every_object(monkeypatch):
    """With an arm: the look's planned grasps (object 0's; the others deferred) are all
    refused by the reachability check, so the look plans every object and the arm
    executes one it reaches (on object 1) instead of stopping "unreachable". Mutation
    caught: no fallback for the arm (the episode stopped unreachable)."""
    from graspsim.tabletop.clutter import ClutterEpisode, ClutterRobot

    asked = []

    def plan(points, *, db, rng, config, labels, previous=None, viewpoint=None, felt=None):
        asked.append(config.good_enough)
        if config.good_enough is None:
            grasps, status = (_Best(0, _at(0.0)), _Best(1, _at(0.5), score=0.8)), ("planned",) * 3
        else:
            grasps, status = (_Best(0, _at(0.0)),), ("planned", "deferred", "deferred")
        return _Plan(_Per(np.arange(150), _View.labels.copy(), 3), grasps, {"total": 0.0},
                     segments=tuple(SimpleNamespace(status=s) for s in status))

    def reachable(self, cands, positive):  # the arm reaches object 1's grasps only
        g = next((g for g in cands if g.segment == 1), None)
        return g, None, {"candidates": len(cands), "refused": [] if g else [{"cause": "unreachable"}]}

    monkeypatch.setattr(clutter, "plan_scene", plan)
    monkeypatch.setattr(clutter, "backproject", lambda frame: _View())
    monkeypatch.setattr(clutter, "_arm", lambda robot: None)
    monkeypatch.setattr(ClutterEpisode, "_reachable", reachable)
    r = run_clutter(_Scene([1]), db=None, rng=np.random.default_rng(0),
                    config=ClutterConfig(depth_noise=None, reuse=False, robot=ClutterRobot(), max_attempts=1))
    assert asked == [0.9, None] and r.attempts[0].target == 1 and r.attempts[0].success


def test_a_start_collision_with_an_object_is_felt_by_the_next_plans_until_the_scene_changes(monkeypatch):
    """``ClutterConfig.feel``: a grasp that started in collision with an object hands the
    next plans its finger volume the camera did not see (``plan_scene(felt=...)``: here
    all of it, behind a wall of observed points, above the table), at the pose executed;
    a start collision with the table adds nothing and keeps it (the scene is as it was);
    a grasp that changed the scene (a success) clears it. feel=False: never handed on.
    Mutations caught: felt not passed, not cleared after a success, the table's added."""
    from graspsim.geometry.table import TablePlane
    from graspsim.grippers import HGPL_25_60_A
    from graspsim.maps.occlusion import ViewDepth, felt_volume

    eye = rig(1)[0].T_world_camera[:3, 3]
    p = np.array([0.0, 0.0, 0.05])
    T = np.diag([1.0, -1.0, -1.0, 1.0])  # top down, the fingers' middle at p
    T[:3, 3] = p + [0.0, 0.0, 0.115]
    u = (eye - p) / np.linalg.norm(eye - p)  # a wall of seen points 15 cm before p, across the view
    a = np.cross(u, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(u, a)
    g = np.linspace(-0.15, 0.15, 101)
    wall = p + 0.15 * u + g[:, None, None] * a + g[None, :, None] * b
    wall = wall.reshape(-1, 3)
    table = TablePlane(normal=(0.0, 0.0, 1.0), height=0.0)
    expected = felt_volume(HGPL_25_60_A, T, 0.03, ViewDepth(wall, eye), ((0.0, 0.0, 1.0), 0.0))
    assert len(expected) > 100

    causes = ["start_collision_target", "start_collision_table", "success", "no_contact"]

    class Sim(_Sim):
        gripper = HGPL_25_60_A

        def execute(self, T_, opening, *, target, noise, rng, plan=None):
            cause = causes[4 - len(self.picks)]
            self.picks.pop(0)
            extra = {"T_world_wrist": T.tolist(), "opening": 0.03}  # the pose executed
            if cause == "success":
                self.left.discard(0)
                return SceneOutcome(TrialOutcome.SUCCESS, 0, target, cause, extra=extra)
            out = TrialOutcome.NO_CONTACT if cause == "no_contact" else TrialOutcome.START_COLLISION
            return SceneOutcome(out, None, target, cause, extra=extra)

    class Scene(_Scene):
        def sim(self, **arm):
            return Sim([None] * 4, {0, 1, 2})

    given = []

    def plan(points, *, db, rng, config, labels, previous=None, viewpoint=None, felt=None):
        given.append(None if felt is None else np.array(felt))
        per = SimpleNamespace(indices=np.arange(150), segment=_View.labels.copy(), n_segments=3, points=wall)
        grasps = (_Best(0, _at(0.1 * len(given))), _Best(0, _at(1.0 + 0.1 * len(given)), score=0.5))
        return SimpleNamespace(perception=per, grasps=grasps, timing={"total": 0.0}, memory=(), table=table,
                               segments=tuple(SimpleNamespace(status="planned") for _ in range(3)))

    monkeypatch.setattr(clutter, "plan_scene", plan)
    monkeypatch.setattr(clutter, "backproject", lambda frame: _View())
    for feel in (True, False):
        given.clear()
        r = run_clutter(Scene([]), db=None, rng=np.random.default_rng(0),
                        config=ClutterConfig(depth_noise=None, reuse=False, max_failures=3, max_attempts=4, feel=feel))
        assert [a.cause for a in r.attempts] == causes
        assert len(given) == 4
        if not feel:
            assert all(f is None for f in given)
            continue
        assert given[0] is None
        np.testing.assert_allclose(given[1], expected)  # felt: the target's start collision
        np.testing.assert_allclose(given[2], expected)  # the table's adds nothing
        assert given[3] is None  # a success changed the scene


def test_clutter_config_sim_settles_the_drawn_scene_and_simulates_the_episode_with_it(monkeypatch):
    """ClutterConfig.sim (e.g. the soft contact model) reaches both the scene run_benchmark draws
    and settles and the episode's simulation; anything but SimSettings is refused."""
    import pytest

    import graspsim.tabletop.table_scene as table_scene
    from graspsim.errors import InvalidParameterError
    from graspsim.grippers.spec import HGPL_25_60_A
    from graspsim.sim import contact_model

    soft = contact_model("soft")
    drawn, simulated = {}, {}
    scene = SimpleNamespace(kind="packed", objects=(), sim=lambda **kw: simulated.update(kw) or SimpleNamespace(
        objects_left=lambda: [], outside=lambda: [], close=lambda: None))
    monkeypatch.setattr(table_scene, "make_scene", lambda *a, **kw: drawn.update(kw) or scene)
    db = SimpleNamespace(gripper=HGPL_25_60_A)
    clutter.run_benchmark(1, "packed", 1, 0, db=db, config=ClutterConfig(sim=soft))
    assert drawn["settings"] is soft and simulated["settings"] is soft
    drawn.clear(), simulated.clear()
    clutter.run_benchmark(1, "packed", 1, 0, db=db, config=ClutterConfig())
    assert "settings" not in drawn and "settings" not in simulated  # SimSettings() by default
    with pytest.raises(InvalidParameterError, match="SimSettings"):
        ClutterConfig(sim="stiff")
