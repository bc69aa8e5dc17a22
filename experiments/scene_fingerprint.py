"""A fingerprint of scene planning's results, to check that a change meant only to be
faster changes no result.

Plans the first frame of ``--scenes`` scenes (``--objects`` objects of ``--object-set``) of each kind as E10 renders and
plans them (its camera, sensor noise and scene settings, the camera's position as the
viewpoint; ``plan_scene`` in this process, ``workers=1``) against an FS map database,
and writes, per frame, a SHA-256 of every result field: the segment labels; per segment
its identified parts (kind, pose, every dimension), status, why it failed, the grasps
scored and its solid samples; the ranked grasps (segment, pose, opening, score, grade,
clearance), all to the bit. ``--compare`` names an earlier fingerprint: the fields that
differ are listed and the script exits 1 when any does.

The database must hold every map the frames need beforehand (a map built during the run
would make the next run differ): run once to fill it, then fingerprint the code before
and after the change against it. An older checkout's code is fingerprinted by putting it
first on ``PYTHONPATH`` (``code`` in the summary records which graspsim ran).

    python experiments/scene_fingerprint.py --db results/e10-fsdb --out results/fp-before
    python experiments/scene_fingerprint.py --db results/e10-fsdb --out results/fp-after \\
        --compare results/fp-before/summary.json
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import hashlib
import json
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import database_record, experiment_database, map_config, opt, rng_for, start

log = logging.getLogger("scene_fingerprint")


@dataclass(frozen=True)
class Config:
    scenes: int = opt(12, "scenes of each kind")
    seed: int = opt(100, "first scene seed")
    kinds: tuple[str, ...] = opt(("pile", "packed"), "scene kinds", choices=("pile", "packed"))
    object_set: str = opt("mixed", "the scenes' object set: a named set (household-tuning, primitives, ...) "
                                   "or a folder of meshes")
    objects: int = opt(5, "objects per scene")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse FS maps (for smoke runs)")
    compare: str = opt("", "an earlier fingerprint's summary.json: list the fields that differ")

    def __post_init__(self) -> None:
        if self.scenes < 1:
            raise ValueError("--scenes must be >= 1")
        if not 1 <= self.objects <= 10:
            raise ValueError("--objects must be in [1, 10]")
        from graspsim.tabletop.scene_objects import check_object_set

        check_object_set(self.object_set)


def _h(*parts) -> str:
    """SHA-256 of the parts' bytes (arrays as they are in memory, the rest as text)."""
    d = hashlib.sha256()
    for p in parts:
        d.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
    return d.hexdigest()


def fingerprint(kind: str, seed: int, db, object_set: str = "mixed", objects: int = 5) -> dict:
    """The hashes of one frame's planning results."""
    from dataclasses import replace

    from graspsim.geometry.camera import backproject, rig
    from graspsim.planning.scene import plan_scene
    from graspsim.tabletop.clutter import ClutterConfig, scene_settings
    from graspsim.tabletop.table_scene import make_scene

    camera = rig(1)[0]
    sim = make_scene(objects, kind, seed, object_set=object_set).sim()
    frame = sim.render(camera, noise=ClutterConfig().depth_noise, rng=rng_for(seed, "depth"))
    sim.close()
    sp = plan_scene(backproject(frame).world(), db=db, rng=rng_for(seed, "plan"),
                    config=replace(scene_settings(kind), workers=1),
                    viewpoint=camera.T_world_camera[:3, 3])  # as E10 plans: the occluded space counts
    segments = []
    for m in sp.memory:
        parts = [] if m.ident is None else [
            (p.shape.value, np.asarray(p.T_world_obj, float), sorted((k, float(v)) for k, v in p.dims.items()))
            for p in m.ident.parts]
        segments.append(_h(m.points, *[x for part in parts for x in part], m.why, m.plan.status, m.plan.scored,
                           np.zeros(0) if m.solids is None else m.solids))
    grasps = [x for g in sp.grasps for x in (g.segment, g.T_world_wrist, g.opening, g.score, g.grade, g.clearance)]
    return {"kind": kind, "seed": seed, "object_set": object_set, "objects": objects,
            "labels": _h(sp.perception.segment), "segments": segments,
            "grasps": _h(*grasps), "n_segments": len(segments), "n_grasps": len(sp.grasps)}


def _code() -> dict:
    """Where the graspsim this run imported lives, and its commit (the harness records the
    experiments folder's, which differs when an older checkout's code is fingerprinted
    with ``PYTHONPATH``)."""
    import subprocess


    where = Path(graspsim.__file__).resolve().parent
    try:
        commit = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True,
                                cwd=where, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"graspsim": str(where), "commit": commit}


def differences(a: list[dict], b: list[dict]) -> list[str]:
    """The fields of frames that differ between two fingerprints (frames by kind and seed)."""
    old = {(f["kind"], f["seed"], f.get("object_set", "mixed"), f.get("objects", 5)): f for f in a}
    out = []
    for f in b:
        g = old.get((f["kind"], f["seed"], f.get("object_set", "mixed"), f.get("objects", 5)))
        if g is None:
            out.append(f"{f['kind']} {f['seed']}: not in the other fingerprint")
            continue
        out += [f"{f['kind']} {f['seed']}: {k}" for k in ("labels", "segments", "grasps") if f[k] != g[k]]
    return out


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__, quiet=("graspsim",))
    db = experiment_database(cfg.db or None, out, map_config(cfg.coarse_db))
    before = database_record(db)
    frames = [fingerprint(kind, cfg.seed + i, db, cfg.object_set, cfg.objects)
              for kind in cfg.kinds for i in range(cfg.scenes)]
    after = database_record(db)
    if after != before:
        log.warning("maps were built during the run: a second run against this database may differ")
    data = {"config": cfg, "frames": frames, "database": {"start": before, "end": after}, "code": _code()}
    if cfg.compare:
        other = json.loads(Path(cfg.compare).read_text())
        data["differences"] = differences(other["frames"], frames)
    record.write(out, data)
    diffs = data.get("differences")
    if diffs is None:
        print(f"{len(frames)} frames fingerprinted: {out / 'summary.json'}")
        return 0
    print(f"{len(frames)} frames, {len(diffs)} differing fields against {cfg.compare}")
    for d in diffs:
        print("  " + d)
    return 1 if diffs else 0


if __name__ == "__main__":
    raise SystemExit(main())
