"""Planning effort per segment against clutter removal (issue 17): what smaller
per-segment budgets save in CPU and what they cost in grasps.

A scene plans each segment until ``SceneConfig.enough`` of its grasps score above 0 or
``SceneConfig.per_segment`` grasps per part have been robust-scored (E10's budget:
32 and 200). Smaller budgets plan less of each segment's maps, so a first frame costs
less CPU, but the scene's best grasp is chosen from fewer candidates. For each budget
(``ENOUGH:PER_SEGMENT``) this runs E10's goal conditions -- ``--objects`` objects, pile
and packed, no execution error -- with E10's protocol, seeds, camera, sensor noise and
database (``e10_clutter_removal.py``) on scenes ``--first`` onwards: by default E10's
next 50, so that a budget chosen here is not chosen on the scenes E10 reports
(``--first 0`` with E10's budget reproduces E10's rows). Per budget it reports the
grasp success rate and objects cleared (95 % Wilson intervals; against the first
budget, paired scene-bootstrap intervals of the differences), the scenes whose
episode differs from the first budget's, and of a scene's first frame the grasps
scored and the CPU time of planning it (``plan_scene``), and the CPU per grasp.
Scenes run one per task on ``--workers`` processes, the budgets interleaved, so every
budget meets the same load; before each scene a worker forgets the objects it has
seen (per-process caches by dimensions), so every first frame is planned as a new frame;
inside a worker a scene's segments are planned one after another, so the CPU is the
whole plan's (on 2 cores the wall time of a first frame is
at least about half of it: ``bench_scene.py`` measures that).

    python experiments/study_scene_budget.py --db results/e10-fsdb --workers 2
    python experiments/study_scene_budget.py --quick --out results/study_scene_budget-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    derived_seed,
    experiment_database,
    map_config,
    opt,
    rate_ci,
    resident_run_database,
    rng_for,
    start,
    task_results,
)

from graspsim.planning.scene_config import budget_fields

log = logging.getLogger("study_scene_budget")


@dataclass(frozen=True)
class Config:
    budgets: tuple[str, ...] = opt(("32:200", "16:200", "8:100"),
                                   "per-segment budgets ENOUGH:PER_SEGMENT (SceneConfig.enough, .per_segment); "
                                   "the first is the reference the others are compared with")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    objects: int = opt(5, "objects per scene")
    scenes: int = opt(50, "scenes per kind")
    first: int = opt(50, "first scene index (E10 runs 0 .. 49: by default a budget is judged on other scenes "
                     "than the ones E10 reports)")
    object_set: str = opt("mixed", "objects drawn from this set")
    seed: int = opt(0, "run seed (E10's)")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder, read only during the run (default: OUT/fsdb, built fresh)")
    grid: bool = opt(True, "store E10's size grid of FS maps in the database before the first scene")
    workers: int = opt(1, "processes; results do not depend on it")
    QUICK: ClassVar[dict] = {"budgets": ("32:200", "4:50"), "kinds": ("packed",), "objects": 2, "scenes": 1,
                             "object_set": "primitives", "quick_maps": True, "grid": False}

    def __post_init__(self) -> None:
        if "" in self.budgets:
            raise ValueError("--budgets: each is ENOUGH:PER_SEGMENT")
        for b in self.budgets:
            budget_fields(b)
        if len(set(self.budgets)) != len(self.budgets) or not self.budgets:
            raise ValueError(f"--budgets must be distinct and not empty, got {self.budgets}")
        if self.objects < 1 or self.scenes < 1 or self.workers < 1 or self.first < 0:
            raise ValueError("--objects, --scenes and --workers must be >= 1, --first >= 0")


_PLANS: list[tuple[float, int]] = []  # this worker's plan_scene calls in order: (CPU seconds, grasps scored)


def _timed_plans() -> None:
    """Record the CPU time and the grasps robust-scored of every ``plan_scene`` the
    clutter protocol calls in this process (the protocol's own call, wrapped once;
    results unchanged)."""
    import graspsim.tabletop.clutter as clutter

    if getattr(clutter.plan_scene, "_timed", False):
        return
    plan = clutter.plan_scene

    def timed(*args, **kwargs):
        c0 = time.process_time()
        sp = plan(*args, **kwargs)
        _PLANS.append((time.process_time() - c0, sum(p.scored for p in sp.segments)))
        return sp

    timed._timed = True
    clutter.plan_scene = timed


def _warm_up(kind: str, cfg: Config, db) -> None:
    """Plan the first frame of a scene no task draws, once per process and kind: the
    kernels, modules and stored maps are loaded before the first timed plan."""
    from graspsim.tabletop.clutter import ClutterEpisode
    from graspsim.tabletop.table_scene import make_scene

    scene = make_scene(cfg.objects, kind, derived_seed(cfg.seed, "warm-up", 0), object_set=cfg.object_set,
                       gripper=db.gripper)
    ep = ClutterEpisode(scene, db=db, rng=rng_for(cfg.seed, "warm-up", 0))
    try:
        ep.observe()
    finally:
        ep.close()


_WARM: set = set()


def _forget_objects() -> None:
    """Empty this process's caches of objects by their dimensions (collision sample
    hierarchies, surface points, feature contexts): every scene's first frame is then
    planned as a new frame (another budget's episode of the same scene may have run
    here just before)."""
    from graspsim.grades import grade_features
    from graspsim.maps import _robust_geometry, hierarchy

    hierarchy.clear_caches()
    _robust_geometry._primitive_points.cache_clear()
    grade_features._context.cache_clear()


def episode(task) -> dict:
    """Scene ``i`` of ``kind`` cleared with budget ``budget`` (E10's protocol and seeds)."""
    kind, budget, i, cfg, root = task

    from graspsim.errors import SimulationError
    from graspsim.tabletop.clutter import ClutterConfig, run_benchmark, scene_settings

    db = resident_run_database(root, cfg.quick_maps)
    if kind not in _WARM:
        _warm_up(kind, cfg, db)
        _WARM.add(kind)
    _timed_plans()
    config = ClutterConfig(scene=scene_settings(kind, **budget_fields(budget)))
    _forget_objects()
    _PLANS.clear()
    db.built = set()
    try:
        (r,) = run_benchmark(cfg.objects, kind, 1, cfg.seed, db=db, config=config, object_set=cfg.object_set,
                             first=i)
    except SimulationError as err:  # a scene that does not settle: skipped for every budget, as E10 does
        log.warning("%s scene %d skipped: %s", kind, i, err)
        return {"kind": kind, "budget": budget, "scene": i, "skipped": str(err)}
    return {"kind": kind, "budget": budget, "scene": i, "skipped": None, "placed": r.placed, "removed": r.removed,
            "attempts": len(r.attempts), "successes": r.successes, "stop": r.stop,
            "causes": [a.cause for a in r.attempts], "scores": [a.score for a in r.attempts],
            "plan_cpu_s": [c for c, _ in _PLANS], "scored": [n for _, n in _PLANS],
            "planning_s": [a.planning for a in r.attempts], "built_in_memory": sorted(db.built)}


def summarize(cfg: Config, episodes: list[dict]) -> list[dict]:
    """One row per kind and budget: pooled rates, CPU medians, scenes that differ from
    the reference budget's episode (the attempts' causes in order)."""
    from graspsim.stats import wilson_interval

    rows = []
    for kind in cfg.kinds:
        # a scene skipped under any budget (it did not settle) is left out of every budget's row
        skipped = {e["scene"] for e in episodes if e["kind"] == kind and e.get("skipped")}
        ran = [e for e in episodes if e["kind"] == kind and e["scene"] not in skipped]
        ref = {e["scene"]: e["causes"] for e in ran if e["budget"] == cfg.budgets[0]}
        for budget in cfg.budgets:
            eps = sorted((e for e in ran if e["budget"] == budget), key=lambda e: e["scene"])
            n, ok = sum(e["attempts"] for e in eps), sum(e["successes"] for e in eps)
            placed, removed = sum(e["placed"] for e in eps), sum(e["removed"] for e in eps)
            first = [e["plan_cpu_s"][0] for e in eps if e["plan_cpu_s"]]
            per_grasp = [sum(e["plan_cpu_s"]) / e["attempts"] for e in eps if e["attempts"]]
            scores = [e["scores"][0] for e in eps if e["scores"]]
            scored = [e["scored"][0] for e in eps if e["scored"]]
            rows.append({
                "kind": kind, "budget": budget, **budget_fields(budget), "scenes": len(eps),
                "skipped_scenes": sorted(skipped), "attempts": n,
                "successes": ok,
                "gsr_interval_95": wilson_interval(ok, n) if n else None, "placed": placed, "removed": removed,
                "cleared_interval_95": wilson_interval(removed, placed) if placed else None,
                "scenes_cleared": sum(e["removed"] == e["placed"] for e in eps),
                "differs_from_reference": sum(e["causes"] != ref.get(e["scene"]) for e in eps),
                "first_frame_cpu_s": _spread(first), "cpu_per_grasp_s": _spread(per_grasp),
                "first_frame_scored": _spread(scored),
                "scenes_building_maps": sum(bool(e["built_in_memory"]) for e in eps),
                "first_score_median": statistics.median(scores) if scores else None})
    return rows


def _spread(values: list[float]) -> dict:
    if not values:
        return {"count": 0, "median": None, "p90": None}
    v = sorted(values)
    return {"count": len(v), "median": statistics.median(v), "p90": v[min(len(v) - 1, int(0.9 * len(v)))]}


def _s(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def readme_section(s: dict) -> str:
    ref = s["config"]["budgets"][0]
    c = s["config"]
    L = [f"`{s['command']}`: E10's goal conditions ({c['objects']} objects, no execution error, its seeds, "
         f"camera, sensor noise and database; scenes {c['first']} to {c['first'] + c['scenes'] - 1}"
         f"; E10 reports scenes 0 to {s['e10_scenes'] - 1}) cleared with each per-segment budget "
         "ENOUGH:PER_SEGMENT (`SceneConfig.enough`: a segment's planning stops at this many grasps scoring > 0; "
         f"`.per_segment`: grasps robust-scored per part at most; E10's is {s['e10_budget']}). "
         "GSR = grasps that lifted their target / grasps, DR = objects removed / placed (95 % Wilson "
         "intervals; the differences below the table: 95 % intervals from resampling whole scenes, the same "
         f"draw for both budgets); *differ*: scenes whose episode (the attempts' outcomes in order) is not {ref}'s; "
         "CPU: `plan_scene`'s CPU time, a scene's segments planned one after another in one process (on 2 "
         "cores a first frame's wall time is at least about half its CPU); each process planned one other "
         "scene of each kind first, untimed, and forgot the objects it had seen before each scene (a new "
         "frame); as in E10, a part no stored map serves gets an FS map built in memory, in its plan's CPU "
         "(*builds*: scenes where that happened); *scored*: grasps robust-scored in a scene's first frame "
         "(median); best score: the robust score of the first grasp executed "
         f"(median over scenes); {s['config']['workers']} processes on {s['machine']['cpus']} cores.", "",
         "| scene | budget | scenes | GSR | DR | cleared scenes | differ | CPU, first frame: median / p90 [s] | "
         "CPU per grasp: median [s] | builds | scored | best score |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in s["rows"]:
        f, g = r["first_frame_cpu_s"], r["cpu_per_grasp_s"]
        L.append(f"| {r['kind']} | {r['budget']} | {r['scenes']} | "
                 f"{rate_ci(r['successes'], r['attempts'], r['gsr_interval_95'])} | "
                 f"{rate_ci(r['removed'], r['placed'], r['cleared_interval_95'])} | {r['scenes_cleared']} | "
                 f"{r['differs_from_reference']} | {_s(f['median'])} / {_s(f['p90'])} | {_s(g['median'])} | "
                 f"{r['scenes_building_maps']} | {r['first_frame_scored']['median']} | {_s(r['first_score_median'])} |")
    lost = {r["kind"]: r["skipped_scenes"] for r in s["rows"] if r.get("skipped_scenes")}
    if lost:
        L += ["", "Skipped (a simulation failed; left out of every budget's row): " + "; ".join(
            f"{kind} scenes {', '.join(map(str, sc))}" for kind, sc in lost.items()) + "."]
    return "\n".join(L + [""] + comparison(s["rows"], ref, s["episodes"], goals=c["objects"] == 5)) + "\n"


#: issue 17's goals for 5-object scenes, per kind: (GSR, DR) at least
GOALS = {"pile": (0.90, 0.90), "packed": (0.90, 0.95)}


def _paired(episodes: list[dict], kind: str, budget: str, ref: str) -> list[tuple[dict, dict]]:
    """(budget's episode, reference's episode) of every scene of ``kind`` no budget skipped."""
    mine = [e for e in episodes if e["kind"] == kind]
    skipped = {e["scene"] for e in mine if e.get("skipped")}
    ref_of = {e["scene"]: e for e in mine if e["budget"] == ref and e["scene"] not in skipped}
    return [(e, ref_of[e["scene"]]) for e in sorted(mine, key=lambda e: e["scene"])
            if e["budget"] == budget and e["scene"] in ref_of]


def _interval(pair: list[tuple[dict, dict]], k: str, n: str) -> str:
    """`` [lo, hi]`` in points: the paired scene-bootstrap interval of the difference."""
    if len(pair) < 2:
        return ""
    import numpy as np

    from graspsim.stats import paired_cluster_difference_interval

    lo, hi = paired_cluster_difference_interval([a[k] for a, _ in pair], [a[n] for a, _ in pair],
                                                [b[k] for _, b in pair], [b[n] for _, b in pair],
                                                np.random.default_rng(0))
    return f" [{100 * lo:+.1f}, {100 * hi:+.1f}]"


def _rate(r: dict, k: str, n: str) -> float | None:
    return r[k] / r[n] if r[n] else None


def comparison(rows: list[dict], ref: str, episodes: list[dict] = (), goals: bool = True) -> list[str]:
    """Each budget against the reference, per kind: the difference in points of GSR and DR,
    with a 95 % interval from resampling the scenes both ran (paired, whole scenes:
    grasps of one scene are correlated), and of first-frame CPU in %; with ``goals``
    (5-object scenes) which budgets meet :data:`GOALS` (point estimates)."""
    out, met = [], {}
    for kind in dict.fromkeys(r["kind"] for r in rows):
        mine = [r for r in rows if r["kind"] == kind]
        base = next((r for r in mine if r["budget"] == ref), None)
        goal = GOALS.get(kind)
        for r in mine:
            gsr, dr = _rate(r, "successes", "attempts"), _rate(r, "removed", "placed")
            if goal is not None and gsr is not None and dr is not None and gsr >= goal[0] and dr >= goal[1]:
                met.setdefault(kind, []).append(r["budget"])
            if base is None or r is base or None in (gsr, dr, _rate(base, "successes", "attempts")):
                continue
            c, c0 = r["first_frame_cpu_s"]["median"], base["first_frame_cpu_s"]["median"]
            cpu = "n/a" if not c or not c0 else f"{100 * (c / c0 - 1):+.0f} %"
            pair = _paired(episodes, kind, r["budget"], ref)
            out.append(f"- {kind}, {r['budget']} against {ref}: GSR "
                       f"{100 * (gsr - _rate(base, 'successes', 'attempts')):+.1f} points"
                       f"{_interval(pair, 'successes', 'attempts')}, DR "
                       f"{100 * (dr - _rate(base, 'removed', 'placed')):+.1f} points"
                       f"{_interval(pair, 'removed', 'placed')}, first-frame CPU {cpu}.")
    met_text = "; ".join(f"{kind} (GSR >= {100 * g[0]:.0f} %, DR >= {100 * g[1]:.0f} %): "
                         + (", ".join(met.get(kind, [])) or "none")
                         for kind, g in GOALS.items() if any(r["kind"] == kind for r in rows))
    if goals and met_text:
        out.append(f"- Budgets meeting issue 17's 5-object goals on these scenes (point estimates): {met_text}.")
    return out


def main(argv=None) -> int:
    from _common import build_grid

    cfg, out, record = start(Config, __file__, argv, __doc__)
    db = experiment_database(cfg.db, out, map_config(cfg.quick_maps))
    if cfg.grid:
        build_grid(db)  # E10's maps, stored before the first scene (kept where stored already)
    # the budgets interleaved scene by scene: every budget meets the same load
    tasks = [(kind, b, i, cfg, str(db.root)) for i in range(cfg.first, cfg.first + cfg.scenes) for kind in cfg.kinds
             for b in cfg.budgets]
    episodes = list(task_results(episode, tasks, cfg.workers))
    from e10_clutter_removal import Config as E10Config

    from graspsim.planning.scene_config import SceneConfig

    e10 = SceneConfig()
    text = record.write(out, {"config": cfg, "e10_budget": e10.budget,
                              "e10_scenes": E10Config().scenes,
                              "rows": summarize(cfg, episodes), "episodes": episodes}, readme_section)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
