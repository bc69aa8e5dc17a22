"""Experiment E10: clutter removal on table-top scenes seen by a simulated depth camera.

For each condition -- object set, scene kind (pile: dropped and settled; packed: upright
side by side, >= 1 cm apart), objects per scene, execution error (none, or 3 mm / 2 deg) --
the script draws scenes (``graspsim.tabletop.table_scene.make_scene``; by default the shipped real
household meshes, their tuning part and their held-out third reported apart: see
``assets/objects/README.md``), renders each
with one D435-like depth camera (sensor noise on) and clears it grasp by grasp
(``graspsim.tabletop.clutter``): segment, plan every object, check grasps against the whole
scene, execute the best, remove the lifted object, render again; until the table is
clear, two grasps in a row failed or no grasp is found. With execution error the planner is
told it, as a user states their robot's accuracy (``ClutterConfig.plan_for_execution``, the
path of ``graspsim scene --noise``; ``graspsim plan-scene --pose-error`` for a real cloud):
its robust score draws the same 3 mm / 2 deg; without, it keeps that default as a margin.
Ablations (without execution
error): no neighbour check; the render's ground-truth segmentation instead of clustering;
no felt evidence (a grasp that started in collision with an object tells the next plans
nothing but its contacts: ``ClutterConfig.feel`` off).
Every condition meets the same scenes and the same random draws (paired).

As the clutter-removal literature reports it (GIGA, EdgeGraspNet): ``--seeds`` seeds of
``--scenes`` scenes each (the seeds of ``graspsim scene --seeds``:
``graspsim.tabletop.clutter_stats.benchmark_seeds``, ``--seed`` itself for one seed, else
``derived_seed(--seed, "seed", k)``), GSR and DR per seed and their mean +- standard
deviation over the seeds, beside GIGA's and EdgeGraspNet's published simulated numbers
(other simulators, grippers and object sets: a reference, not a like-for-like
comparison). The failure table per object (which object failed how often and why) is
in the summary and the README block.

Reports per condition: grasp success rate (GSR = lifts / grasps) and declutter rate
(DR = objects removed / placed) with 95 % Wilson intervals (grasps and objects of one
scene are correlated: the intervals understate the spread between scenes), scenes
cleared, failure causes, planning seconds per grasp, and the share of objects
segmented as one cluster in the first frame (planning times are a warm planner's: each
process plans one untimed frame first, :func:`_warm_up`). The summary is rewritten after every
scene, so a run cut short (Ctrl-C, or SIGTERM to the main process) still reports the
scenes it finished (``complete`` says whether every condition ran all it asked;
``--others N`` runs the goal conditions -- 5 objects, the full method -- first and N
scenes of the rest after them). The database is read only during the run: a size grid
of FS maps is stored in it before the first scene, so the first scene plans like the
last; a part no stored map serves gets a map built in memory, not stored.

    python experiments/e10_clutter_removal.py                 # 5 seeds x 20 scenes per condition
    python experiments/e10_clutter_removal.py --seeds 2 --scenes 5 --objects 5 --noise none --ablations none
    python experiments/e10_clutter_removal.py --quick --out results/e10-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import signal
import sys
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (
    RunDatabase,
    build_grid,
    database_record,
    derived_seed,
    experiment_database,
    map_config,
    opt,
    rate_ci,
    resident_run_database,
    rng_for,
    start,
)
from _e10_report import readme_section, rows_of

from graspsim.contacts import CONTACT_MODELS, DEFAULT_CONTACTS
from graspsim.errors import SimulationError
from graspsim.maps.robust import UNSEEN_MARGIN
from graspsim.planning.scene_config import (
    FEATURE_GRASPS,
    SceneConfig,
    with_feature_grasps,
    with_seen_between,
    with_shadow_depth,
    with_sparse_between,
    with_unseen_margin,
)
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.trial_scene import contact_settings
from graspsim.stats import wilson_interval
from graspsim.tabletop.clutter import ClutterConfig, run_benchmark, scene_settings, summarize
from graspsim.tabletop.clutter_stats import benchmark_seeds, per_seed
from graspsim.tabletop.scene_objects import prepare_objects

log = logging.getLogger("e10")
ABLATIONS = ("no_neighbours", "ground_truth", "no_feel")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(20, "scenes per condition and seed")
    seeds: int = opt(5, "seeds per condition (one: --seed; else seed k: derived_seed(--seed, 'seed', k)); "
                     "GSR and DR are reported "
                     "per seed and as mean +- std over them")
    object_sets: tuple[str, ...] = opt(("household-tuning", "household-heldout"),
                                       "object sets (reported apart): named sets or folders of meshes")
    others: int = opt(0, "scenes of the conditions outside the goals (other sizes, ablations), run after the "
                      "goal conditions (0: --scenes, all conditions together)")
    goal_objects: int = opt(5, "objects per scene of the goal conditions (--others does not cut them)")
    block: int = opt(2, "scenes of a condition in a row in the run's order (the summary is written after each scene)")
    objects: tuple[int, ...] = opt((5, 10), "objects per scene")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    noise: tuple[str, ...] = opt(("none", "default"), "execution error: none, default (3 mm / 2 deg)",
                                 choices=("none", "default"))
    ablations: tuple[str, ...] = opt(ABLATIONS, "ablations (without execution error; none: no ablation)",
                                     choices=(*ABLATIONS, "none"))
    ablation_objects: tuple[int, ...] = opt((5,), "objects per scene of the ablations")
    seed: int = opt(0, "run seed")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    grid: bool = opt(True, "store FS maps of a size grid (GRID) in the database before the first scene")
    workers: int = opt(1, "processes; results do not depend on it (the database is read only during the run)")
    unseen_margin: float | None = opt(None, "the robust score's margin [m] against an object's unseen back "
                                      "(graspsim scene --unseen-margin; alone: the measured UNSEEN_MARGIN; "
                                      "none: the scene planner's default)", const=UNSEEN_MARGIN)
    seen_between: int | None = opt(None, "the points of its own segment a grasp must close on (graspsim scene "
                                   "--seen-between; 0: off; none: the scene planner's default, the measured "
                                   "SEEN_BETWEEN)")
    sparse_between: int | None = opt(None, "a grasp closing on fewer of its segment's points keeps SPARSE_SHARE of "
                                     "its score (graspsim scene --sparse-between; 0: off; none: the scene planner's "
                                     "default, the measured SPARSE_BETWEEN)")
    shadow_depth: float | None = opt(None, "in piles, the depth [m] behind each neighbour's seen points, along the "
                                     "camera's rays, kept clear as an obstacle (graspsim scene --shadow-depth; 0: off; "
                                     "none: the scene planner's default, the measured SHADOW_DEPTH)")
    feature_grasps: str = opt("fallback", "where a segment's planning adds grasps on its cloud's own features "
                              "(graspsim scene --feature-grasps; SceneConfig.feature_grasps): fallback, the default, "
                              "on packed tables, and in a pile's frame whose parts give no grasp at all; apart: on "
                              "packed tables only", choices=FEATURE_GRASPS)
    plan_all: bool = opt(False, "plan every object at every look (graspsim scene --plan-all; default: the highest "
                         "first until a grasp's robust score reaches ClutterConfig.good_enough)")
    contacts: str = opt(DEFAULT_CONTACTS, "the simulation's contact model (graspsim.sim.contact_model; "
                        "ClutterConfig.sim): stiff, the default, or soft (the results published before it)",
                        choices=CONTACT_MODELS)
    QUICK: ClassVar[dict] = {"scenes": 1, "seeds": 1, "block": 1, "objects": (2,), "kinds": ("packed",),
                             "noise": ("none",), "ablations": ("ground_truth",), "ablation_objects": (2,),
                             "quick_maps": True, "grid": False, "object_sets": ("primitives",)}

    def __post_init__(self) -> None:
        from graspsim.tabletop.scene_objects import check_object_set

        if self.scenes < 1 or self.seeds < 1 or not self.object_sets:
            raise ValueError("--scenes and --seeds must be >= 1 and --object-sets not empty")
        for name in self.object_sets:
            check_object_set(name)
        scene = with_seen_between(with_unseen_margin(SceneConfig(), self.unseen_margin), self.seen_between)
        scene = with_shadow_depth(with_sparse_between(scene, self.sparse_between), self.shadow_depth)
        with_feature_grasps(scene, self.feature_grasps)  # bad values:
        # refused before the work


def conditions(cfg: Config) -> list[dict]:
    """Every condition: object set, kind, objects, noise label, ablation (None: the full method)."""
    out = []
    for o in cfg.object_sets:
        out += [{"object_set": o, "kind": k, "objects": n, "noise": z, "ablation": None}
                for k in cfg.kinds for n in cfg.objects for z in cfg.noise]
        out += [{"object_set": o, "kind": k, "objects": n, "noise": "none", "ablation": a}
                for a in cfg.ablations if a != "none" for k in cfg.kinds for n in cfg.ablation_objects]
    return out


def seed_of(cfg: Config, k: int) -> int:
    """The benchmark seed of seed index ``k``: ``graspsim scene --seeds``' rule
    (:func:`graspsim.tabletop.clutter_stats.benchmark_seeds`)."""
    return benchmark_seeds(cfg.seed, cfg.seeds)[k]


def _clutter_config(c: dict, unseen_margin: float | None = None, plan_all: bool = False,
                    contacts: str = DEFAULT_CONTACTS, seen_between: int | None = None,
                    feature_grasps: str | None = None, sparse_between: int | None = None,
                    shadow_depth: float | None = None) -> ClutterConfig:
    """A condition's clutter settings; ``unseen_margin`` [m]: ``Config.unseen_margin``
    (``graspsim scene --unseen-margin``'s path: :func:`~graspsim.planning.scene_config.with_unseen_margin`);
    ``seen_between``: ``Config.seen_between`` (``--seen-between``'s path:
    :func:`~graspsim.planning.scene_config.with_seen_between`); ``feature_grasps``: ``Config.feature_grasps``
    (``--feature-grasps``' path: :func:`~graspsim.planning.scene_config.with_feature_grasps`; None: the default);
    ``sparse_between``: ``Config.sparse_between`` (``--sparse-between``'s path:
    :func:`~graspsim.planning.scene_config.with_sparse_between`); ``shadow_depth``: ``Config.shadow_depth``
    (:func:`~graspsim.planning.scene_config.with_shadow_depth`);
    ``plan_all``: every object planned at every look (``graspsim scene --plan-all``); ``contacts``: the
    simulation's contact model (:func:`graspsim.sim.contact_model`; the default: ``SimSettings()``)."""
    scene = with_seen_between(with_unseen_margin(scene_settings(c["kind"], neighbours=c["ablation"] != "no_neighbours"),
                                                 unseen_margin), seen_between)
    scene = with_sparse_between(with_feature_grasps(scene, feature_grasps), sparse_between)
    scene = with_shadow_depth(scene, shadow_depth)
    return ClutterConfig(scene=scene,
                         execution=ExecutionNoise() if c["noise"] == "default" else None,
                         ground_truth=c["ablation"] == "ground_truth", feel=c["ablation"] != "no_feel",
                         **({"good_enough": None} if plan_all else {}),
                         sim=contact_settings(contacts))


def _row(c: dict, pairs: list) -> dict:
    """A condition's row from its (seed, ClutterResult) pairs; per seed GSR and DR and
    their mean +- std by :func:`graspsim.tabletop.clutter_stats.per_seed` (as ``graspsim
    scene --seeds`` and E15 report them)."""
    results = [r for _, r in pairs]
    s = summarize(results)
    by_seed: dict = {}
    for k, r in pairs:
        by_seed.setdefault(k, []).append(r)
    ps = per_seed(dict(sorted(by_seed.items())))
    gsr = wilson_interval(s["successes"], s["attempts"]) if s["attempts"] else None
    dr = wilson_interval(s["removed"], s["placed"]) if s["placed"] else None
    return {**c, **s, "gsr_interval_95": gsr, "cleared_interval_95": dr, "per_seed": ps["per_seed"],
            "gsr_over_seeds": ps["gsr"], "dr_over_seeds": ps["dr"],
            "episodes": [{"seed": k, "scene": i, **{key: v for key, v in r.to_dict().items() if key != "steps"},
                          "causes": [a.cause for a in r.attempts], "planning": [a.planning for a in r.attempts],
                          "scores": [round(a.score, 4) for a in r.attempts],  # the robust score of each grasp
                          "between": [a.between for a in r.attempts],  # its seen points between the pads
                          "sources": [a.source for a in r.attempts],  # what it was planned from
                          "targets": [None if a.target is None or a.target >= len(r.names) else r.names[a.target]
                                      for a in r.attempts]}  # the object it was aimed at (ground truth)
                         for i, (k, r) in enumerate(pairs)]}


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    db = experiment_database(cfg.db, out, map_config(cfg.quick_maps))
    empty = build_grid(db) if cfg.grid else []  # the maps the run plans from, before the first scene
    for o in cfg.object_sets:  # every mesh's convex parts (cached on disk) before the first scene
        prepare_objects(o, db.gripper, progress=True)
    db_start = {**database_record(db), "grid_without_grasps": empty}
    conds = conditions(cfg)
    goal = [target(cfg, c) for c in conds]
    done: list[list] = [[] for _ in conds]
    skipped: list[list] = [[] for _ in conds]
    built: list[set] = [set() for _ in conds]
    pool = get_context("spawn").Pool(cfg.workers) if cfg.workers > 1 else None
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # kill PID: stop as Ctrl-C does
    text = run.write(out, _data(cfg, conds, goal, done, skipped, built, db_start, db_start), readme_section)
    try:
        order = [p for r in rounds(cfg, conds) for p in r]
        tasks = [(conds[i], cfg, str(db.root), j, 1) for i, j in order]  # one scene a task: even loads
        results = pool.imap(_block, tasks) if pool is not None else map(_block, tasks)
        for (i, _), (new, miss, keys) in zip(order, results):  # in order: each condition's first scenes
            done[i] += new
            skipped[i] += miss
            built[i] |= keys
            log.info("scenes done per condition: %s", [len(d) + len(k) for d, k in zip(done, skipped)])
            data = _data(cfg, conds, goal, done, skipped, built, db_start, database_record(db))
            text = run.write(out, data, readme_section)  # after every scene: a run cut short reports them
    except KeyboardInterrupt:  # the scenes finished so far are in the summary already (complete: false)
        log.warning("interrupted: %s holds the scenes finished before", out / "summary.json")
        if pool is not None:
            pool.terminate()
        return 130
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    print(text)
    return 0


def rounds(cfg: Config, conds: list) -> list[list[tuple[int, int]]]:
    """The run's order: rounds of (condition index, scene), ``block`` scenes of every
    condition a round; with ``others`` the goal conditions
    (:func:`target`) run all their scenes first, then the others, so a run cut short
    has finished the goals."""
    goal = [target(cfg, c) for c in conds]
    first = [i for i, c in enumerate(conds) if not cfg.others or _is_goal(cfg, c)]
    out = []
    for group in (first, [i for i in range(len(conds)) if i not in first]):
        for lo in range(0, max((goal[i] for i in group), default=0), cfg.block):
            out.append([(i, j) for i in group for j in range(lo, min(lo + cfg.block, goal[i]))])
    return [r for r in out if r]


def _is_goal(cfg: Config, c: dict) -> bool:
    return c["objects"] == cfg.goal_objects and c["ablation"] is None


def scenes_per_seed(cfg: Config, c: dict) -> int:
    """Scenes a condition runs per seed: ``scenes`` for the goal conditions
    (``goal_objects`` objects, the full method), ``others`` (if > 0) for the rest."""
    return cfg.scenes if _is_goal(cfg, c) or not cfg.others else min(cfg.others, cfg.scenes)


def target(cfg: Config, c: dict) -> int:
    """Scenes a condition runs in all: :func:`scenes_per_seed` x ``seeds``; its j-th is
    scene j % per-seed of seed index j // per-seed."""
    return scenes_per_seed(cfg, c) * cfg.seeds


def _data(cfg: Config, conds: list, goal: list, done: list, skipped: list, built: list, db_start: dict,
          db_end: dict) -> dict:
    """The summary's data so far: per condition its scenes asked (``target``) and
    whether they all ran (``complete``)."""
    counts = [len(d) + len(k) for d, k in zip(done, skipped)]
    return {"config": cfg, "complete": all(n >= g for n, g in zip(counts, goal)),
            "conditions": [{**_row(c, r), "target": g, "complete": n >= g, "skipped": k,
                            "built_in_memory": sorted(b)}
                           for c, r, g, n, k, b in zip(conds, done, goal, counts, skipped, built)],
            "database": {"start": db_start, "end": db_end}}


@dataclass(frozen=True)
class E10Cases:
    """The settings that name an E10 run's clutter episodes, for the studies that replay
    them (:func:`replay_cases`): scene kind and size, execution error, E10's seed count and
    seed, the object set, and its map database (``db`` read only; :func:`read_only_database`).
    A study's ``Config`` derives from it and adds its ``cases`` and its own settings."""

    kind: str = opt("pile", "scene kind", choices=("pile", "packed"))
    objects: int = opt(5, "objects per scene")
    noise: str = opt("none", "execution error: none, default (3 mm / 2 deg)", choices=("none", "default"))
    seeds: int = opt(5, "seeds of the E10 run the cases come from (--seeds of e10_clutter_removal.py)")
    object_set: str = opt("household-tuning", "object set")
    seed: int = opt(0, "run seed (E10's)")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder, read only (default: OUT/fsdb, built fresh)")


def read_only_database(cfg, out: Path) -> RunDatabase:
    """The database E10 plans against (read only), for a study of its clutter episodes with
    E10's ``db`` and ``quick_maps`` options: ``cfg.db``, else one built in ``out``."""
    config = map_config(cfg.quick_maps)
    return RunDatabase(experiment_database(cfg.db, out, config).root, config=config)


def looks(ep, stop_after: int | None = None):
    """A study's walk through a clutter episode ``ep``: each look that found a grasp, as
    (look, its best grasp, the plan, that grasp's segment memory), until the episode
    stops or ``stop_after`` grasps were executed; the caller executes each."""
    while ep.stop is None and (stop_after is None or len(ep.attempts) < stop_after):
        look = ep.observe()
        if look is None:
            return
        yield look, look.best, look.plan, look.plan.memory[look.best.segment]


def replay_cases(cfg, out: Path, record, replay, shown: str) -> int:
    """The rest of a replay study's ``main`` after ``start``: every case of ``cfg.cases``
    ("K:I[:...]", as integers) replayed by ``replay(numbers, db)`` against E10's database
    (:func:`read_only_database`) into rows, the rows recorded, and those holding the key
    ``shown`` printed."""
    db = read_only_database(cfg, out)
    rows = []
    for case in cfg.cases:
        rows += replay([int(x) for x in case.split(":")], db)
    record.write(out, {"config": cfg, "rows": rows}, lambda s: "")
    print(json.dumps([r for r in rows if shown in r], indent=1))
    return 0


def _block(task) -> tuple[list, list, set]:
    """Scenes first .. first + n - 1 of a condition, against the run's database:
    (results, skipped scenes, keys of maps built in memory). A scene that cannot be
    drawn (it does not settle on the table) or whose simulation fails is skipped and
    said so; the same scene is then skipped in every condition of its kind and size
    that fails the same way."""
    c, cfg, root, first, n = task
    per = scenes_per_seed(cfg, c)
    key = (root, cfg.quick_maps)
    db = resident_run_database(root, cfg.quick_maps)
    warm = _warm_up(c, cfg, db) if key not in _WARM else set()
    _WARM.add(key)
    db.built = set(warm)
    out, skipped = [], []
    for j in range(first, first + n):
        k, i = divmod(j, per)
        sd = seed_of(cfg, k)
        try:
            config = _clutter_config(c, cfg.unseen_margin, cfg.plan_all, cfg.contacts, cfg.seen_between,
                                     cfg.feature_grasps, cfg.sparse_between, cfg.shadow_depth)
            out += [(sd, r) for r in run_benchmark(c["objects"], c["kind"], 1, sd, db=db, config=config,
                                                   object_set=c["object_set"], first=i)]
        except SimulationError as err:
            log.warning("%s seed %d scene %d skipped: %s", c, sd, i, err)
            skipped.append({"seed": sd, "scene": i, "reason": str(err)})
    return out, skipped, db.built


_WARM: set = set()


def _warm_up(c: dict, cfg: Config, db) -> set:
    """Plan the first frame of a scene no condition draws (``derived_seed(--seed,
    "warm-up")``, the condition's object set, kind and size), untimed, once per process
    before its first scene: the compiled kernels, the modules and the segment workers are
    loaded, so every condition's planning times are a warm planner's, whichever
    condition a process meets first (a fresh process's first frame, 3-6 s more:
    ``bench_first_frame.py``). Returns the keys of the maps it built in memory (reported
    with the first scene's condition); nothing it does changes a result."""
    from graspsim.tabletop.clutter import ClutterEpisode
    from graspsim.tabletop.table_scene import make_scene

    db.built = set()
    config = _clutter_config(c, cfg.unseen_margin, cfg.plan_all, cfg.contacts, cfg.seen_between, cfg.feature_grasps,
                             cfg.sparse_between, cfg.shadow_depth)
    scene = make_scene(c["objects"], c["kind"], derived_seed(cfg.seed, "warm-up"), object_set=c["object_set"],
                       gripper=db.gripper, **({} if config.sim is None else {"settings": config.sim}))
    ep = ClutterEpisode(scene, db=db, rng=rng_for(cfg.seed, "warm-up"), config=config)
    try:
        ep.observe()
    finally:
        ep.close()
    return set(db.built)


def headline(s: dict) -> str:
    """The README's headline line (see ``experiments/report.py``): clutter removal by the
    full method without and with execution error (the conditions the run has), per object
    set, scene kind and size, with the seeds x scenes it pooled (a summary written before
    object sets and seeds: the "mixed" set and its one seed)."""
    groups: dict[tuple, dict] = {}
    for r in rows_of(s):
        if not r["ablation"]:
            groups.setdefault((r["object_set"], r["kind"], r["objects"]), {})[r["noise"]] = r
    order = [n for n in ("none", "default") if any(n in g for g in groups.values())]
    label = " / ".join({"none": "without", "default": "with"}[n] for n in order)

    def rates(g: dict, num: str, den: str) -> str:
        return " / ".join(rate_ci(g[n][num], g[n][den]) if n in g else "not run" for n in order)

    def group(key: tuple, g: dict) -> str:
        r = next(iter(g.values()))
        return (f"{key[0]} {key[1]} of {key[2]} ({len(r['per_seed'])} x {max(x['scenes'] for x in r['per_seed'])}): "
                f"GSR {rates(g, 'successes', 'attempts')}, DR {rates(g, 'removed', 'placed')}")

    return (f"Clutter removal {label} execution error (GSR: grasps that lifted their target; DR: objects "
            "removed; seeds x scenes): " + "; ".join(group(k, g) for k, g in groups.items()) + ".")

if __name__ == "__main__":
    raise SystemExit(main())
