"""Batched trials: many grasps of one scene, run natively in parallel threads.

``run_trials`` checks every pose for penetration at t = 0 (START_COLLISION, not
simulated), builds the protocol's open-loop controls, runs the rest through
``mujoco.rollout`` in chunks (threads from a persistent pool; each trial starts from its
own full physics state with a zero warm start, so outcomes do not depend on the thread
count or on which trials share a chunk) and judges the recorded states. The
``backend="python"`` fallback steps the same trials one by one in Python, for debugging
and rendering; it produces the same records.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable

import mujoco
import numpy as np
from mujoco import rollout

from graspsim.errors import InvalidParameterError, SimulationError
from graspsim.sim.noise import ExecutionNoise
from graspsim.sim.outcomes import Record, TrialOutcome, collision_kind
from graspsim.sim.protocols import LiftPlace, Protocol
from graspsim.sim.results import TrialResults
from graspsim.sim.trial_scene import Scene
from graspsim.transforms import matrix_to_quat

__all__ = ["run_trials", "run_in_chunks", "trial_inputs", "start_penetration", "initial_states", "simulate",
           "pregrasp_opening", "arm_below_table"]

log = logging.getLogger(__name__)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def pregrasp_opening(scene: Scene, widths: np.ndarray) -> np.ndarray:
    """Pad gap (N,) [m] at the pose: contact width + 2 x approach clearance, in range."""
    return scene.gripper.pregrasp_opening(widths)


def initial_states(scene: Scene, T_world_wrist: np.ndarray, openings: np.ndarray) -> np.ndarray:
    """Full physics states (N, nstate): wrist at the poses, jaws at ``openings``, the
    object at rest on the table, everything still, time 0."""
    m = scene.model
    d = mujoco.MjData(m)
    state = np.empty(scene.nstate)
    mujoco.mj_getState(m, d, state, _FULL)
    out = np.repeat(state[None], len(T_world_wrist), axis=0)
    q0 = 1 + scene.qadr_wrist
    out[:, q0:q0 + 3] = T_world_wrist[:, :3, 3]
    out[:, q0 + 3:q0 + 7] = matrix_to_quat(T_world_wrist[:, :3, :3])
    out[:, 1 + scene.drive.qadr] = scene.drive.joint_positions(openings)
    return out


def start_penetration(scene: Scene, state0: np.ndarray, T_world_wrist: np.ndarray) -> np.ndarray:
    """Deepest overlap (N,) [m] at t = 0 of the gripper with the object or the table
    (0 where they do not touch); the arm keep-out box counts against the table."""
    return np.maximum(*start_overlaps(scene, state0, T_world_wrist))


def start_overlaps(scene: Scene, state0: np.ndarray, T_world_wrist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deepest overlap at t = 0 of the gripper with the object and with the table, apart:
    ((N,), (N,)) [m], 0 where they do not touch (the arm keep-out box counts against the
    table; a scene without a table: zeros)."""
    m, d = scene.model, mujoco.MjData(scene.model)
    obj, table = np.zeros(len(state0)), np.zeros(len(state0))
    grip = np.zeros(m.ngeom, bool)
    grip[scene.gripper_geoms] = True
    other = np.zeros(m.ngeom, bool)
    other[scene.contact_geoms] = True
    table_geom = np.zeros(m.ngeom, bool)
    if scene.table:
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "table")
        if gid >= 0:
            table_geom[gid] = True
    for i, s in enumerate(state0):
        mujoco.mj_setState(m, d, s, _FULL)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        if d.ncon:
            g = d.contact.geom[: d.ncon]
            mine = grip[g[:, 0]] | grip[g[:, 1]]
            hit = (grip[g[:, 0]] & other[g[:, 1]]) | (grip[g[:, 1]] & other[g[:, 0]])
            on_table = mine & (table_geom[g[:, 0]] | table_geom[g[:, 1]])
            dist = d.contact.dist[: d.ncon]
            if np.any(hit & ~on_table):
                obj[i] = max(0.0, -float(dist[hit & ~on_table].min()))
            if np.any(hit & on_table):
                table[i] = max(0.0, -float(dist[hit & on_table].min()))
    if scene.table:
        table = np.maximum(table, arm_below_table(scene.gripper, T_world_wrist))
    return obj, table


def arm_below_table(gripper, T_world_wrist: np.ndarray) -> np.ndarray:
    """(N,) how deep [m] the gripper's arm keep-out box reaches below the table (z = 0) at
    the wrist poses (N, 4, 4); 0 where it stays above or the gripper has no arm box."""
    b = gripper.collision_boxes()
    if "arm" not in b.names:
        return np.zeros(len(T_world_wrist))
    k = b.names.index("arm")
    corners = b.centers[k] + b.half_extents[k] * np.array(
        np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    z = np.einsum("nj,cj->nc", T_world_wrist[:, 2, :3], corners) + T_world_wrist[:, 2, 3:4]
    return np.maximum(0.0, -z.min(axis=1))


def simulate(scene: Scene, protocol: Protocol, state0: np.ndarray, control: np.ndarray, *,
             pool: rollout.Rollout | None = None, datas: list | None = None,
             backend: str = "rollout") -> tuple[np.ndarray, np.ndarray]:
    """Run trials; returns states (n, S, nstate) and sensordata (n, S, nsensordata)."""
    m = scene.model
    n, S = control.shape[:2]
    if backend == "python":
        d = mujoco.MjData(m)
        states = np.empty((n, S, scene.nstate))
        sens = np.empty((n, S, m.nsensordata))
        for i in range(n):
            mujoco.mj_setState(m, d, state0[i], _FULL)
            d.qacc_warmstart[:] = 0.0
            for k in range(S):
                mujoco.mj_setState(m, d, control[i, k], protocol.control_spec)
                mujoco.mj_step(m, d)
                mujoco.mj_getState(m, d, states[i, k], _FULL)
                sens[i, k] = d.sensordata
        return states, sens
    if backend != "rollout":
        raise InvalidParameterError(f"backend must be 'rollout' or 'python', got {backend!r}")
    datas = datas or [mujoco.MjData(m)]
    states, sens = rollout.rollout(
        [m] * n, datas, np.ascontiguousarray(state0), np.ascontiguousarray(control),
        control_spec=protocol.control_spec, nstep=S,
        initial_warmstart=np.zeros((n, m.nv)),
    ) if pool is None else pool.rollout(
        [m] * n, datas, np.ascontiguousarray(state0), np.ascontiguousarray(control),
        control_spec=protocol.control_spec, nstep=S, initial_warmstart=np.zeros((n, m.nv)),
    )
    return states, sens


def _record(scene: Scene, states: np.ndarray, sens: np.ndarray) -> Record:
    m = scene.model
    qp = states[..., 1:1 + m.nq]
    qv = states[..., 1 + m.nq:1 + m.nq + m.nv]
    w, o = scene.qadr_wrist, scene.qadr_obj
    pads = np.stack([sens[..., a:a + 4] for a in scene.pad_sensors], axis=-2)
    return Record(time=states[..., 0], wrist_pos=qp[..., w:w + 3], wrist_quat=qp[..., w + 3:w + 7],
                  obj_pos=qp[..., o:o + 3], obj_quat=qp[..., o + 3:o + 7],
                  obj_vel=qv[..., scene.dadr_obj:scene.dadr_obj + 6],
                  jaws=scene.drive.half_openings(qp[..., scene.qadr_jaws]), pads=pads)


def trial_inputs(scene, T_obj_wrist, widths, *, threads: int | None, seed: int,
                 noise: ExecutionNoise | None) -> tuple[np.ndarray, np.ndarray, int]:
    """(T_world_wrist (N, 4, 4) with the execution noise drawn from ``seed`` applied, widths
    (N,), threads) of a batch of trials, checked: poses (N, 4, 4) and widths (N,) finite,
    threads >= 1 and clamped to the trials and a few per core (beyond that they only cost
    memory: one MjData and one native thread each; results do not depend on them). Every
    executor of a batch (:func:`run_trials`, the arm's ``run_arm_trials``) starts here."""
    T = np.asarray(T_obj_wrist, dtype=float)
    widths = np.asarray(widths, dtype=float).reshape(-1)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) != len(widths):
        raise InvalidParameterError(
            f"T_obj_wrist must be (N, 4, 4) and widths (N,); got {T.shape} and {widths.shape}")
    if not (np.all(np.isfinite(T)) and np.all(np.isfinite(widths))):
        raise InvalidParameterError("poses and widths must be finite")
    threads = int(threads or os.cpu_count() or 1)
    if threads < 1:
        raise InvalidParameterError(f"threads must be >= 1, got {threads}")
    n = len(T)
    threads = min(threads, max(n, 1), 4 * (os.cpu_count() or 1))
    T_world = scene.T_world_obj @ T
    if noise is not None:
        T_world = T_world @ noise.sample(n, np.random.default_rng(seed), pivot=scene.gripper.nominal_tcp)
    return T_world, widths, threads


def run_in_chunks(todo: np.ndarray, chunk: int, run: Callable[[np.ndarray], tuple[np.ndarray, dict[str, np.ndarray]]],
                  outcome: np.ndarray, metrics: dict[str, np.ndarray], *, done: int,
                  on_progress: Callable[[int], None] | None = None) -> None:
    """Simulate the trials ``todo`` (indices into ``outcome``) ``chunk`` at a time:
    ``run(idx)`` simulates and judges those trials and returns their outcomes and metrics,
    written into ``outcome`` and ``metrics`` at ``idx`` (a metric not in ``metrics`` yet
    is NaN for the other trials). ``on_progress(k)`` after each chunk: ``k`` trials
    finished, counting the ``done`` ones decided before any ran. The chunk loop of
    :func:`run_trials` and of the arm's trials
    (:func:`graspsim.robots.execute.run_arm_trials`)."""
    n = len(outcome)
    for a in range(0, len(todo), chunk):
        idx = todo[a:a + chunk]
        out, met = run(idx)
        outcome[idx] = out
        for k, v in met.items():
            metrics.setdefault(k, np.full(n, np.nan))[idx] = v
        done += len(idx)
        if on_progress is not None:
            on_progress(done)


def run_trials(scene: Scene, T_obj_wrist: np.ndarray, widths: np.ndarray,
               protocol: Protocol = LiftPlace(), *, threads: int | None = None, seed: int = 0,
               noise: ExecutionNoise | None = None, backend: str = "rollout",
               chunk: int | None = None,
               on_progress: Callable[[int], None] | None = None,
               on_record: Callable[[np.ndarray, Record], None] | None = None) -> TrialResults:
    """Simulate N grasps of ``scene`` under ``protocol``.

    T_obj_wrist: (N, 4, 4) wrist poses in the object frame; widths: (N,) contact
    distances [m] (the jaws start at width + 2 x approach clearance). threads: native
    threads (default: all cores); seed: draws the execution noise (if ``noise``), one
    independent draw per trial in trial order, so results do not depend on threads.
    on_progress(k): called with the number of trials finished after each chunk.
    on_record(index, record): called after each chunk with its trial numbers (n,) and
    their full :class:`Record` (e.g. a :class:`~graspsim.sim.recording.Recorder`).
    """
    t_start = time.perf_counter()
    T_world, widths, threads = trial_inputs(scene, T_obj_wrist, widths, threads=threads, seed=seed, noise=noise)
    n = len(T_world)
    if scene.table != protocol.table or scene.gravity != protocol.gravity:
        raise SimulationError(
            f"protocol {protocol.name!r} needs a scene with table={protocol.table}, "
            f"gravity={protocol.gravity}; build it with build_scene(..., table=..., gravity=...)")
    openings = pregrasp_opening(scene, widths)
    state0 = initial_states(scene, T_world, openings)
    on_object, on_table = start_overlaps(scene, state0, T_world)
    depth = np.maximum(on_object, on_table)
    collide = depth > scene.settings.start_penetration

    outcome = np.full(n, TrialOutcome.START_COLLISION, np.int8)
    metrics = {k: np.full(n, np.nan) for k in protocol.metric_names}
    todo = np.flatnonzero(~collide)
    chunk = int(chunk or 32 * threads)
    m = scene.model
    obj_q = scene.model.qpos0[scene.qadr_obj:scene.qadr_obj + 7]  # the object at rest
    pool = rollout.Rollout(nthread=threads if threads > 1 else 0) if backend == "rollout" else None
    datas = [mujoco.MjData(m) for _ in range(threads)]

    def run(idx: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        control = protocol.controls(scene, T_world[idx], openings[idx])
        states, sens = simulate(scene, protocol, state0[idx], control, pool=pool, datas=datas, backend=backend)
        rec = _record(scene, states, sens)
        judged = protocol.judge(scene, rec, np.repeat(obj_q[None], len(idx), axis=0))
        if on_record is not None:
            on_record(idx, rec)
        return judged

    try:
        run_in_chunks(todo, chunk, run, outcome, metrics, done=int(collide.sum()), on_progress=on_progress)
    finally:
        if pool is not None:
            pool.close()
    wall = time.perf_counter() - t_start
    sim_seconds = len(todo) * protocol.nstep(m.opt.timestep) * m.opt.timestep
    log.info("%d trials (%d simulated) in %.2f s", n, len(todo), wall)
    return TrialResults(
        outcome=outcome, metrics=metrics, object_in_gripper=protocol.held(outcome).astype(np.int8),
        start_penetration=depth, T_world_wrist=T_world, protocol=protocol.to_dict(),
        scene=scene.info(), seed=int(seed), noise=None if noise is None else noise.to_dict(),
        threads=threads, wall_time=wall, simulated_seconds=sim_seconds,
        start_kind=_start_kinds(on_object, on_table, scene.settings.start_penetration),
    )


def _start_kinds(on_object: np.ndarray, on_table: np.ndarray, tol: float) -> np.ndarray:
    """(N,) what each start collision hit (:func:`collision_kind`): "table" alone, or the
    "object" (the table maybe too); "" where the trial started clear."""
    hits = [((0,) if o > tol else ()) + (("table",) if t > tol else ()) for o, t in zip(on_object, on_table)]
    return np.array([collision_kind(h, None) if h else "" for h in hits], dtype="<U6")
