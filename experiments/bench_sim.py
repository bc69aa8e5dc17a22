"""Benchmark: raw MuJoCo stepping of the held-object scene vs the trial harness.

For a primitive (the paper's cylinder, r 2 cm, h 20 cm) and a CoACD mesh object (the
robosuite bread, 4 convex parts): simulated seconds per wall second of

* raw ``mj_step`` (native loop, one thread) of the scene with the object held in the air,
* the harness (``run_trials``: start-collision check, controls, ``mujoco.rollout``,
  judging) for a batch of ``lift_place`` trials on one thread,

their ratio (goal >= 0.9), the bare ``mujoco.rollout`` rate of the same trials (so the
harness's own overhead shows apart from the physics of the trial's phases, e.g. the
object resting on the table), and trials/s on all cores. Timings are the best of
``--repeats`` runs (the machine may be shared). Writes bench_sim.json, table.md and
config.json into ``--out``.

    python experiments/bench_sim.py --out results/bench_sim
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np

from graspsim.primitives import Cylinder
from graspsim.sim import LiftPlace, build_scene, object_from_mesh, object_from_shape, run_trials
from graspsim.sim.batch import initial_states, pregrasp_opening, simulate
from graspsim.sim.testing import grasp_pose

log = logging.getLogger("bench_sim")
BREAD = Path(__file__).resolve().parents[1] / "assets/objects/robosuite/bread.stl"


@dataclass(frozen=True)
class BenchConfig:
    trials: int
    raw_steps: int
    repeats: int
    threads: int
    seed: int


def parse_args(argv=None) -> tuple[BenchConfig, Path]:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="results/bench_sim", help="output folder")
    p.add_argument("--trials", type=int, default=64, help="lift_place trials per object")
    p.add_argument("--raw-steps", type=int, default=20000, help="mj_step calls for the raw rate")
    p.add_argument("--repeats", type=int, default=3, help="best of this many timings")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="'all cores'")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    return BenchConfig(a.trials, a.raw_steps, max(1, a.repeats), max(1, a.threads), a.seed), Path(a.out)


def _poses(kind: str, n: int, rng: np.random.Generator, com: np.ndarray):
    """Feasible side grasps: random yaw and height (the 5 cm tall housing must clear the
    table, so grasps on the low bread stay at or above its centre of mass)."""
    yaw = rng.uniform(-np.pi, np.pi, n) if kind == "primitive" else rng.uniform(-0.1, 0.1, n)
    z = rng.uniform(-0.06, 0.06, n) if kind == "primitive" else rng.uniform(0.0, 0.008, n)
    T = np.stack([grasp_pose(com + [0, 0, zi], [-np.cos(a), -np.sin(a), 0], [-np.sin(a), np.cos(a), 0],
                             depth=rng.uniform(0.01, 0.03)) for a, zi in zip(yaw, z)])
    w = np.full(n, 0.04) if kind == "primitive" else 0.05 / np.cos(yaw)
    return T, w


def _raw_rate(scene, T, w, cfg: BenchConfig) -> float:
    """Simulated s per wall s of mj_step with the object held at the top of the lift."""
    p = LiftPlace()
    m = scene.model
    T_world = scene.T_world_obj @ T[:1]
    control = p.controls(scene, T_world)
    hold_end = p.steps(m.opt.timestep)["hold"][1]
    states, _ = simulate(scene, p, initial_states(scene, T_world, pregrasp_opening(scene, w[:1])),
                         control[:, : hold_end + 1], backend="python")
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, states[0, -1], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_setState(m, d, control[0, hold_end], p.control_spec)
    t = time.perf_counter()
    mujoco.mj_step(m, d, nstep=cfg.raw_steps)
    wall = time.perf_counter() - t
    assert d.qpos[scene.qadr_obj + 2] > 0.1, "the object must still be held"
    return cfg.raw_steps * m.opt.timestep / wall


def _rollout_rate(scene, T, w, cfg: BenchConfig) -> float:
    """Simulated s per wall s of the bare ``mujoco.rollout`` call for the same trials
    (one thread): what the harness adds on top of it is its overhead."""
    p = LiftPlace()
    T_world = scene.T_world_obj @ T
    state0 = initial_states(scene, T_world, pregrasp_opening(scene, w))
    control = p.controls(scene, T_world)
    t = time.perf_counter()
    simulate(scene, p, state0, control)
    return control.shape[0] * control.shape[1] * scene.model.opt.timestep / (time.perf_counter() - t)


def run(cfg: BenchConfig) -> list[dict]:
    rng = np.random.default_rng(cfg.seed)
    objects = {"primitive": object_from_shape(Cylinder(0.02, 0.20)),
               "coacd_mesh": object_from_mesh(BREAD)}
    rows = []
    for kind, obj in objects.items():
        scene = build_scene(obj)
        T, w = _poses(kind, cfg.trials, rng, obj.com)
        raw, bare, one, allc = [], [], None, None
        for _ in range(cfg.repeats):  # interleaved, so load changes hit all timers alike
            raw.append(_raw_rate(scene, T, w, cfg))
            r = run_trials(scene, T, w, LiftPlace(), threads=1, seed=cfg.seed)
            one = r if one is None or r.wall_time < one.wall_time else one
            feasible = r.outcome != 1  # START_COLLISION poses are not simulated
            bare.append(_rollout_rate(scene, T[feasible], w[feasible], cfg))
            r = run_trials(scene, T, w, LiftPlace(), threads=cfg.threads, seed=cfg.seed)
            allc = r if allc is None or r.wall_time < allc.wall_time else allc
        raw, bare = max(raw), max(bare)
        rows.append({
            "object": kind, "geoms": len(obj.geoms), "trials": len(T),
            "successes": one.counts()["success"],
            "raw_sim_s_per_s": raw, "harness_sim_s_per_s": one.simulated_seconds / one.wall_time,
            "ratio": one.simulated_seconds / one.wall_time / raw,
            "rollout_sim_s_per_s": bare,
            "harness_overhead": 1.0 - one.simulated_seconds / one.wall_time / bare,
            "trials_per_s_1_thread": one.trials_per_second,
            "trials_per_s_all_cores": allc.trials_per_second, "threads": cfg.threads,
            "trial_sim_s": one.simulated_seconds / max(1, one.feasible),
        })
        log.info("%s: %s", kind, rows[-1])
    return rows


def table(rows: list[dict]) -> str:
    head = ("object", "raw sim s/s", "harness sim s/s", "ratio", "bare rollout sim s/s",
            "harness overhead", "trials/s 1 thread",
            "trials/s all cores", "successes")
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        out.append(f"| {r['object']} ({r['geoms']} geoms) | {r['raw_sim_s_per_s']:.1f} | "
                   f"{r['harness_sim_s_per_s']:.1f} | {r['ratio']:.2f} | {r['rollout_sim_s_per_s']:.1f} | "
                   f"{100 * r['harness_overhead']:.1f} % | {r['trials_per_s_1_thread']:.1f} | "
                   f"{r['trials_per_s_all_cores']:.1f} ({r['threads']} threads) | "
                   f"{r['successes']}/{r['trials']} |")
    return "\n".join(out)


def main(argv=None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    cfg, out = parse_args(argv)
    rows = run(cfg)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"mujoco_version": mujoco.__version__, "cpu_count": os.cpu_count()}
    (out / "bench_sim.json").write_text(json.dumps({"rows": rows, **meta}, indent=2))
    (out / "config.json").write_text(json.dumps(asdict(cfg), indent=2))
    text = table(rows)
    (out / "table.md").write_text(text + "\n")
    print(text)  # noqa: T201 (a script's report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
