"""Benchmark: the trial harness against raw MuJoCo stepping of the same trials.

For a primitive (the paper's cylinder, r 2 cm, h 20 cm) and a CoACD mesh object (the
robosuite bread, 4 convex parts), one batch of ``lift_place`` trials (the same poses,
initial states and open-loop controls throughout) is timed three ways on one thread:

* the harness: ``run_trials`` (start-collision check, controls, ``mujoco.rollout``,
  judging the recorded states);
* bare ``mujoco.rollout`` of the harness's feasible trials (the same initial states
  and controls; what the harness adds on top of it is its overhead);
* raw ``mj_step`` of the same feasible trials: a loop setting each step's control and
  stepping (no recording, no judging).

Rates are simulated seconds per wall second, the medians of ``--repeats`` interleaved
runs (the machine is shared: load changes hit all three alike), with the ratios
harness / rollout and harness / raw mj_step of those medians, and trials/s on all
cores (median). Writes summary.json, table.md and config.json into ``--out``.

    python experiments/bench_sim.py
    python experiments/bench_sim.py --quick --out results/bench_sim-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import os
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # hand_made: the tests' hand-made grasps
from _common import NAMED, machine_load, opt, rng_for, start
from hand_made import grasp_pose

from graspsim.primitives import Cylinder
from graspsim.sim import LiftPlace, build_scene, object_from_mesh, object_from_shape, run_trials
from graspsim.sim.batch import initial_states, pregrasp_opening, simulate

log = logging.getLogger("bench_sim")
BREAD = Path(__file__).resolve().parents[1] / "assets/objects/robosuite/bread.stl"
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class BenchConfig:
    trials: int = opt(64, "lift_place trials per object")
    repeats: int = opt(5, "timed runs (medians)")
    threads: int = opt(os.cpu_count() or 1, "'all cores'")
    seed: int = opt(0, "run seed")
    QUICK: ClassVar[dict] = {"trials": 4, "repeats": 1}

    def __post_init__(self) -> None:
        if self.trials < 1 or self.repeats < 1 or self.threads < 1:
            raise ValueError(f"--trials, --repeats and --threads must be >= 1, got {self.trials}, {self.repeats}, "
                             f"{self.threads}")


def _poses(kind: str, n: int, rng: np.random.Generator, com: np.ndarray):
    """Feasible side grasps: random yaw and height (the 5 cm tall housing must clear the
    table, so grasps on the low bread stay at or above its centre of mass)."""
    yaw = rng.uniform(-np.pi, np.pi, n) if kind == "primitive" else rng.uniform(-0.1, 0.1, n)
    z = rng.uniform(-0.06, 0.06, n) if kind == "primitive" else rng.uniform(0.0, 0.008, n)
    T = np.stack([grasp_pose(com + [0, 0, zi], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0],
                             depth=rng.uniform(0.01, 0.03)) for a, zi in zip(yaw, z)])
    w = np.full(n, 0.04) if kind == "primitive" else 0.05 / np.cos(yaw)
    return T, w


def _workload(scene, T, w):
    """(initial states, controls) of the trials, as the harness builds them."""
    p = LiftPlace()
    T_world = scene.T_world_obj @ T
    return (initial_states(scene, T_world, pregrasp_opening(scene, w)),
            p.controls(scene, T_world, pregrasp_opening(scene, w)))


def _rollout_rate(scene, state0, control) -> float:
    """Simulated s per wall s of one bare ``mujoco.rollout`` call (one thread)."""
    t = time.perf_counter()
    simulate(scene, LiftPlace(), state0, control)
    return control.shape[0] * control.shape[1] * scene.model.opt.timestep / (time.perf_counter() - t)


def _step_rate(scene, state0, control) -> float:
    """Simulated s per wall s of raw ``mj_step``: each trial from its initial state,
    each step's control set, no recording."""
    m, d, spec = scene.model, mujoco.MjData(scene.model), LiftPlace().control_spec
    t = time.perf_counter()
    for i in range(len(state0)):
        mujoco.mj_setState(m, d, state0[i], _FULL)
        d.qacc_warmstart[:] = 0.0
        for c in control[i]:
            mujoco.mj_setState(m, d, c, spec)
            mujoco.mj_step(m, d)
    return control.shape[0] * control.shape[1] * m.opt.timestep / (time.perf_counter() - t)


def run(cfg: BenchConfig) -> list[dict]:
    rng = rng_for(cfg.seed)
    objects = {"primitive": object_from_shape(Cylinder(0.02, 0.20)),
               "coacd_mesh": object_from_mesh(BREAD)}
    rows = []
    for kind, obj in objects.items():
        scene = build_scene(obj)
        T, w = _poses(kind, cfg.trials, rng, obj.com)
        harness, bare, raw, allc = [], [], [], []
        r = None
        for _ in range(cfg.repeats):  # interleaved, so load changes hit all timers alike
            r = run_trials(scene, T, w, LiftPlace(), threads=1, seed=cfg.seed)
            harness.append(r.simulated_seconds / r.wall_time)
            feasible = r.outcome != 1  # START_COLLISION poses are not simulated
            state0, control = _workload(scene, T[feasible], w[feasible])
            bare.append(_rollout_rate(scene, state0, control))
            raw.append(_step_rate(scene, state0, control))
            allc.append(run_trials(scene, T, w, LiftPlace(), threads=cfg.threads, seed=cfg.seed).trials_per_second)
        h, b, s = (statistics.median(x) for x in (harness, bare, raw))
        rows.append({
            "object": kind, "geoms": len(obj.geoms), "trials": len(T), "feasible": int(r.feasible),
            "successes": r.counts()["success"], "trial_sim_s": r.simulated_seconds / max(1, r.feasible),
            "repeats": cfg.repeats, "harness_sim_s_per_s": h, "rollout_sim_s_per_s": b, "mj_step_sim_s_per_s": s,
            "harness_over_rollout": h / b, "harness_over_mj_step": h / s,
            "runs": {"harness": harness, "rollout": bare, "mj_step": raw, "trials_per_s_all_cores": allc},
            "trials_per_s_1_thread": h / (r.simulated_seconds / max(1, r.feasible)),
            "trials_per_s_all_cores": statistics.median(allc), "threads": cfg.threads,
        })
        log.info("%s: %s", kind, {k: v for k, v in rows[-1].items() if k != "runs"})
    return rows


def table(rows: list[dict]) -> str:
    head = ("object", "trials (feasible)", "harness sim s/s", "bare rollout sim s/s", "raw mj_step sim s/s",
            "harness / rollout", "harness / mj_step", "trials/s 1 thread", "trials/s all cores")
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        out.append(f"| {r['object']} ({r['geoms']} geoms) | {r['trials']} ({r['feasible']}) | "
                   f"{r['harness_sim_s_per_s']:.1f} | {r['rollout_sim_s_per_s']:.1f} | "
                   f"{r['mj_step_sim_s_per_s']:.1f} | "
                   f"{r['harness_over_rollout']:.2f} | {r['harness_over_mj_step']:.2f} | "
                   f"{r['trials_per_s_1_thread']:.1f} | {r['trials_per_s_all_cores']:.1f} ({r['threads']} threads) |")
    return "\n".join(out)


def main(argv=None) -> int:
    cfg, out, run_record = start(BenchConfig, __file__, argv, __doc__, log_format=NAMED, quiet=("graspsim.sim.batch",))
    rows = run(cfg)
    run_record.write(out, {"config": cfg, "rows": rows}, readme_section)
    text = table(rows)
    (out / "table.md").write_text(text + "\n")
    print(text)
    return 0


def readme_section(s: dict) -> str:
    """The README's simulation-speed sentence and table (see ``experiments/report.py``)."""
    m, rows, (start, _) = s["machine"], s["rows"], machine_load(s)
    trial = rows[0]["trial_sim_s"]
    L = [f"`{s['command']}` (one batch of lift-and-place trials, {trial:.1f} s simulated each, timed through the "
         f"harness and as bare `mujoco.rollout` and raw `mj_step` of the same trials on one thread; medians of "
         f"{rows[0]['repeats']} interleaved runs on {m['cpus']} cores, load average {start[0]:g} at the "
         f"start):", "", table(rows)]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
