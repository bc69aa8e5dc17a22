"""Clutter removal: clear a table of several objects, one grasp at a time.

The benchmark of VGN, GPD and their successors, on a :class:`~graspsim.tabletop.table_scene.TableScene`:

    render a depth frame (one D435-like camera, sensor noise) -> back-project to the world
    -> :func:`~graspsim.planning.scene.plan_scene` (table, segments, every segment
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

from graspsim.checks import BOOLEAN, check_fields, integer, or_none
from graspsim.errors import InvalidParameterError
from graspsim.geometry.camera import Camera, backproject, rig
from graspsim.planning.scene import plan_scene
from graspsim.planning.scene_config import SceneConfig
from graspsim.planning.scene_reuse import drop_grasp, near_pose
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.trial_scene import SimSettings
from graspsim.tabletop.clutter_metrics import (
    ARM_STOPS,
    FAILURE_COLUMNS,
    LEFT,
    OTHER,
    STOPS,
    failure_rows,
    object_segmentation,
    one_cluster_objects,
    per_object,
    per_source,
    summarize,
)
from graspsim.tabletop.depth_noise import DepthNoise
from graspsim.tabletop.mesh_objects import BENCHMARK_SET
from graspsim.tabletop.planners import grasp_target
from graspsim.tabletop.table_scene import known_gap

__all__ = ["scene_settings", "ClutterRobot", "ClutterConfig", "Attempt", "ClutterResult", "ClutterFrame",
           "ClutterEpisode", "run_clutter", "run_benchmark", "benchmark_episode", "summarize", "one_cluster_objects",
           "object_segmentation",
           "per_object", "per_source", "failure_rows", "FAILURE_COLUMNS", "STOPS", "ARM_STOPS", "OTHER", "LEFT",
           "GOOD_ENOUGH"]

#: The robust score a clutter look stops planning further objects at (``ClutterConfig.good_enough``):
#: a grasp that at most one in ten of the sampled execution errors makes fail. Set before any
#: clutter run measured it (not tuned).
GOOD_ENOUGH = 0.9


def scene_settings(kind: str, **kw) -> SceneConfig:
    """``SceneConfig(**kw)`` for planning scenes of ``kind`` made by
    :func:`~graspsim.tabletop.table_scene.make_scene`, with the least gap such scenes keep between
    objects as ``min_gap`` (packed: 1 cm; piles: none, :func:`~graspsim.tabletop.table_scene.known_gap`):
    what a user who placed the objects knows."""
    return SceneConfig(**{"min_gap": known_gap(kind), **kw})


@dataclass(frozen=True)
class ClutterRobot:
    """The arm that clears the table (``ClutterConfig.robot``): ``name`` (one of
    :data:`graspsim.robots.ARMS`) standing at ``base`` (x [m], y [m], yaw [rad] on the
    table top, the scene's objects lying around the origin); each look, the ranked grasps
    go through the arm's capability map (the first cut, all of them) and the best
    ``exact`` of those it lets through, in ranking order, through the exact check in the
    scene as it lies (:meth:`~graspsim.tabletop.scene_sim.SceneSim.plan_arm`) until one
    passes: that one is executed by the arm. ``capability``: the first cut's
    :class:`~graspsim.robots.CapabilityConfig` (None: the default) and ``cache_dir``
    its cache folder (None: the default; False: none)."""

    name: str = "panda"
    base: tuple = (-0.5, 0.0, 0.0)
    exact: int = 10
    capability: object = None
    cache_dir: object = None

    def __post_init__(self) -> None:
        from graspsim.robots.arm import base_transform, get_arm

        get_arm(self.name)
        base_transform(self.base)
        object.__setattr__(self, "base", tuple(float(v) for v in np.asarray(self.base, float).reshape(-1)))
        check_fields(self, integer(1), "exact", owner="ClutterRobot")

    def to_dict(self) -> dict:
        from graspsim.robots.arm import base_transform, get_arm

        return {"robot": get_arm(self.name).to_dict(), "base": list(self.base),
                "T_world_base": base_transform(self.base).tolist(), "exact": self.exact}


@dataclass(frozen=True)
class ClutterConfig:
    """scene: the perception and planning settings; depth_noise: the sensor's (None: a
    perfect sensor); execution: the arm's pose error (None: none); ground_truth: segment
    by the render's object labels instead of clustering (ablation); max_failures:
    consecutive failed grasps that end an episode; max_attempts: grasps per episode at
    most (None: 2 x objects + 2); min_seen: points (after thinning) an object needs in
    a frame to count in the segmentation quality; reuse: a segment that did not change
    since the previous frame keeps its plan (``plan_scene(previous=...)``), less the
    grasp that was executed; planner: one of :mod:`graspsim.tabletop.planners` (its name in ``planner_name``);
    robot: the arm that executes the grasps (:class:`ClutterRobot`; None: the floating
    gripper), its gripper the database's (a model-file gripper); plan_for_execution: with
    an ``execution`` error, the planner's robust score assumes that error (its sigmas
    replace ``scene.planner.robust``'s: :attr:`planning`), so the grasps it ranks first are
    those that survive the arm the user stated; False: ``scene``'s own (3 mm / 2 deg by
    default, also when the arm has no error); good_enough: each look plans the objects
    highest first until one has a grasp whose robust score reaches this
    (``SceneConfig.good_enough``; the default :data:`GOOD_ENOUGH`), the others when a later
    look needs them -- one grasp is executed a look, and an object's plan is often
    outdated by the time its turn comes (a pile shifts); a look whose planned grasps are
    all spent (failed twins, or none the arm reaches) plans every object; None: every
    object every look (the clutter environment's candidates); feel: a grasp that started
    in collision with an object tells where something the camera did not see is (its
    finger volume in the camera's shadow, :func:`~graspsim.maps.occlusion.felt_volume`),
    and the next looks' plans keep clear of it (``plan_scene(felt=...)``) until an attempt
    changes the scene (any but a start collision, which leaves it as it was); False: a
    failed grasp only rules out grasps on its contacts. graspsim's planner only (a
    planner of :mod:`graspsim.tabletop.planners` is not told). sim: the simulation's
    settings (e.g. :func:`graspsim.sim.contact_model`'s ``"stiff"``) for the scenes
    :func:`run_benchmark` draws and settles and for every episode's simulation; None:
    ``SimSettings()``."""

    scene: SceneConfig = field(default_factory=SceneConfig)
    depth_noise: DepthNoise | None = field(default_factory=DepthNoise)
    execution: ExecutionNoise | None = None
    ground_truth: bool = False
    max_failures: int = 2
    max_attempts: int | None = None
    min_seen: int = 40
    reuse: bool = True
    planner: object = None  # a planner of graspsim.tabletop.planners' interface; None: plan_scene (with reuse)
    planner_name: str = "graspsim"
    robot: ClutterRobot | None = None
    plan_for_execution: bool = True
    good_enough: float | None = GOOD_ENOUGH
    feel: bool = True
    sim: SimSettings | None = None

    def __post_init__(self) -> None:
        replace(self.scene, good_enough=self.good_enough)  # validates it
        if self.sim is not None and not isinstance(self.sim, SimSettings):
            raise InvalidParameterError(f"ClutterConfig.sim must be SimSettings or None, got {type(self.sim).__name__}")
        check_fields(self, integer(1), "max_failures", "min_seen", owner="ClutterConfig")
        check_fields(self, BOOLEAN, "plan_for_execution", "feel", owner="ClutterConfig")
        check_fields(self, or_none(integer(1)), "max_attempts", owner="ClutterConfig")

    @property
    def planning(self) -> SceneConfig:
        """The scene settings ``plan_scene`` runs with: ``scene`` with ``good_enough``, its
        robust score's pose error the ``execution`` error's where one is given and
        ``plan_for_execution``."""
        scene = replace(self.scene, good_enough=self.good_enough)
        if self.execution is None or not self.plan_for_execution:
            return scene
        robust = replace(scene.planner.robust, position_sigma=float(self.execution.position_sigma),
                         rotation_sigma=float(self.execution.rotation_sigma))
        return replace(scene, planner=replace(scene.planner, robust=robust))

    def to_dict(self) -> dict:
        return {"scene": self.scene.to_dict(), "depth_noise": None if self.depth_noise is None
                else self.depth_noise.to_dict(), "execution": None if self.execution is None
                else self.execution.to_dict(), "ground_truth": self.ground_truth,
                "max_failures": self.max_failures, "max_attempts": self.max_attempts, "min_seen": self.min_seen,
                "reuse": self.reuse, "planner": self.planner_name, "plan_for_execution": self.plan_for_execution,
                "good_enough": self.good_enough, "feel": self.feel,
                **({} if self.sim is None else {"sim": self.sim.to_dict()}),
                "robust_sigma": [self.planning.planner.robust.position_sigma,
                                 self.planning.planner.robust.rotation_sigma],
                **({} if self.robot is None else {"robot": self.robot.to_dict()})}


@dataclass(frozen=True)
class Attempt:
    """One executed grasp: target (the object the chosen segment is mostly of, ground
    truth), outcome (:meth:`SceneOutcome.to_dict`), success (the target lifted), cause
    (``success_other_object``: another object came up; not a success), score (robust),
    planning [s] (depth frame to ranked grasps; ``timing`` per stage), segments found,
    objects seen, and of those segmented as one cluster; reach (with an arm): what the
    look's reachability check found (:meth:`ClutterEpisode.observe`); between: the points
    of the grasp's segment in its closing region at the pose and opening executed
    (:meth:`~graspsim.grippers.spec.GripperSpec.points_between`, what
    ``PlannerConfig.seen_between`` asks of a plan; None with an external planner); source: what
    the grasp was planned from (:attr:`SceneGrasp.source <graspsim.planning.scene.SceneGrasp.source>`:
    a part's primitive or ``"features"``; None with an external planner)."""

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
    reach: dict | None = None
    between: int | None = None
    source: str | None = None

    def to_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in ("reach", "between", "source") or v is not None}




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
    robot: dict | None = None  # the arm and its base (ClutterRobot.to_dict); None: the floating gripper

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
                "steps": [a.to_dict() for a in self.attempts],
                **({} if self.robot is None else {"robot": self.robot})}


@dataclass(frozen=True, eq=False)
class ClutterFrame:
    """What one look at the scene gives: the depth ``frame`` (colour too when asked),
    its back-projected ``view``, the :class:`~graspsim.planning.scene.ScenePlan`
    ``plan``, ``planning`` [s] (depth frame to ranked grasps), of the objects seen
    (ground truth) those segmented as one cluster; ``candidates``: the plan's grasps in
    ranking order less those closing on a failed grasp's contacts (not tried again), and
    ``best``: the first of them with a robust score > 0 (None: none), what the protocol
    executes; with an arm (``ClutterConfig.robot``), the first the arm reaches, its plan
    ``arm_plan``, and ``reach`` what the check found of the candidates (how many, how many
    the first cut let through, those the exact check refused with their rank, cause and
    stage, the one chosen, the seconds the check took)."""

    frame: object
    view: object
    plan: object
    planning: float
    seen: int
    one_cluster: int
    candidates: tuple = ()
    best: object = None
    arm_plan: object = None  # with an arm: the plan of ``best`` (graspsim.robots.execute.ArmPlan)
    reach: dict | None = None  # with an arm: what the reachability check found


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
        self._planning = cfg.planning  # the planner told the arm's error (ClutterConfig.plan_for_execution)
        self.scene, self.db, self.rgb = scene, db, rgb
        self.camera = camera or rig(1)[0]
        self.cap = cfg.max_attempts or 2 * len(scene.objects) + 2
        self._t0 = time.perf_counter()
        # the database's gripper executes what was planned for it (the default gripper: scene.sim()'s own)
        grip = {} if db is None else {"gripper": db.gripper}
        if cfg.sim is not None:
            grip["settings"] = cfg.sim
        self.sim = scene.sim(**grip) if cfg.robot is None else scene.sim(
            **grip, robot=_arm(cfg.robot), base=cfg.robot.base)
        self._depth_rng, self._plan_rng, self._exec_rng = rng.spawn(3)
        self.attempts: list[Attempt] = []
        self.failures = 0
        self.first: tuple[int, int] | None = None
        self.last: ClutterFrame | None = None  # the latest look, also when it found no grasp
        self._previous = None  # the plan the next look may reuse (ClutterConfig.reuse)
        self.failed: list[np.ndarray] = []  # wrist poses of the episode's failed grasps
        self.felt = np.zeros((0, 3))  # where grasps that started in collision met something unseen (ClutterConfig.feel)
        self.reach = float(db.gripper.fingertip_z) if db is not None else 0.0  # wrist to fingertips [m]
        self.stop: str | None = None if self.sim.objects_left() else "cleared"

    def render(self):
        """A depth frame of the scene now (the sensor's noise drawn from the episode)."""
        return self.sim.render(self.camera, noise=self.config.depth_noise, rng=self._depth_rng, rgb=self.rgb)

    def observe(self) -> ClutterFrame | None:
        """Render and plan the scene; None (and ``stop`` = "no_grasp") when no grasp left
        to try has a robust score > 0 (``last`` holds that look all the same). With a planner
        of :mod:`graspsim.tabletop.planners`: its first proposal left to try (no segments)."""
        if self.stop is not None:
            raise InvalidParameterError(f"the episode has ended ({self.stop}); nothing to observe")
        cfg = self.config
        frame = self.render()
        if cfg.planner is not None:
            from graspsim.tabletop.planners import plan_frame

            view, sp, grasps, planning = plan_frame(cfg.planner, frame, self.db.gripper, self._plan_rng)
            cands, best = self._candidates(grasps, positive=False)
            seen, one = one_cluster_objects(view.labels, np.full(len(view.labels), -1), min_seen=cfg.min_seen)
        else:
            view, sp, cands, best, planning = self._plan(frame)
            per = sp.perception
            seen, one = one_cluster_objects(view.labels[per.indices], per.segment, min_seen=cfg.min_seen)
        if self.first is None:
            self.first = (seen, one)
        arm_plan = reach = None
        if cfg.robot is not None and best is not None:
            best, arm_plan, reach = self._reachable(cands, positive=cfg.planner is None)
            if best is None and cfg.planner is None and _deferred(sp):  # the arm reaches none planned: plan all
                t0 = time.perf_counter()
                sp, cands, best = self._plan_all(view, view.labels if cfg.ground_truth else None,
                                                 self.camera.T_world_camera[:3, 3])
                if best is not None:
                    best, arm_plan, reach = self._reachable(cands, positive=True)
                planning += time.perf_counter() - t0
        self.last = ClutterFrame(frame, view, sp, planning, seen, one, cands, best, arm_plan, reach)
        if best is None:
            self.stop = "no_grasp" if reach is None else "unreachable"
            return None
        return self.last

    def _reachable(self, cands, positive: bool):
        """The arm's choice among the candidates (with a robust score > 0 when
        ``positive``), best first: (grasp, its plan, what the check found) or (None,
        None, found) when it reaches none (:class:`ClutterRobot`). A grasp whose gripper
        is in an object or the table at the grasp pose (the floating gripper's start
        collision) is chosen as the floating gripper would: the check cannot make the
        planner's grasp better, only refuse what the arm cannot do."""
        from graspsim.sim.outcomes import TrialOutcome

        robot, t0 = self.config.robot, time.perf_counter()
        pool = [g for g in cands if g.score > 0 or not positive]
        T = np.array([g.T_world_wrist for g in pool], float).reshape(-1, 4, 4)
        ok, seeds = self.sim.reach_first_cut(T, config=robot.capability, cache_dir=robot.cache_dir)
        found = {"candidates": len(pool), "first_cut": int(ok.sum()), "checked": 0, "refused": []}
        for i in np.flatnonzero(ok)[:robot.exact]:
            plan = self.sim.plan_arm(T[i], pool[i].opening, seeds[i])
            found["checked"] += 1
            if plan.outcome is None or plan.outcome is TrialOutcome.START_COLLISION:
                found.update(chosen=int(i), seconds=time.perf_counter() - t0)
                return pool[i], plan, found
            found["refused"].append({"rank": int(i), "cause": plan.outcome.label, "stage": plan.stage,
                                     "reach": plan.check.reach.label})
        found["seconds"] = time.perf_counter() - t0
        return None, None, found

    def _plan(self, frame):
        """graspsim's scene planner on ``frame``: (view, plan, candidates, best, seconds)."""
        cfg = self.config
        t1 = time.perf_counter()  # planning: from the depth image to ranked grasps
        view = backproject(frame)
        labels = view.labels if cfg.ground_truth else None
        eye = self.camera.T_world_camera[:3, 3]  # the occluded space behind what the camera saw
        sp = plan_scene(view.world(), db=self.db, rng=self._plan_rng, config=self._planning, labels=labels,
                        previous=self._previous, viewpoint=eye, felt=self._felt())
        cands, best = self._candidates(sp.grasps)
        if best is None and (self._previous is not None or _deferred(sp)):
            sp, cands, best = self._plan_all(view, labels, eye)
        return view, sp, cands, best, time.perf_counter() - t1

    def _plan_all(self, view, labels, eye):
        """The frame planned afresh, every segment (reused plans kept scores from before,
        and deferred segments were not planned): (plan, candidates, best)."""
        sp = plan_scene(view.world(), db=self.db, rng=self._plan_rng, config=replace(self._planning, good_enough=None),
                        labels=labels, viewpoint=eye, felt=self._felt())
        cands, best = self._candidates(sp.grasps)
        return sp, cands, best

    def _candidates(self, grasps, positive: bool = True) -> tuple[tuple, object]:
        """The ``grasps`` (a plan's) still to try, in ranking order, and the first of them
        with a robust score > 0 (``positive``; else the first) or None. A grasp that failed
        is not tried again, nor any that closes on its contacts (:func:`~graspsim.planning.
        scene_reuse.near_pose` at the fingertips: the other approaches of a contact pair
        fail the same way; a start collision leaves the scene as it was)."""
        cands = tuple(g for g in grasps
                      if not any(near_pose(T, g.T_world_wrist, reach=self.reach) for T in self.failed))
        return cands, next((g for g in cands if g.score > 0 or not positive), None)

    def execute(self, look: ClutterFrame, grasp) -> Attempt:
        """Execute ``grasp`` (a :class:`~graspsim.planning.scene.SceneGrasp` of
        ``look.plan``) with the configured execution error, then apply the stopping rules."""
        if self.stop is not None:
            raise InvalidParameterError(f"the episode has ended ({self.stop}); no more grasps")
        cfg = self.config
        sp, external = look.plan, cfg.planner is not None
        target = grasp_target(look, grasp, self.db.gripper if self.db is not None else None)
        arm = {} if cfg.robot is None else {"plan": look.arm_plan if grasp is look.best else None}
        out = self.sim.execute(grasp.T_world_wrist, grasp.opening, target=target, noise=cfg.execution,
                               rng=self._exec_rng if cfg.execution is not None else None, **arm)
        if cfg.reuse and not external:  # the executed grasp is not offered again
            self._previous = replace(sp, memory=drop_grasp(sp.memory, grasp.T_world_wrist, reach=self.reach))
        hit = out.success and out.picked == target  # the target came up (None: unknown target)
        cause = OTHER if out.success and not hit else out.cause
        gripper = self.db.gripper if self.db is not None else None  # the planner's (the simulated one too)
        between = None if external or gripper is None else int(gripper.points_between(
            np.asarray(grasp.T_world_wrist, float)[None], np.array([grasp.opening]),
            sp.perception.segment_points(grasp.segment))[0])
        a = Attempt(target, out.to_dict(), hit, cause, grasp.score, look.planning, {} if external else sp.timing,
                    0 if external else sp.perception.n_segments, look.seen, look.one_cluster,
                    look.reach if grasp is look.best else None, between,
                    None if external else getattr(grasp, "source", None))  # a stand-in grasp may lack it
        self.attempts.append(a)
        # a grasp that lifted another object is no success, but the scene changed: no failure in a row
        self.failures = 0 if out.success else self.failures + 1
        if not out.success:
            self.failed.append(np.asarray(grasp.T_world_wrist, float))
        if cfg.feel and not external:
            self._feel(look, grasp, out)
        if self.failures >= cfg.max_failures:
            self.stop = "failures"
        elif not self.sim.objects_left():
            self.stop = "cleared"
        elif len(self.attempts) >= self.cap:
            self.stop = "max_attempts"
        return a

    def _felt(self) -> np.ndarray | None:
        return self.felt if self.config.feel and len(self.felt) else None

    def _feel(self, look: ClutterFrame, grasp, out) -> None:
        """``ClutterConfig.feel``: a start collision with an object adds the finger volume
        the look's camera did not see, at the pose executed, to ``felt``; any attempt but a
        start collision changed the scene, and clears it."""
        if not out.cause.startswith("start_collision"):
            self.felt = np.zeros((0, 3))
            return
        if out.cause == "start_collision_table":  # the table is known: nothing unseen was met
            return
        from graspsim.maps.occlusion import ViewDepth, felt_volume

        per, table = look.plan.perception, look.plan.table
        if len(per.points) < 3:
            return
        view = ViewDepth(per.points, self.camera.T_world_camera[:3, 3])
        T = np.asarray(out.extra.get("T_world_wrist", grasp.T_world_wrist), float)
        opening = float(out.extra.get("opening", grasp.opening))
        got = felt_volume(self.sim.gripper, T, opening, view,
                          None if table.height is None else (np.asarray(table.normal, float), float(table.height)))
        self.felt = np.concatenate([self.felt, got])

    @property
    def removed(self) -> int:
        return len(self.scene.objects) - len(self.sim.objects_left())

    def left_reasons(self) -> dict[int, str]:
        """Why each object left on the table is there, judged on the last look
        (:data:`LEFT`): off the table (knocked beyond it), not seen (fewer than
        ``min_seen`` points), merged with another object or split (by
        :func:`object_segmentation`), one cluster but no grasp with a robust score > 0
        planned on its segment (no_grasp), its planned grasps all closing on the contacts
        of a grasp that failed, so not tried again (excluded), or one left to try that was
        not tried before the episode stopped (not_tried). With a planner of
        :mod:`graspsim.tabletop.planners` (no segments) a seen object is not_tried when a grasp left to try aims at it
        (:func:`~graspsim.tabletop.planners.grasp_target`), else no_grasp."""
        look, out = self.last, {}
        gripper = self.db.gripper if self.db is not None else None
        off = set(self.sim.outside())
        for k in self.sim.objects_left():
            if k in off:
                out[k] = "off_table"
                continue
            if look is None:
                out[k] = "not_seen"
                continue
            if self.config.planner is not None:
                seen = int(np.sum(look.view.labels == k)) >= self.config.min_seen
                aimed = any(grasp_target(look, g, gripper) == k for g in look.candidates)
                tried = "unreachable" if self.stop == "unreachable" else "not_tried"
                out[k] = "not_seen" if not seen else tried if aimed else "no_grasp"
                continue
            per = look.plan.perception
            how, seg = object_segmentation(look.view.labels[per.indices], per.segment, k,
                                           min_seen=self.config.min_seen)
            if how != "one":
                out[k] = how
            elif any(g.segment == seg and g.score > 0 for g in look.candidates) or \
                    look.plan.segments[seg].status == "deferred":  # deferred: not planned yet, so not tried
                out[k] = "unreachable" if self.stop == "unreachable" else "not_tried"
            else:  # planned grasps that all close on a failed grasp's contacts are not "none planned"
                out[k] = "excluded" if any(g.segment == seg and g.score > 0 for g in look.plan.grasps) \
                    else "no_grasp"
        return out

    def result(self) -> ClutterResult:
        first = self.first or (0, 0)
        robot = self.config.robot
        return ClutterResult(len(self.scene.objects), tuple(self.attempts), self.removed, self.stop or "max_attempts",
                             first[0], first[1], time.perf_counter() - self._t0,
                             tuple(o.name for o in self.scene.objects), self.left_reasons(),
                             None if robot is None else robot.to_dict())

    def close(self) -> None:
        """Free the renderer (the simulation stays readable)."""
        self.sim.close()


def _deferred(plan) -> bool:
    """Whether a scene plan left segments unplanned (``SceneConfig.good_enough``)."""
    return any(p.status == "deferred" for p in plan.segments)


def _arm(robot: ClutterRobot):
    from graspsim.robots.arm import get_arm

    return get_arm(robot.name)


def run_clutter(scene, *, db, rng: np.random.Generator, config: ClutterConfig | None = None,
                camera: Camera | None = None, on_step=None) -> ClutterResult:
    """One clutter-removal episode on ``scene`` (a :class:`~graspsim.tabletop.table_scene.TableScene`)
    seen by ``camera`` (default: one D435-like camera, ``rig(1)``), planning against the
    :class:`~graspsim.maps.database.MapDatabase` ``db``, executing the best grasp each
    time (:class:`ClutterEpisode`). Deterministic given ``rng``.
    on_step(view, frame, plan, attempt): called after each executed grasp with the
    back-projected view, the depth frame (colour rendered too), the ScenePlan and the
    Attempt (e.g. to draw it: :func:`~graspsim.tabletop.clutter_figure.save_step_figure`)."""
    return _play(ClutterEpisode(scene, db=db, rng=rng, config=config, camera=camera, rgb=on_step is not None), on_step)


def _play(ep: ClutterEpisode, on_step=None) -> ClutterResult:
    """Episode ``ep`` played to its end, the best grasp executed at each look (:func:`run_clutter`)."""
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
                  object_set: str = BENCHMARK_SET, first: int = 0, on_step=None, on_scene=None) -> list[ClutterResult]:
    """``scenes`` episodes on scenes ``first``, ``first + 1``, ... of ``n_objects`` of
    ``kind`` ("pile" | "packed") from ``object_set`` (by default the benchmark's,
    :data:`~graspsim.tabletop.mesh_objects.BENCHMARK_SET`: the shipped real meshes, as ``graspsim scene``).
    Scene ``i`` is ``make_scene(n_objects, kind, derived_seed(seed, "scene", i))`` and its
    episode draws from ``rng_for(seed, "clutter", i)``: every condition (noise,
    ablation) meets the same scenes and the same draws. on_step(i, view, frame, plan,
    attempt) as :func:`run_clutter`'s; on_scene(i, scene, result) after each episode."""
    if isinstance(scenes, bool) or not isinstance(scenes, int) or scenes < 1:
        raise InvalidParameterError(f"scenes must be a whole number >= 1, got {scenes!r}")
    out = []
    for i in range(first, first + scenes):
        ep = benchmark_episode(n_objects, kind, seed, i, db=db, config=config, object_set=object_set,
                               rgb=on_step is not None)
        step = None if on_step is None else (lambda *a, i=i: on_step(i, *a))
        r = _play(ep, step)
        out.append(r)
        if on_scene is not None:
            on_scene(i, ep.scene, r)
    return out


def benchmark_episode(n_objects: int, kind: str, seed: int, i: int, *, db, config: ClutterConfig | None = None,
                      object_set: str = BENCHMARK_SET, rgb: bool = False) -> ClutterEpisode:
    """Episode ``i`` of :func:`run_benchmark` with ``seed``, not yet played: its scene drawn and
    settled, its draws from ``rng_for(seed, "clutter", i)`` -- a caller that walks it look by
    look (a study replaying a benchmark's episodes) meets what the benchmark met."""
    from graspsim.seeding import derived_seed, rng_for
    from graspsim.tabletop.table_scene import make_scene

    scene = make_scene(n_objects, kind, derived_seed(seed, "scene", i), object_set=object_set,
                       gripper=db.gripper, **({} if config is None or config.sim is None
                                              else {"settings": config.sim}))
    return ClutterEpisode(scene, db=db, rng=rng_for(seed, "clutter", i), config=config, rgb=rgb)
