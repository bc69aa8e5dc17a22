"""Study: objects that are not primitives, through the commands a user runs (issue 33, item 6).

A test bed of objects the project never tuned on, chosen for how primitives fail on
them: development meshes (``--meshes`` under ``--objects-dir``: a mug, a duck, a teddy,
a bottle, a lemon, bread, irregular random shapes), each resting on its most stable face
(trimesh's stable poses, the most probable) at a random yaw, and procedural ones
(``--procedural``, ``experiments/_procedural.py``: a 2 mm thin-walled 15 cm bowl, a
clamp, scissors and a hammer lying flat, a rounded box, a curved banana-like tube, and a
tall box as a primitive control). For each: a full cloud of ``--points`` uniform surface
samples with ``--noise`` Gaussian noise, saved as ``.npy``, then exactly what a user runs,
each in a fresh process:

    graspsim adapt CLOUD.npy -o MAP.h5 --table auto --db OUT/fsdb --json
    graspsim trial MAP.h5 --top 10 --mesh OBJECT.stl --json

Recorded per object: a usable map (adapt wrote one: it has a grasp), its grasps (and how
many have a grade > 0.7), the parts
identified, how well they explain the cloud (the map's ``fit`` record where the planner
writes one), the outcome of each of the ten best (START_COLLISION counts as a failed
attempt, never a smaller denominator), and how many of the ten best have fingers that
contain observed points at their nominal pose (the map's robust ``clearance`` < 0, or
unscored). The FS map database is ``OUT/fsdb``, built fresh from the paper's five shapes
(``experiment_database``), so the run does not depend on what ran before.

    python experiments/study_non_primitive.py
    python experiments/study_non_primitive.py --quick --out results/study_non_primitive-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import database_record, experiment_database, map_config, md_table, opt, rng_for, run_cli_fresh, start
from _mesh_views import surface_points
from _procedural import PROCEDURAL, make

log = logging.getLogger("study_non_primitive")

MESHES = ("pybullet/mug.stl", "pybullet/duck.stl", "pybullet/teddy.stl", "robosuite/bottle.stl",
          "robosuite/lemon.stl", "robosuite/bread.stl", "pybullet/random_003.stl", "pybullet/random_019.stl")


@dataclass(frozen=True)
class Config:
    objects_dir: str = opt("../shared/objects", "folder of the development meshes [m]")
    meshes: tuple[str, ...] = opt(MESHES, "development meshes, relative to --objects-dir")
    procedural: tuple[str, ...] = opt(tuple(PROCEDURAL), f"procedural objects, of {list(PROCEDURAL)}")
    points: int = opt(6000, "surface samples of each full cloud")
    noise: float = opt(0.001, "sensor noise sigma [m]")
    top: int = opt(10, "best grasps of each map simulated (graspsim trial --top)")
    seed: int = opt(33, "run seed (poses, clouds, the CLI's --seed)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    coarse_db: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations): for smoke runs")
    QUICK: ClassVar[dict] = {"meshes": (), "procedural": ("bowl", "clamp"), "top": 3,
                             "points": 3000, "coarse_db": True}


def resting(name: str, cfg: Config, rng: np.random.Generator):
    """The object ``name`` resting on the table (z = 0) at a random yaw, centred."""
    import trimesh

    if name in PROCEDURAL:
        mesh = make(name)
    else:
        mesh = trimesh.load(Path(cfg.objects_dir) / name, force="mesh")
        poses, prob = trimesh.poses.compute_stable_poses(mesh)
        mesh.apply_transform(poses[int(np.argmax(prob))])
    a = rng.uniform(0.0, 2.0 * math.pi)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(a, [0.0, 0.0, 1.0]))
    c = mesh.bounds.mean(axis=0)
    mesh.apply_translation([-c[0], -c[1], -mesh.bounds[0, 2]])
    return mesh


def _cli(args: list[str]) -> tuple[int, dict | None, str]:
    r = run_cli_fresh(args)
    try:
        data = json.loads(r["stdout"]) if r["stdout"].strip() else None
    except json.JSONDecodeError:
        data = None
    return r["exit"], data, r["stderr"].strip().splitlines()[-1] if r["stderr"].strip() else ""


def _fingers_in_cloud(map_path: Path, top: int) -> dict:
    """Of the map's ``top`` best (the order ``trial --top`` simulates): how many have
    fingers containing observed points at the nominal pose (clearance < 0), how many
    were never checked against the cloud (clearance NaN)."""
    from graspsim.maps import load_map
    from graspsim.sim.mapsim import select_grasps

    m = load_map(map_path)
    rows = select_grasps(m, top=top)
    c = np.asarray(m.clearance[rows], float)
    return {"in_cloud": int(np.sum(c < 0)), "unchecked": int(np.sum(~np.isfinite(c))), "of": len(rows)}


def run_object(name: str, cfg: Config, out: Path, db_root: Path, gen_flags: list[str]) -> dict:
    rng = rng_for(cfg.seed, name)
    mesh = resting(name, cfg, rng)
    stem = Path(name).stem
    mesh_path, cloud_path, map_path = out / "objects" / f"{stem}.stl", out / "clouds" / f"{stem}.npy", \
        out / "maps" / f"{stem}.h5"
    for p in (mesh_path, cloud_path, map_path):
        p.parent.mkdir(parents=True, exist_ok=True)
    map_path.unlink(missing_ok=True)
    mesh.export(mesh_path)
    cloud = surface_points(mesh, cfg.points, rng) + rng.normal(0.0, cfg.noise, (cfg.points, 3))
    np.save(cloud_path, cloud)
    row = {"object": name, "extents_mm": sorted((1e3 * mesh.extents).round(1).tolist())}
    code, s, err = _cli(["adapt", str(cloud_path), "-o", str(map_path), "--table", "auto", "--db", str(db_root),
                         "--seed", str(cfg.seed), "--json", *gen_flags])
    row["adapt_exit"] = code
    row["adapt_error"] = err if code else ""
    if s is not None:
        row["parts"] = [f"{p['primitive']}" + ("~" if p.get("approximate") else "") for p in s.get("parts", [])]
        row["accepted"] = s.get("accepted", 0)
        row["grasps"] = f"{s.get('grasps', 0)} ({row['accepted']})"
        row["fit"] = s.get("fit")
    row["usable"] = bool(code == 0 and map_path.exists())
    if not row["usable"]:
        log.info("%-22s no usable map (%s)", name, err)
        return row
    row["fingers"] = _fingers_in_cloud(map_path, cfg.top)
    code, t, err = _cli(["trial", str(map_path), "--top", str(cfg.top), "--mesh", str(mesh_path),
                         "--seed", str(cfg.seed), "--json"])
    if code or t is None:
        row["trial_error"] = err
        log.info("%-22s trial failed: %s", name, err)
        return row
    counts = t["counts"]
    row["trials"] = t["trials"]
    row["counts"] = counts
    row["placed"] = int(counts.get("success", 0))
    row["start_collision"] = int(counts.get("start_collision", 0))
    log.info("%-22s %-34s placed %d/%d start-collision %d fingers-in-cloud %d/%d fit %s", name,
             "+".join(row["parts"]), row["placed"], row["trials"], row["start_collision"],
             row["fingers"]["in_cloud"], row["fingers"]["of"], _fit_text(row.get("fit")))
    return row


def _fit_text(fit: dict | None) -> str:
    if not fit:
        return "n/a"
    return (f"{fit['score']:.2f} ({100 * fit['explained']:.0f} % of points explained, {100 * fit['covered']:.0f} % of "
            f"the parts covered, p95 {1e3 * fit['p95']:.1f} mm)")


def run(cfg: Config, out: Path) -> dict:
    bad = sorted(set(cfg.procedural) - set(PROCEDURAL))
    if bad:
        raise SystemExit(f"unknown procedural objects {bad}; valid: {list(PROCEDURAL)}")
    mc = map_config(cfg.coarse_db)
    db = experiment_database(cfg.db or None, out, mc)
    gen_flags = ["--surface-step", str(mc.surface_step), "--rotation-step-deg", str(math.degrees(mc.rotation_step))]
    start_maps = database_record(db)
    rows = [run_object(n, cfg, out, db.root, gen_flags) for n in (*cfg.meshes, *cfg.procedural)]
    sims = [r for r in rows if "trials" in r]
    n = sum(r["trials"] for r in sims)
    pooled = {"objects": len(rows), "usable": sum(r["usable"] for r in rows), "trials": n,
              "placed": sum(r["placed"] for r in sims),
              "held": sum(r["placed"] + r["counts"].get("place_failed", 0) for r in sims),
              "start_collision": sum(r["start_collision"] for r in sims),
              "fingers_in_cloud": sum(r["fingers"]["in_cloud"] for r in sims),
              "objects_with_a_placed_grasp": sum(r["placed"] > 0 for r in sims)}
    return {"rows": rows, "pooled": pooled, "database": {"start": start_maps, "end": database_record(db)}}


def readme_section(summary: dict) -> str:
    rows = []
    for r in summary["rows"]:
        held = r["placed"] + r["counts"].get("place_failed", 0) if "trials" in r else 0
        sim = (f"{r['placed']}/{r['trials']}", f"{held}/{r['trials']}", f"{r['start_collision']}/{r['trials']}",
               f"{r['fingers']['in_cloud']}/{r['fingers']['of']}") if "trials" in r else ("-",) * 4
        rows.append((r["object"], "yes" if r["usable"] else "no", r.get("grasps", "-"),
                     "+".join(r.get("parts", [])) or "-", _fit_text(r.get("fit")), *sim))
    p = summary["pooled"]
    sims = [r for r in summary["rows"] if "trials" in r]
    p.setdefault("held", sum(r["placed"] + r["counts"].get("place_failed", 0) for r in sims))
    head = (f"`{summary['command']}`: {p['objects']} objects, full clouds; usable maps {p['usable']}/{p['objects']}; "
            f"the ten best placed {p['placed']}/{p['trials']} (held {p['held']}), "
            f"START_COLLISION {p['start_collision']}/{p['trials']}, "
            f"fingers containing observed points {p['fingers_in_cloud']}/{p['trials']}; "
            f"{p['objects_with_a_placed_grasp']} objects with a placed grasp. (`~`: an approximate part.)\n\n")
    return head + md_table(["object", "usable", "grasps (> 0.7)", "parts", "fit", "placed", "held", "start collision",
                            "fingers in cloud"], rows)


def main(argv=None) -> int:
    cfg, out, record = start(Config, __file__, argv, __doc__)
    res = run(cfg, out)
    record.write(out, {"config": cfg, **res}, readme_section)
    print(readme_section(json.loads((out / "summary.json").read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
