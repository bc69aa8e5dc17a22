"""Clutter removal: clear a table of several objects, one grasp at a time.

The benchmark of VGN, GPD and their successors, on a :class:`~graspsim.sim.scenes.TableScene`:

    render a depth frame (one D435-like camera, sensor noise) -> back-project to the world
    -> :func:`~graspsim.perception.scene.plan_scene` (table, segments, every segment
    planned, grasps checked against the whole scene) -> execute the best grasp on any
    object (execution error optional) -> a lifted object leaves the scene -> render again

until the table is clear, two consecutive grasps failed, no grasp is found, or
``max_attempts`` grasps were tried. Metrics (:class:`ClutterResult`): grasp success rate
(GSR = grasps that lifted their target / grasps executed; a grasp that lifted another
object than its target is no success: it is counted apart (cause ``success_other_object``), and the
object it lifted leaves the scene), declutter rate (objects removed / objects placed),
planning seconds per grasp (from the depth image, back-projection included,
to the ranked grasps), each failure's cause, and segmentation quality
against MuJoCo's segmentation render: of the objects seen in a frame, the share whose
points form exactly one cluster (:func:`one_cluster_objects`).
Ablations: ``SceneConfig(neighbours=False)`` (no neighbour check) and
``ClutterConfig(ground_truth=True)`` (the render's object labels as the segments).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from graspsim.errors import InvalidParameterError
from graspsim.perception.scene import SceneConfig, plan_scene
from graspsim.perception.scene_reuse import drop_grasp, near_pose
from graspsim.sim.camera import Camera, DepthNoise, backproject, rig
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.scenes import known_gap

__all__ = ["scene_settings", "ClutterConfig", "Attempt", "ClutterResult", "ClutterFrame", "ClutterEpisode",
           "run_clutter", "run_benchmark", "summarize", "one_cluster_objects", "object_segmentation",
           "per_object", "failure_rows", "FAILURE_COLUMNS", "STOPS", "OTHER", "LEFT"]

#: Why an episode ended.
STOPS = ("cleared", "failures", "no_grasp", "max_attempts")
#: The cause of a grasp that lifted an object other than its target.
OTHER = "success_other_object"


def scene_settings(kind: str, **kw) -> SceneConfig:
    """``SceneConfig(**kw)`` for planning scenes of ``kind`` made by
    :func:`~graspsim.sim.scenes.make_scene`, with the least gap such scenes keep between
    objects as ``min_gap`` (packed: 1 cm; piles: none, :func:`~graspsim.sim.scenes.known_gap`):
    what a user who placed the objects knows."""
    return SceneConfig(**{"min_gap": known_gap(kind), **kw})


@dataclass(frozen=True)
class ClutterConfig:
    """scene: the perception and planning settings; depth_noise: the sensor's (None: a
    perfect sensor); execution: the arm's pose error (None: none); ground_truth: segment
    by the render's object labels instead of clustering (ablation); max_failures:
    consecutive failed grasps that end an episode; max_attempts: grasps per episode at
    most (None: 2 x objects + 2); min_seen: points (after thinning) an object needs in
    a frame to count in the segmentation quality; reuse: a segment that did not change
    since the previous frame keeps its plan (``plan_scene(previous=...)``), less the
    grasp that was executed."""

    scene: SceneConfig = field(default_factory=SceneConfig)
    depth_noise: DepthNoise | None = field(default_factory=DepthNoise)
    execution: ExecutionNoise | None = None
    ground_truth: bool = False
    max_failures: int = 2
    max_attempts: int | None = None
    min_seen: int = 40
    reuse: bool = True

    def __post_init__(self) -> None:
        for k in ("max_failures", "min_seen"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise InvalidParameterError(f"ClutterConfig.{k} must be an integer >= 1, got {v!r}")
        m = self.max_attempts
        if m is not None and (isinstance(m, bool) or not isinstance(m, int) or m < 1):
            raise InvalidParameterError(f"ClutterConfig.max_attempts must be an integer >= 1 or None, got {m!r}")

    def to_dict(self) -> dict:
        return {"scene": self.scene.to_dict(), "depth_noise": None if self.depth_noise is None
                else self.depth_noise.to_dict(), "execution": None if self.execution is None
                else self.execution.to_dict(), "ground_truth": self.ground_truth,
                "max_failures": self.max_failures, "max_attempts": self.max_attempts, "min_seen": self.min_seen,
                "reuse": self.reuse}


@dataclass(frozen=True)
class Attempt:
    """One executed grasp: target (the object the chosen segment is mostly of, ground
    truth), outcome (:meth:`SceneOutcome.to_dict`), success (the target lifted), cause
    (``success_other_object``: another object came up; not a success), score (robust),
    planning [s] (depth frame to ranked grasps; ``timing`` per stage), segments found,
    objects seen, and of those segmented as one cluster."""

    target: int | None
    outcome: dict
    success: bool
    cause: str
    score: float
    planning: float
    timing: dict
    segments: int
    seen: int
    one_cluster: int

    def to_dict(self) -> dict:
        return dict(self.__dict__)


#: Why an object was left on the table, judged on the episode's last look
#: (:meth:`ClutterEpisode.left_reasons`).
LEFT = ("not_seen", "merged", "split", "no_grasp", "not_tried", "off_table")


@dataclass(frozen=True)
class ClutterResult:
    """One episode: placed objects, attempts in order, removed objects, why it stopped
    (:data:`STOPS`), the first frame's segmentation quality (objects seen, one cluster);
    names: the placed objects' names (by id); left: object id -> why it is still on the
    table (:data:`LEFT`)."""

    placed: int
    attempts: tuple[Attempt, ...]
    removed: int
    stop: str
    first_seen: int
    first_one_cluster: int
    seconds: float
    names: tuple[str, ...] = ()
    left: dict = field(default_factory=dict)

    @property
    def successes(self) -> int:
        return sum(a.success for a in self.attempts)

    @property
    def other_objects(self) -> int:
        """Grasps that lifted an object other than their target (not successes)."""
        return sum(a.cause == OTHER for a in self.attempts)

    @property
    def grasp_success_rate(self) -> float:
        return self.successes / len(self.attempts) if self.attempts else float("nan")

    @property
    def declutter_rate(self) -> float:
        return self.removed / self.placed

    def to_dict(self) -> dict:
        return {"placed": self.placed, "removed": self.removed, "attempts": len(self.attempts),
                "successes": self.successes, "other_objects": self.other_objects,
                "grasp_success_rate": self.grasp_success_rate,
                "declutter_rate": self.declutter_rate, "stop": self.stop, "first_seen": self.first_seen,
                "first_one_cluster": self.first_one_cluster, "seconds": self.seconds,
                "objects": list(self.names), "left": {str(k): v for k, v in self.left.items()},
                "steps": [a.to_dict() for a in self.attempts]}


def object_segmentation(truth: np.ndarray, found: np.ndarray, k: int, *, min_seen: int = 40,
                        share: float = 0.9) -> tuple[str, int | None]:
    """How object ``k`` is segmented: ("not_seen" | "one" | "merged" | "split", its
    segment when "one") by :func:`one_cluster_objects`' rule; merged: the segment holding
    most of its points is less than ``share`` its own (it shares it with another object);
    split: spread over segments, or not segmented."""
    mine = truth == k
    if mine.sum() < min_seen:
        return "not_seen", None
    segs = found[mine & (found >= 0)]
    if not len(segs):
        return "split", None
    ids, counts = np.unique(segs, return_counts=True)
    best = int(ids[np.argmax(counts)])
    pure = np.mean(truth[found == best] == k) >= share
    if not pure:
        return "merged", None
    return ("one", best) if counts.max() >= share * len(segs) else ("split", None)


def one_cluster_objects(truth: np.ndarray, found: np.ndarray, *, min_seen: int = 40,
                        share: float = 0.9) -> tuple[int, int]:
    """(objects seen, objects segmented as one cluster) from per-point ground-truth
    object ids ``truth`` (N,) (< 0: none) and found segment ids ``found`` (N,) (< 0:
    none) of the same points. An object is seen with ``min_seen`` points or more; it is
    one cluster when one segment holds at least ``share`` of its segmented points and at
    least ``share`` of that segment's points are the object's."""
    truth, found = np.asarray(truth), np.asarray(found)
    seen = one = 0
    for k in np.unique(truth[truth >= 0]):
        mine = truth == k
        if mine.sum() < min_seen:
            continue
        seen += 1
        segs = found[mine & (found >= 0)]
        if not len(segs):
            continue
        ids, counts = np.unique(segs, return_counts=True)
        best = ids[np.argmax(counts)]
        if counts.max() >= share * len(segs) and np.mean(truth[found == best] == k) >= share:
            one += 1
    return seen, one


def _target(per, seg: int, truth: np.ndarray) -> int | None:
    """The object most of segment ``seg``'s points show (ground truth), or None."""
    t = truth[per.indices[per.segment == seg]]
    t = t[t >= 0]
    return int(np.bincount(t).argmax()) if len(t) else None


@dataclass(frozen=True, eq=False)
class ClutterFrame:
    """What one look at the scene gives: the depth ``frame`` (colour too when asked),
    its back-projected ``view``, the :class:`~graspsim.perception.scene.ScenePlan`
    ``plan``, ``planning`` [s] (depth frame to ranked grasps), of the objects seen
    (ground truth) those segmented as one cluster; ``candidates``: the plan's grasps in
    ranking order less those closing on a failed grasp's contacts (not tried again), and
    ``best``: the first of them with a robust score > 0 (None: none), what the protocol
    executes."""

    frame: object
    view: object
    plan: object
    planning: float
    seen: int
    one_cluster: int
    candidates: tuple = ()
    best: object = None


class ClutterEpisode:
    """One clutter-removal episode, stepped by its caller: the one implementation of
    the protocol's render -> plan -> execute step and of its stopping rules, shared by
    :func:`run_clutter` (which always executes the best grasp) and the Gymnasium env
    ``graspsim/ClutterClear-v0`` (where a policy chooses).

        ep = ClutterEpisode(scene, db=db, rng=rng)
        while ep.stop is None:
            look = ep.observe()            # None when it ended (cleared, no grasp)
            if look is not None:
                ep.execute(look, look.best)
        result = ep.result(); ep.close()

    ``stop`` is None while it runs, then one of :data:`STOPS`: the table is clear, no
    grasp with a robust score > 0 was left to try, ``max_failures`` consecutive grasps
    failed, or ``max_attempts`` grasps were executed. Deterministic given ``rng``.
    ``config`` None: the defaults, planned with :func:`scene_settings` of the scene's kind."""

    def __init__(self, scene, *, db, rng: np.random.Generator, config: ClutterConfig | None = None,
                 camera: Camera | None = None, rgb: bool = False):
        self.config = cfg = config or ClutterConfig(scene=scene_settings(scene.kind))
        self.scene, self.db, self.rgb = scene, db, rgb
        self.camera = camera or rig(1)[0]
        self.cap = cfg.max_attempts or 2 * len(scene.objects) + 2
        self._t0 = time.perf_counter()
        self.sim = scene.sim()
        self._depth_rng, self._plan_rng, self._exec_rng = rng.spawn(3)
        self.attempts: list[Attempt] = []
        self.failures = 0
        self.first: tuple[int, int] | None = None
        self.last: ClutterFrame | None = None  # the latest look, also when it found no grasp
        self._previous = None  # the plan the next look may reuse (ClutterConfig.reuse)
        self.failed: list[np.ndarray] = []  # wrist poses of the episode's failed grasps
        self.reach = float(db.gripper.fingertip_z) if db is not None else 0.0  # wrist to fingertips [m]
        self.stop: str | None = None if self.sim.objects_left() else "cleared"

    def render(self):
        """A depth frame of the scene now (the sensor's noise drawn from the episode)."""
        return self.sim.render(self.camera, noise=self.config.depth_noise, rng=self._depth_rng, rgb=self.rgb)

    def observe(self) -> ClutterFrame | None:
        """Render and plan the scene; None (and ``stop`` = "no_grasp") when no grasp left
        to try has a robust score > 0 (``last`` holds that look all the same)."""
        if self.stop is not None:
            raise InvalidParameterError(f"the episode has ended ({self.stop}); nothing to observe")
        cfg = self.config
        frame = self.render()
        t1 = time.perf_counter()  # planning: from the depth image to ranked grasps
        view = backproject(frame)
        truth = view.labels
        labels = truth if cfg.ground_truth else None
        eye = self.camera.T_world_camera[:3, 3]  # the occluded space behind what the camera saw
        sp = plan_scene(view.world(), db=self.db, rng=self._plan_rng, config=cfg.scene, labels=labels,
                        previous=self._previous, viewpoint=eye)
        cands, best = self._candidates(sp)
        if best is None and self._previous is not None:  # reused plans kept scores from before: plan afresh
            sp = plan_scene(view.world(), db=self.db, rng=self._plan_rng, config=cfg.scene, labels=labels,
                            viewpoint=eye)
            cands, best = self._candidates(sp)
        planning = time.perf_counter() - t1
        per = sp.perception
        seen, one = one_cluster_objects(truth[per.indices], per.segment, min_seen=cfg.min_seen)
        if self.first is None:
            self.first = (seen, one)
        self.last = ClutterFrame(frame, view, sp, planning, seen, one, cands, best)
        if best is None:
            self.stop = "no_grasp"
            return None
        return self.last

    def _candidates(self, sp) -> tuple[tuple, object]:
        """The grasps of plan ``sp`` still to try, in ranking order, and the first of them
        with a robust score > 0 (or None). A grasp that failed is not tried again, nor
        any that closes on its contacts (:func:`~graspsim.perception.scene_reuse.near_pose`
        at the fingertips: the other approaches of a contact pair fail the same way; a
        start collision leaves the scene as it was)."""
        cands = tuple(g for g in sp.grasps
                      if not any(near_pose(T, g.T_world_wrist, reach=self.reach) for T in self.failed))
        return cands, next((g for g in cands if g.score > 0), None)

    def execute(self, look: ClutterFrame, grasp) -> Attempt:
        """Execute ``grasp`` (a :class:`~graspsim.perception.scene.SceneGrasp` of
        ``look.plan``) with the configured execution error, then apply the stopping rules."""
        if self.stop is not None:
            raise InvalidParameterError(f"the episode has ended ({self.stop}); no more grasps")
        cfg = self.config
        sp, truth = look.plan, look.view.labels
        target = _target(sp.perception, grasp.segment, truth)
        out = self.sim.execute(grasp.T_world_wrist, grasp.opening, target=target, noise=cfg.execution,
                               rng=self._exec_rng if cfg.execution is not None else None)
        if cfg.reuse:  # the executed grasp is not offered again
            self._previous = replace(sp, memory=drop_grasp(sp.memory, grasp.T_world_wrist, reach=self.reach))
        hit = out.success and out.picked == target  # the target came up (None: unknown target)
        cause = OTHER if out.success and not hit else out.cause
        a = Attempt(target, out.to_dict(), hit, cause, grasp.score, look.planning, sp.timing,
                    sp.perception.n_segments, look.seen, look.one_cluster)
        self.attempts.append(a)
        # a grasp that lifted another object is no success, but the scene changed: no failure in a row
        self.failures = 0 if out.success else self.failures + 1
        if not out.success:
            self.failed.append(np.asarray(grasp.T_world_wrist, float))
        if self.failures >= cfg.max_failures:
            self.stop = "failures"
        elif not self.sim.objects_left():
            self.stop = "cleared"
        elif len(self.attempts) >= self.cap:
            self.stop = "max_attempts"
        return a

    @property
    def removed(self) -> int:
        return len(self.scene.objects) - len(self.sim.objects_left())

    def left_reasons(self) -> dict[int, str]:
        """Why each object left on the table is there, judged on the last look
        (:data:`LEFT`): off the table (knocked beyond it), not seen (fewer than
        ``min_seen`` points), merged with another object or split (by
        :func:`object_segmentation`), one cluster but no grasp with a robust score > 0
        left to try on its segment (no_grasp), or one that was not tried before the
        episode stopped (not_tried)."""
        look, out = self.last, {}
        off = set(self.sim.outside())
        for k in self.sim.objects_left():
            if k in off:
                out[k] = "off_table"
                continue
            if look is None:
                out[k] = "not_seen"
                continue
            per = look.plan.perception
            how, seg = object_segmentation(look.view.labels[per.indices], per.segment, k,
                                           min_seen=self.config.min_seen)
            if how != "one":
                out[k] = how
            else:
                out[k] = "not_tried" if any(g.segment == seg and g.score > 0 for g in look.candidates) \
                    else "no_grasp"
        return out

    def result(self) -> ClutterResult:
        first = self.first or (0, 0)
        return ClutterResult(len(self.scene.objects), tuple(self.attempts), self.removed, self.stop or "max_attempts",
                             first[0], first[1], time.perf_counter() - self._t0,
                             tuple(o.name for o in self.scene.objects), self.left_reasons())

    def close(self) -> None:
        """Free the renderer (the simulation stays readable)."""
        self.sim.close()


def run_clutter(scene, *, db, rng: np.random.Generator, config: ClutterConfig | None = None,
                camera: Camera | None = None, on_step=None) -> ClutterResult:
    """One clutter-removal episode on ``scene`` (a :class:`~graspsim.sim.scenes.TableScene`)
    seen by ``camera`` (default: one D435-like camera, ``rig(1)``), planning against the
    :class:`~graspsim.maps.database.MapDatabase` ``db``, executing the best grasp each
    time (:class:`ClutterEpisode`). Deterministic given ``rng``.
    on_step(view, frame, plan, attempt): called after each executed grasp with the
    back-projected view, the depth frame (colour rendered too), the ScenePlan and the
    Attempt (e.g. to draw it: :func:`~graspsim.sim.clutter_figure.save_step_figure`)."""
    ep = ClutterEpisode(scene, db=db, rng=rng, config=config, camera=camera, rgb=on_step is not None)
    try:
        while ep.stop is None:
            look = ep.observe()
            if look is None:
                break
            a = ep.execute(look, look.best)
            if on_step is not None:
                on_step(look.view, look.frame, look.plan, a)
    finally:
        ep.close()
    return ep.result()


def run_benchmark(n_objects: int, kind: str, scenes: int, seed: int, *, db, config: ClutterConfig | None = None,
                  object_set: str = "mixed", first: int = 0, on_step=None, on_scene=None) -> list[ClutterResult]:
    """``scenes`` episodes on scenes ``first``, ``first + 1``, ... of ``n_objects`` of
    ``kind`` ("pile" | "packed"). Scene ``i`` is ``make_scene(n_objects, kind, derived_seed(seed, "scene", i))`` and its
    episode draws from ``rng_for(seed, "clutter", i)``: every condition (noise,
    ablation) meets the same scenes and the same draws. on_step(i, view, frame, plan,
    attempt) as :func:`run_clutter`'s; on_scene(i, scene, result) after each episode."""
    from graspsim.seeding import derived_seed, rng_for
    from graspsim.sim.scenes import make_scene

    if isinstance(scenes, bool) or not isinstance(scenes, int) or scenes < 1:
        raise InvalidParameterError(f"scenes must be a whole number >= 1, got {scenes!r}")
    out = []
    for i in range(first, first + scenes):
        scene = make_scene(n_objects, kind, derived_seed(seed, "scene", i), object_set=object_set,
                           gripper=db.gripper)
        step = None if on_step is None else (lambda *a, i=i: on_step(i, *a))
        r = run_clutter(scene, db=db, rng=rng_for(seed, "clutter", i), config=config, on_step=step)
        out.append(r)
        if on_scene is not None:
            on_scene(i, scene, r)
    return out


def _spread(values: list[float]) -> dict:
    """count, mean, median and max of seconds (None when there are none)."""
    v = np.asarray(values, float)
    if not len(v):
        return {"count": 0, "mean": None, "median": None, "max": None}
    return {"count": len(v), "mean": float(v.mean()), "median": float(np.median(v)), "max": float(v.max())}


def per_object(results: list[ClutterResult]) -> dict:
    """The failure table per object name, over episodes: placed, removed, grasps aimed
    at it (the target: the object most of the chosen segment's points show), those that
    lifted it, the failed ones by cause (start collisions by what they hit, slips,
    drops, another object lifted, ...), and the copies left on the table by why
    (:data:`LEFT`). Sorted by objects left, then failed grasps, most first."""
    rows: dict[str, dict] = {}
    for r in results:
        names = r.names or tuple(str(k) for k in range(r.placed))
        for k, name in enumerate(names):
            row = rows.setdefault(name, {"placed": 0, "removed": 0, "grasps": 0, "lifted": 0, "failed": {},
                                         "left": {}})
            row["placed"] += 1
            row["removed"] += k not in r.left
        for k, why in r.left.items():
            d = rows[names[k]]["left"]
            d[why] = d.get(why, 0) + 1
        for a in r.attempts:
            if a.target is None:
                continue
            row = rows[names[a.target]]
            row["grasps"] += 1
            row["lifted"] += a.success
            if not a.success:
                row["failed"][a.cause] = row["failed"].get(a.cause, 0) + 1
    for row in rows.values():
        row["failed"] = dict(sorted(row["failed"].items()))
        row["left"] = dict(sorted(row["left"].items()))
    return dict(sorted(rows.items(), key=lambda kv: (-(kv[1]["placed"] - kv[1]["removed"]),
                                                     -(kv[1]["grasps"] - kv[1]["lifted"]), kv[0])))


#: The columns of :func:`failure_rows`.
FAILURE_COLUMNS = ("object", "placed", "removed", "grasps", "lifted", "failed grasps", "left on the table")


def failure_rows(table: dict) -> list[tuple]:
    """Rows of :data:`FAILURE_COLUMNS` from a :func:`per_object` table (what the CLI and
    E10 print)."""
    def causes(d: dict) -> str:
        return ", ".join(f"{k} {v}" for k, v in d.items()) or "-"

    return [(name, r["placed"], r["removed"], r["grasps"], r["lifted"], causes(r["failed"]), causes(r["left"]))
            for name, r in table.items()]


def summarize(results: list[ClutterResult]) -> dict:
    """Pooled metrics of episodes: grasp success rate (successes / attempts), cleared
    rate (objects removed / placed), grasps that lifted another object than their
    target (``other_objects``, not successes), scenes cleared, stops, failure causes,
    planning seconds per grasp (count, mean, median, max; of the episodes' first frames
    and of later frames, which may reuse plans, apart; median per stage of
    ``plan_scene``), segmentation quality of the first frames
    (objects seen, segmented as one cluster), and the failure table per object
    (:func:`per_object`)."""
    attempts = [a for r in results for a in r.attempts]
    ok = sum(a.success for a in attempts)
    placed, removed = sum(r.placed for r in results), sum(r.removed for r in results)
    causes: dict[str, int] = {}
    for a in attempts:
        if not a.success:
            causes[a.cause] = causes.get(a.cause, 0) + 1
    seen, one = sum(r.first_seen for r in results), sum(r.first_one_cluster for r in results)
    stages = sorted({k for a in attempts for k in a.timing})
    medians = {k: float(np.median([a.timing.get(k, 0.0) for a in attempts])) for k in stages}
    first = [r.attempts[0].planning for r in results if r.attempts]
    later = [a.planning for r in results for a in r.attempts[1:]]
    return {"scenes": len(results), "attempts": len(attempts), "successes": ok,
            "other_objects": sum(a.cause == OTHER for a in attempts),
            "grasp_success_rate": ok / len(attempts) if attempts else None,
            "placed": placed, "removed": removed, "cleared_rate": removed / placed if placed else None,
            "scenes_cleared": sum(r.removed == r.placed for r in results),
            "stops": {s: sum(r.stop == s for r in results) for s in STOPS},
            "failure_causes": dict(sorted(causes.items())),
            "planning_s": {**_spread([a.planning for a in attempts]), "stages_median": medians,
                           "first_frame": _spread(first), "later_frames": _spread(later)},
            "segmentation": {"objects_seen": seen, "one_cluster": one,
                             "share": one / seen if seen else None},
            "per_object": per_object(results)}
