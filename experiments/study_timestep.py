"""Does a clutter grasp's outcome depend on the simulation's time step?

E10 (``e10_clutter_removal.py``) judges every grasp by simulating it in MuJoCo at the
default contact model's time step (``SimSettings().timestep``, 1 ms). A result that
changes when the same grasp is simulated at a finer step measures the integration, not
the grasp. This study walks E10's episodes (the same scenes, seeds, camera, sensor
noise, planner settings and read-only database as ``e10_clutter_removal.py --seeds
SEEDS``; scenes ``0 .. --scenes - 1`` of the first ``--seed-indices`` seeds of each
condition, no execution error) and, before each grasp is executed, simulates it again
from the very state it starts in with ``SceneSim.execute(..., commit=False)`` -- the
benchmark's own simulation and judge, with nothing committed -- at the step the run used
and at each of ``--steps`` (the model's ``opt.timestep`` changed for that simulation only;
the protocol's phases are in seconds, so a finer step runs proportionally more steps).
Then the episode goes on with the grasp executed as E10 executes it.

Per condition and step: the grasps lifted, and every grasp whose outcome changed from the
run's step (lifted -> failed, failed -> lifted, one failure for another). The simulation at
the run's own step must give the episode's outcome (checked: ``as_run_differs`` counts the
grasps where it did not). A start collision is decided before any step is taken (the
gripper's pose against the settled scene), so it is the same at every step.

    python experiments/study_timestep.py --db /work/runs/e10-fsdb
    python experiments/study_timestep.py --quick --out results/study_timestep-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start, task_results

SUCCESS = "success"


@dataclass(frozen=True)
class Config:
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    object_sets: tuple[str, ...] = opt(("household-tuning", "random-tuning"), "object sets")
    objects: int = opt(5, "objects per scene")
    seeds: int = opt(5, "seeds of the E10 run the episodes come from (--seeds of e10_clutter_removal.py)")
    seed: int = opt(0, "run seed (E10's)")
    seed_indices: int = opt(1, "episodes from the first N of those seeds")
    scenes: int = opt(20, "scenes 0 .. N-1 of each of those seeds")
    steps: tuple[float, ...] = opt((0.0005, 0.00025), "finer time steps [s] each grasp is simulated at too")
    workers: int = opt(2, "processes (episodes run one per process)")
    quick_maps: bool = opt(False, "coarse FS maps (1 cm, 22 deg)")
    db: str = opt("", "FS database folder, read only (default: OUT/fsdb, built fresh)")
    QUICK: ClassVar[dict] = {"kinds": ("packed",), "object_sets": ("primitives",), "objects": 2, "seeds": 1,
                             "scenes": 1, "steps": (0.0005,), "workers": 1, "quick_maps": True}

    def __post_init__(self) -> None:
        from graspsim.tabletop.scene_objects import check_object_set

        for s in self.object_sets:
            check_object_set(s)
        if not 1 <= self.seed_indices <= self.seeds:
            raise ValueError("--seed-indices must be in [1, --seeds]")
        if self.scenes < 1 or self.objects < 1 or self.workers < 1:
            raise ValueError("--scenes, --objects and --workers must be >= 1")
        if not self.steps or any(not 0.0 < s < 0.01 for s in self.steps):
            raise ValueError("--steps must be time steps in (0, 0.01) s")


def episode(task) -> list[dict]:
    """One E10 episode (condition, seed index k, scene i): per executed grasp, its outcome
    as the episode met it and simulated again at the run's step and at each finer one."""
    from _scenes import resident_run_database
    from e10_clutter_removal import _clutter_config, looks

    from graspsim.tabletop.clutter import OTHER, benchmark_episode
    from graspsim.tabletop.clutter_stats import benchmark_seeds
    from graspsim.tabletop.planners import grasp_target

    (kind, object_set), k, i, cfg, root = task
    db = resident_run_database(root, cfg.quick_maps)
    config = _clutter_config({"kind": kind, "noise": "none", "ablation": None})
    ep = benchmark_episode(cfg.objects, kind, benchmark_seeds(cfg.seed, cfg.seeds)[k], i, db=db, config=config,
                           object_set=object_set)
    scene = ep.scene
    rows = []
    try:
        m = ep.sim.model
        run_step = float(m.opt.timestep)
        for n, (look, g, _, _) in enumerate(looks(ep)):
            target = grasp_target(look, g, db.gripper)
            T, opening = g.T_world_wrist, float(g.opening)
            again = {}
            for step in (run_step, *cfg.steps):
                m.opt.timestep = step
                try:
                    out = ep.sim.execute(T, opening, target=target, commit=False)
                finally:
                    m.opt.timestep = run_step
                hit = out.success and out.picked == target
                again[repr(step)] = OTHER if out.success and not hit else out.cause
            a = ep.execute(look, g)
            rows.append({"kind": kind, "object_set": object_set, "case": f"{k}:{i}", "grasp": n,
                         "object": None if a.target is None else scene.objects[a.target].name,
                         "score": round(float(g.score), 3), "source": getattr(g, "source", None),
                         "cause": a.cause, "run_step": run_step, "again": again})
    finally:
        ep.close()
    return rows


def run(cfg: Config, out: Path) -> dict:
    import logging

    from e10_clutter_removal import read_only_database

    root = str(read_only_database(cfg, out).root)
    conds = [(kind, s) for s in cfg.object_sets for kind in cfg.kinds]
    tasks = [(c, k, i, cfg, root) for c in conds for k in range(cfg.seed_indices) for i in range(cfg.scenes)]
    rows = []
    log = logging.getLogger("study_timestep")
    for done, r in enumerate(task_results(episode, tasks, cfg.workers), 1):
        rows += r
        log.info("episodes done: %d of %d", done, len(tasks))
    return {"rows": rows, "conditions": [summarise(cfg, rows, kind, s) for kind, s in conds],
            "denominators": "grasps: every grasp executed in the listed episodes; each simulated again from its "
                            "start state at the run's step and each finer one"}


def summarise(cfg: Config, rows: list[dict], kind: str, object_set: str) -> dict:
    """Per step: grasps lifted, and the grasps whose outcome differs from the run's step."""
    mine = [r for r in rows if r["kind"] == kind and r["object_set"] == object_set]
    steps = {}
    for step in cfg.steps:
        key = repr(step)
        changed = [r for r in mine if r["again"][key] != r["again"][repr(r["run_step"])]]
        steps[key] = {"lifted": sum(r["again"][key] == SUCCESS for r in mine),
                      "to_lifted": sum(r["again"][key] == SUCCESS for r in changed),
                      "from_lifted": sum(r["again"][repr(r["run_step"])] == SUCCESS for r in changed),
                      "changed": [{k: r[k] for k in ("case", "grasp", "object", "score", "source")}
                                  | {"as_run": r["again"][repr(r["run_step"])], "now": r["again"][key]}
                                  for r in changed]}
    return {"kind": kind, "object_set": object_set, "objects": cfg.objects,
            "episodes": len({r["case"] for r in mine}), "grasps": len(mine),
            "lifted": sum(r["cause"] == SUCCESS for r in mine),
            "as_run_differs": sum(r["again"][repr(r["run_step"])] != r["cause"] for r in mine),
            "run_steps": sorted({r["run_step"] for r in mine}), "steps": steps}


def readme_section(s: dict) -> str:
    cfg = s["config"]
    ms = ", ".join(f"{1000 * x:g} ms" for x in cfg["steps"])
    L = [f"`{s['command']}`: E10's episodes (scenes 0-{cfg['scenes'] - 1} of its first {cfg['seed_indices']} "
         f"seed(s) of {cfg['seeds']}, {cfg['objects']} objects, no execution error); every executed grasp simulated "
         f"again from its start state at the run's step and at {ms} (`SceneSim.execute`, nothing committed). "
         "Changed: grasps whose outcome differs from the run's step (lifted its target or not; a failure that "
         "became another failure counts under neither arrow).", "",
         "| object set | scene | episodes | grasps | step | lifted | changed | failed -> lifted | lifted -> failed |",
         "|---|---|---|---|---|---|---|---|---|"]
    for c in s["conditions"]:
        as_run = ", ".join(f"{1000 * x:g} ms" for x in c["run_steps"])
        L.append(f"| {c['object_set']} | {c['kind']} | {c['episodes']} | {c['grasps']} | {as_run} (as run) | "
                 f"{c['lifted']} | - | - | - |")
        for key, v in c["steps"].items():
            L.append(f"| | | | | {1000 * float(key):g} ms | {v['lifted']} | {len(v['changed'])} | {v['to_lifted']} | "
                     f"{v['from_lifted']} |")
    diff = sum(c["as_run_differs"] for c in s["conditions"])
    L += ["", f"Simulated again at the run's own step, {diff} of {sum(c['grasps'] for c in s['conditions'])} grasps "
          "gave another outcome than the episode did (0: the replay is the episode's simulation)."]
    changed = [(c, key, x) for c in s["conditions"] for key, v in c["steps"].items() for x in v["changed"]]
    if changed:
        L += ["", "The grasps that changed (case: seed index:scene, grasp: its place in the episode):", "",
              "| object set | scene | step | case | grasp | object | score | source | as run | at the step |",
              "|---|---|---|---|---|---|---|---|---|---|"]
        for c, key, x in changed:
            L.append(f"| {c['object_set']} | {c['kind']} | {1000 * float(key):g} ms | {x['case']} | {x['grasp']} | "
                     f"{x['object']} | {x['score']:.2f} | {x['source']} | {x['as_run']} | {x['now']} |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    import json

    cfg, out, record = start(Config, __file__, argv, __doc__)
    record.write(out, {"config": cfg, **run(cfg, out)}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
