"""The clutter protocol's bookkeeping on a scripted scene (no rendering, no planning):
a grasp that lifts another object than its target is no success; first-frame and
later-frame planning times are reported apart."""

from dataclasses import dataclass

import numpy as np

import graspsim.sim.clutter as clutter
from graspsim.sim.clutter import OTHER, ClutterConfig, run_clutter, summarize
from graspsim.sim.outcomes import TrialOutcome
from graspsim.sim.scene_sim import SceneOutcome


@dataclass
class _Sim:
    picks: list  # the object each grasp lifts, in order (None: the grasp fails)
    left: set

    def objects_left(self):
        return sorted(self.left)

    def render(self, cam, **kw):
        return "frame"

    def execute(self, T, opening, *, target, noise, rng):
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
        self.objects = [0, 1, 2]
        self.picks = picks

    def sim(self):
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
    best: _Best
    timing: dict
    memory: tuple = ()


def _scripted(monkeypatch, targets):
    """plan_scene always chooses the segment of the next target in ``targets``."""
    order = list(targets)

    def plan(points, *, db, rng, config, labels, previous):
        truth = _View.labels
        return _Plan(_Per(np.arange(150), truth.copy(), 3), _Best(order.pop(0), np.eye(4)), {"total": 0.0})

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
    s = summarize([r])
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
