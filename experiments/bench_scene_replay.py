"""Benchmark: E10's scene frames planned again from the same inputs -- where a frame's
planning time goes, and whether a change to the planner moved it.

**Capture.** E10's episodes (its settings for the kind, its seeds and scenes, its database)
are walked as E10 walks them, the best grasp executed each time, and every
``plan_scene`` call's inputs are saved to ``OUT/frames.pkl``: the cloud, the generator's
state, the settings, the previous frame's plan, the viewpoint and the felt points.
``--frames FILE`` replays a capture made before instead.

**Replay.** Every frame is first planned once, untimed: stored maps are read and each
process's caches warmed. Then every frame is planned ``--rounds`` times in this process
alone (``workers`` 1: no segment worker processes, so this process's CPU time is the whole
planning's, the kernels' threads included). Recorded:

* per frame, the CPU seconds and the wall seconds;
* per segment, its status and seconds. Segments that end with no grasp (``no_grasp``)
  still stream and check their maps in full;
* a digest of each frame's ranked grasps, which tells whether two code versions plan alike.
  A capture also checks that each frame replayed plans as the episode's own call did.

Wall time on a shared or virtual machine varies between runs by more than most changes
move it, so compare CPU times, and replay two versions in turn. The frames file holds this
code version's objects (pickled). Replay it only with a version whose planning settings
and plan records have the same fields.

    python experiments/bench_scene_replay.py --object-set household-heldout --kind pile \
        --seeds 5 --first-seed 1 --walk-seeds 1 --scenes 8 --db /work/runs/s19/fsdb
    python experiments/bench_scene_replay.py --frames OUT/frames.pkl --rounds 3 --db /work/runs/s19/fsdb
    python experiments/bench_scene_replay.py --frames OUT/frames.pkl --unseen-margin 0.03 --db /work/runs/s19/fsdb
    python experiments/bench_scene_replay.py --quick --out results/bench_scene_replay-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import copy
import hashlib
import json
import pickle
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_load, opt, reference_clause, start
from e10_clutter_removal import E10Cases

STATUSES = ("planned", "no_grasp", "reused", "deferred", "failed")


@dataclass(frozen=True)
class Config(E10Cases):
    first_seed: int = opt(0, "the first of E10's seeds walked (an index into its --seeds seeds)")
    walk_seeds: int = opt(1, "how many of E10's seeds are walked, from --first-seed")
    scenes: int = opt(4, "scenes walked per seed (E10's scenes 0, 1, ... of each)")
    frames: str = opt("", "replay this capture (OUT/frames.pkl of an earlier run) instead of capturing")
    rounds: int = opt(2, "timed replays of every frame")
    unseen_margin: float | None = opt(None, "the robust score's margin [m] against an object's unseen back, in the "
                                      "episodes captured and in every frame replayed (E10's --unseen-margin; "
                                      "none: the settings each frame was captured with)")
    QUICK: ClassVar[dict] = {"kind": "packed", "objects": 2, "seeds": 1, "scenes": 1, "object_set": "primitives",
                             "quick_maps": True, "rounds": 1}

    def __post_init__(self) -> None:
        if self.rounds < 1 or self.scenes < 1 or self.walk_seeds < 1:
            raise ValueError("--rounds, --scenes and --walk-seeds must be >= 1")
        if not 0 <= self.first_seed or self.first_seed + self.walk_seeds > self.seeds:
            raise ValueError("--first-seed + --walk-seeds must be <= --seeds (E10's seed count)")


def capture(cfg: Config, db) -> tuple[list[tuple[np.ndarray, dict]], list[str]]:
    """Every ``plan_scene`` call's inputs (cloud, keyword arguments less the database) of
    the walked episodes, copied as the call was made, and the digest of each call's plan."""
    from e10_clutter_removal import _clutter_config, looks

    import graspsim.tabletop.clutter as clutter
    from graspsim.tabletop.clutter import benchmark_episode
    from graspsim.tabletop.clutter_stats import benchmark_seeds

    frames: list[tuple[np.ndarray, dict]] = []
    live: list[str] = []
    plan = clutter.plan_scene

    def recorded(points, **kw):
        frames.append((np.array(points, float), {k: copy.deepcopy(v) for k, v in kw.items() if k != "db"}))
        sp = plan(points, **kw)
        live.append(_digest(sp))
        return sp

    config = _clutter_config({"objects": cfg.objects, "kind": cfg.kind, "noise": cfg.noise, "ablation": None,
                              "object_set": cfg.object_set}, cfg.unseen_margin)
    seeds = benchmark_seeds(cfg.seed, cfg.seeds)[cfg.first_seed:cfg.first_seed + cfg.walk_seeds]
    with mock.patch.object(clutter, "plan_scene", recorded):
        for sd in seeds:
            for i in range(cfg.scenes):
                ep = benchmark_episode(cfg.objects, cfg.kind, sd, i, db=db, config=config,
                                       object_set=cfg.object_set)
                try:
                    for look, g, _, _ in looks(ep):
                        ep.execute(look, g)
                finally:
                    ep.close()
    return frames, live


def _digest(sp) -> str:
    """The frame's ranked grasps (score and pose of the first ten, rounded) as a short hash."""
    rows = [[round(float(g.score), 7), *np.round(np.asarray(g.T_world_wrist, float).ravel(), 7)]
            for g in sp.grasps[:10]]
    return hashlib.sha1(json.dumps(rows).encode()).hexdigest()[:12]


def replay(frames: list[tuple[np.ndarray, dict]], db, rounds: int, unseen_margin: float | None = None) -> dict:
    """Each frame planned once untimed, then ``rounds`` times timed, in this process;
    ``unseen_margin``: each frame's settings with that margin (the path of E10's
    ``--unseen-margin``, :func:`~graspsim.planning.scene_config.with_unseen_margin`), None: as captured."""
    from graspsim.planning.scene import plan_scene
    from graspsim.planning.scene_config import with_unseen_margin

    def one(points, kw):
        kw = {**kw, "rng": copy.deepcopy(kw["rng"]), "previous": copy.deepcopy(kw.get("previous")),
              "config": with_unseen_margin(replace(kw["config"], workers=1), unseen_margin)}
        c0, w0 = time.process_time(), time.perf_counter()
        sp = plan_scene(points, db=db, **kw)
        return sp, time.process_time() - c0, time.perf_counter() - w0

    digests = [_digest(one(p, kw)[0]) for p, kw in frames]
    cpu, wall = np.zeros((rounds, len(frames))), np.zeros((rounds, len(frames)))
    seconds: dict[str, list[float]] = defaultdict(list)
    stages: dict[str, float] = defaultdict(float)
    changed = 0
    for r in range(rounds):
        for f, (p, kw) in enumerate(frames):
            sp, cpu[r, f], wall[r, f] = one(p, kw)
            changed += _digest(sp) != digests[f]
            if r == 0:
                for s in sp.segments:
                    seconds[s.status].append(float(s.seconds))
                for k in ("table", "segment", "identify", "plan"):
                    stages[k] += float(sp.timing.get(k) or 0.0)
    planning = sum(sum(v) for v in seconds.values())
    return {"frames": len(frames), "rounds": rounds, "cpu_s": cpu.tolist(), "wall_s": wall.tolist(),
            "cpu_per_frame": float(cpu.mean()), "wall_per_frame": float(wall.mean()),
            "cpu_per_round": cpu.mean(axis=1).tolist(),
            "stages_per_frame": {k: v / len(frames) for k, v in stages.items()},
            "segments": {s: {"plans": len(seconds[s]), "seconds": float(sum(seconds[s])),
                             "share": float(sum(seconds[s]) / planning) if planning > 0 else 0.0}
                         for s in STATUSES if s in seconds},
            "digests": digests, "replays_unlike_first": int(changed)}


def run(cfg: Config, out: Path) -> dict:
    from e10_clutter_removal import read_only_database

    db = read_only_database(cfg, out)
    live = None
    if cfg.frames:
        with open(cfg.frames, "rb") as fh:
            frames = pickle.load(fh)
        source = cfg.frames
    else:
        frames, live = capture(cfg, db)
        source = str(out / "frames.pkl")
        with open(source, "wb") as fh:
            pickle.dump(frames, fh)
    if not frames:
        raise SystemExit("no frame was captured: every episode ended before its first plan")
    got = replay(frames, db, cfg.rounds, cfg.unseen_margin)
    # a faithful capture: each frame replayed plans as the episode's own call did
    unlike = None if live is None else int(sum(a != b for a, b in zip(live, got["digests"])))
    return {"frames_file": source, "episode_unlike_replay": unlike, **got}


def readme_section(s: dict) -> str:
    seg = ", ".join(f"{k} {v['plans']} plans, {100 * v['share']:.0f} %" for k, v in s["segments"].items())
    st = ", ".join(f"{k} {v:.3f} s" for k, v in s["stages_per_frame"].items())
    load0, load1 = machine_load(s)
    return (f"`{s['command']}`: {s['frames']} frames of `{s['frames_file']}` planned in one process "
            f"({s['rounds']} timed rounds after an untimed one): CPU {s['cpu_per_frame']:.3f} s per frame "
            f"(per round {', '.join(f'{x:.3f}' for x in s['cpu_per_round'])}), wall {s['wall_per_frame']:.3f} s; "
            f"stages per frame (wall) {st}; segment planning by how it ended: {seg}; "
            f"{s['replays_unlike_first']} timed replays planned otherwise than the untimed one"
            + ("" if s.get("episode_unlike_replay") is None else
               f", {s['episode_unlike_replay']} frames otherwise than the episode's own call") + ". "
            f"Load average {load0[0]:.2f} at the start, {load1[0]:.2f} at the end, "
            f"{s['machine']['cpus']} cores{reference_clause(s)}.")


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__, quiet=("graspsim",))
    data = run(cfg, out)
    record.write(out, {"config": cfg, **data}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
