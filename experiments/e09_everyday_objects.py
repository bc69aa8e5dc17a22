"""Experiment E09: everyday objects -- paper vs robust identification, and the grasps in MuJoCo.

Every mesh in ``--objects-dir`` (default ``../shared/objects``: 6 robosuite and 36
pybullet everyday and random objects) rests on a table (z = 0) as physics rests it (its
simulated object put down upright when that looks stable, else on the hull face nearest its
centre of mass, then stepped in MuJoCo until at rest: ``--rest physics``), at a random yaw.
Two clouds per object, both with 1 mm noise: a *full* cloud (uniform surface samples,
3 mm spacing) and a *single view* (a camera 0.6 m away at 40 deg elevation, random
azimuth; the points it sees, noise along the ray; planned with that camera as its
viewpoint: the robust score's occluded-space term). Everything goes through the public
path a user runs, the functions ``graspsim adapt`` and ``graspsim trial`` are layers
over: each cloud is adapted (:func:`graspsim.planning.adapt.adapt_cloud`, ``graspsim adapt CLOUD
--table auto --mode MODE [--viewpoint X Y Z]``; ``--table`` a height instead, e.g. 0 for
the table known) in paper and in robust mode against a private FS database
(``_common.experiment_database``): status, parts, fit rates, time for identification +
adaptation. The map is written (``OUT/maps``), and its 10 best grasps (``graspsim trial
MAP --top 10 --rank robust --mesh MESH``: :func:`graspsim.sim.mapsim.simulate_map`) are
lifted and placed in MuJoCo against the true mesh as it stood (``OUT/meshes``, the
clouds' frame; CoACD convex parts);
a START_COLLISION counts as a failure. *held*: lifted without dropping (success or
PLACE_FAILED: a round object rolls off after release); *placed*: success. With
``--separation-mm`` > 0 the run also simulates the 10 best at least that far apart
(grasp points) or ``--separation-deg`` apart (wrist orientation, jaws swapped counted
the same): non-maximum suppression (:mod:`graspsim.maps.separation`), reported apart.

The held-out set, fixed before any tuning on these meshes (issue 33) and reported apart:
a mesh is held out when the CRC-32 of its path relative to ``--objects-dir`` (e.g.
``pybullet/random_003.stl``) is divisible by 3 (:func:`held_out`) -- blind to the
shapes; 15 of the 42 development meshes (pybullet domino, random_000, 002, 003, 008, 010,
017, 018, 019, 021, 026, teddy; robosuite bottle, lemon, milk). Nothing is to be tuned on
them; random_003 was used (before the split) to find the trial scene's misplaced table.

Which objects fit the gripper is a stated rule, not a choice: an object fits when the
shortest edge of its minimum-volume bounding box (the narrowest width a grasp can close
across) is at most the gripper's opening less the approach clearance on both sides.

    python experiments/e09_everyday_objects.py
    python experiments/e09_everyday_objects.py --quick --objects-dir assets/objects --out results/e09-quick
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import logging
import math
import sys
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import (
    database_note,
    database_record,
    derived_seed,
    experiment_database,
    map_config,
    opt,
    pct,
    rate_ci,
    rng_for,
    start,
    write_json,
)
from _mesh_views import clouds, rest_on_table, rest_physics, rest_stable

from graspsim.errors import InvalidParameterError
from graspsim.maps.database import MapDatabase
from graspsim.maps.io import save_map
from graspsim.maps.match import MatchKind
from graspsim.maps.robust import RANKS
from graspsim.perception.mvbb import min_volume_box
from graspsim.planning.adapt import adapt_cloud, adapt_config
from graspsim.sim import TrialOutcome
from graspsim.sim.mapsim import simulate_map
from graspsim.sim.meshes import load_mesh, surface_model
from graspsim.sim.objects import object_from_mesh
from graspsim.stats import wilson_interval

log = logging.getLogger("e09")

VIEWS = ("full", "single")
MODES = ("paper", "robust")


@dataclass(frozen=True)
class Config:
    objects_dir: str = opt("../shared/objects", "folder of .stl meshes [m]")
    objects: tuple[str, ...] = opt((), "meshes to use, relative to --objects-dir (default: every .stl in it)")
    seed: int = opt(9, "run seed")
    resolution: float = opt(0.003, "point spacing of the clouds [m]")
    noise: float = opt(0.001, "sensor noise sigma [m]")
    max_points: int = opt(12000, "most points of a full cloud")
    camera_distance: float = opt(0.6, "single view: camera distance [m]")
    camera_elevation_deg: float = opt(40.0, "single view: camera elevation [deg]")
    top: int = opt(10, "best grasps of each map simulated")
    rank: str = opt("robust", "the ranking of the grasps simulated (graspsim trial --rank)", choices=RANKS)
    table: str = opt("auto", "the table the clouds were planned with (graspsim adapt --table): 'auto' (the "
                     "object's lowest point, as a user gives it) or a height [m] (0: the table known)")
    threads: int | None = opt(None, "simulation threads (default: all cores)")
    db: str = opt("", "FS database folder (default: OUT/fsdb, built fresh)")
    separation_mm: float = opt(10.0, "also simulate the best grasps at least this far apart [mm] (0: not)")
    separation_deg: float = opt(20.0, "... or this far apart in orientation [deg]")
    rest: str = opt("physics", "resting pose: 'physics' (the 'simulator' pose stepped in MuJoCo until at rest), "
                    "'simulator' (upright when stable, else the hull face nearest the centre of mass; a centre of "
                    "mass over the support's edge tips over once released) or 'stable' (trimesh's most probable "
                    "stable pose)", choices=("physics", "simulator", "stable"))
    mesh_model: str = opt("parts", "the true mesh's collision model in the trials (graspsim trial --mesh-model): "
                          "parts (CoACD's convex parts within the CPU limit, else its hull) or surface (the mesh's "
                          "own surface, a prism per face: cavities kept)", choices=("parts", "surface"))
    unseen_margin: float | None = opt(None, "single views: the robust score's margin against the unseen back [m] "
                                      "(graspsim adapt --unseen-margin M; default: the command's, "
                                      "graspsim.planning.adapt.DEFAULT_UNSEEN_MARGIN in robust mode; 0: none); "
                                      "full clouds have no viewpoint, so none")
    coarse_db: bool = opt(False, "coarse FS maps (1 cm surface step, 22 deg rotations): for smoke runs")
    QUICK: ClassVar[dict] = {"resolution": 0.005, "coarse_db": True, "top": 4}


def held_out(name: str) -> bool:
    """Whether the mesh ``name`` (its path relative to the objects folder) is in the
    held-out set: CRC-32 of the path divisible by 3 (module docstring)."""
    return zlib.crc32(Path(name).as_posix().encode()) % 3 == 0


def object_names(cfg: Config) -> list[str]:
    root = Path(cfg.objects_dir)
    if cfg.objects:
        return list(cfg.objects)
    return sorted(str(p.relative_to(root)) for p in root.rglob("*.stl"))


def fits_gripper(mesh, gripper) -> tuple[bool, float, float]:
    """(fits, narrowest width [m], largest graspable width [m]): the rule of the module
    docstring."""
    width = float(np.min(min_volume_box(np.asarray(mesh.vertices, float)).extents))
    limit = float(gripper.max_opening - 2.0 * gripper.approach_clearance)
    return width <= limit, width, limit


def _sim(map_path: Path, mesh_path: Path, cfg: Config, seed: int, separated: bool = False) -> dict | None:
    """``graspsim trial MAP --top K --rank R --mesh MESH [--separation MM DEG] --seed S``,
    through the function the command is a layer over (:func:`simulate_map`)."""
    sep = (1e-3 * cfg.separation_mm, math.radians(cfg.separation_deg)) if separated else None
    try:
        # the plain run stores its outcomes in the map (as `trial` does); the separated one
        # is `trial --separation MM DEG --no-write` (storing would replace them)
        mesh = surface_model(mesh_path) if cfg.mesh_model == "surface" else mesh_path  # `trial --mesh-model`
        t = simulate_map(map_path, top=cfg.top, rank=cfg.rank, mesh=mesh, seed=seed, threads=cfg.threads,
                         separation=sep, write=not separated)
    except InvalidParameterError:  # nothing to simulate (an empty map): `trial` refuses it too
        return None
    if not len(t.index):
        return None
    out = np.asarray(t.results.outcome)
    placed = int(np.sum(out == TrialOutcome.SUCCESS))
    held = placed + int(np.sum(out == TrialOutcome.PLACE_FAILED))
    n = len(t.index)
    return {"trials": n, "counts": t.results.counts(), "start_collision": int(n - t.results.feasible),
            "placed": placed, "held": held}


def _plan_entry(points, db, mode: str, cfg: Config, viewpoint=None) -> tuple[dict, object]:
    """``graspsim adapt CLOUD --mode MODE --table TABLE --seed S [--viewpoint X Y Z
    [--unseen-margin M]]``, through the functions the command is a layer over
    (:mod:`graspsim.planning.adapt`); the margin only with a viewpoint, as the command
    refuses it without one."""
    margin = cfg.unseen_margin if viewpoint is not None else None  # the command refuses it without a viewpoint
    pc = adapt_config(mode=mode, table=cfg.table, unseen_margin=margin)
    t0 = time.perf_counter()
    res = adapt_cloud(points, db=db, config=pc, seed=cfg.seed, viewpoint=viewpoint)
    wall = time.perf_counter() - t0
    ident = res.identification
    built = any(p.match == MatchKind.BUILD for p in res.parts)
    entry = {"status": res.status.value, "points": len(points),
             "parts": [{"primitive": p.shape.value, "points": p.n_points, "fit_rate": p.fit_rate,
                        "band_rate": p.band_rate, "approximate": p.approximate} for p in ident.parts],
             "unidentified_points": int(sum(p.n_points for p in ident.unidentified)),
             "matches": [p.match.value for p in res.parts], "built": built,
             "identify_s": res.timing.get("identify"), "seconds": wall,
             "grasps": len(res.map), "accepted": int(res.map.accepted.sum())}
    return entry, res


def object_views(name: str, cfg: Config):
    """(simulated object in the mesh's frame -- None with ``--rest stable`` --, mesh resting on the table (world frame,
    the clouds' frame), T_world_mesh, {"full": cloud, "single": cloud}) of one mesh,
    drawn from ``rng_for(cfg.seed, name)``."""
    rng = rng_for(cfg.seed, name)
    path = Path(cfg.objects_dir) / name
    # physics and the simulator's rule need the simulated object (a convex decomposition); trimesh's does not
    # (with --mesh-model surface the rest is the surface's too: a hull rests otherwise)
    model = surface_model(path) if cfg.mesh_model == "surface" else path
    obj = None if cfg.rest == "stable" else object_from_mesh(model)
    rest = {"physics": rest_physics, "simulator": rest_on_table, "stable": rest_stable}[cfg.rest]
    mesh, T_world_mesh = rest(load_mesh(path), obj, rng)
    return obj, mesh, T_world_mesh, clouds(mesh, cfg, rng)


def _file_stem(name: str) -> str:
    return str(Path(name).with_suffix("")).replace("/", "__")


def run_object(name: str, db: MapDatabase, cfg: Config, out: Path) -> tuple[dict, dict]:
    """One object: its row and, for the figure, its clouds with part labels. As a user
    would: the mesh as it stands (the clouds' frame) written to ``out/meshes``, each
    cloud adapted and the map written to ``out/maps``, then simulated against the mesh."""
    obj, mesh, T_world_mesh, cl = object_views(name, cfg)
    ok, width, limit = fits_gripper(mesh, db.gripper)
    stem = _file_stem(name)
    mesh_path = out / "meshes" / f"{stem}.stl"
    mesh_path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(mesh_path)
    (out / "maps").mkdir(parents=True, exist_ok=True)
    row = {"object": name, "held_out": held_out(name), "fits": ok,
            "width": width, "extents": sorted(np.ptp(mesh.vertices, axis=0).tolist())}
    figs = {}
    for view in VIEWS:
        for mode in MODES:
            entry, res = _plan_entry(cl[view], db, mode, cfg, cl["camera"] if view == "single" else None)
            map_path = out / "maps" / f"{stem}.{view}.{mode}.h5"
            entry["sim"] = entry["sim_separated"] = None
            if len(res.map):  # `graspsim adapt` writes no map without grasps
                save_map(res.map, map_path)
                seed = derived_seed(cfg.seed, name, view, mode)
                entry["sim"] = _sim(map_path, mesh_path, cfg, seed)
                if cfg.separation_mm > 0:
                    entry["sim_separated"] = _sim(map_path, mesh_path, cfg, seed, separated=True)
            row[f"{view}/{mode}"] = entry
            figs[f"{view}/{mode}"] = (cl[view], _labels(res, len(cl[view])))
            s = entry["sim"]
            log.info("%-22s %-6s %-6s %-9s %-28s %5.2f s  %s", name, view, mode, entry["status"],
                     "+".join(p["primitive"] for p in entry["parts"]) or "-", entry["seconds"],
                     "no grasps" if s is None else f"held {s['held']}/{s['trials']} placed {s['placed']}/{s['trials']}"
                     f" start-collision {s['start_collision']}")
    return row, figs


def _labels(res, n: int) -> np.ndarray:
    lab = np.full(n, -1)
    for i, p in enumerate(res.identification.parts):
        lab[p.indices] = i
    return lab


def pooled(rows: list[dict], sim: str = "sim") -> dict:
    """Per view and mode over the objects that fit: counts and the trials of ``sim``
    ("sim": the 10 best; "sim_separated": the 10 best a pose apart)."""
    out = {}
    fit = [r for r in rows if r["fits"]]
    for view in VIEWS:
        for mode in MODES:
            es = [r[f"{view}/{mode}"] for r in fit]
            sims = [e.get(sim) for e in es if e.get(sim)]
            n = sum(s["trials"] for s in sims)
            placed, held = sum(s["placed"] for s in sims), sum(s["held"] for s in sims)
            secs = sorted(e["seconds"] for e in es if not e["built"])
            usable = sum(e["accepted"] > 0 for e in es)
            out[f"{view}/{mode}"] = {
                "objects": len(es), "with_grasp": usable,
                "identified": sum(e["status"] == "complete" for e in es),
                "trials": n, "placed": placed, "held": held,
                "start_collision": sum(s["start_collision"] for s in sims),
                "placed_95": list(wilson_interval(placed, n)) if n else None,
                "held_95": list(wilson_interval(held, n)) if n else None,
                "median_s": float(np.median(secs)) if secs else None, "timed": len(secs)}
    return out


def figure(figs: dict, path: Path, key: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(figs)
    cols = 7
    rows = math.ceil(len(names) / cols)
    fig = plt.figure(figsize=(2.2 * cols, 2.2 * rows))
    cmap = plt.get_cmap("tab10")
    for i, name in enumerate(names):
        pts, lab = figs[name][key]
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        sel = np.arange(0, len(pts), max(1, len(pts) // 1500))
        c = np.array([(0.7, 0.7, 0.7, 1.0) if v < 0 else cmap(v % 10) for v in lab[sel]])
        ax.scatter(pts[sel, 0], pts[sel, 1], pts[sel, 2], s=0.5, c=c)
        ax.set_title(Path(name).stem, fontsize=7)
        ax.set_axis_off()
        r = np.ptp(pts, axis=0).max() / 2
        m = pts.mean(axis=0)
        ax.set_xlim(m[0] - r, m[0] + r)
        ax.set_ylim(m[1] - r, m[1] + r)
        ax.set_zlim(m[2] - r, m[2] + r)
    fig.suptitle(f"E09 clouds ({key}), coloured by identified part (grey: not covered)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_table(rows: list[dict], pool: dict) -> str:
    L = ["# E09: everyday objects, paper vs robust identification", "",
         "Per object and cloud: status, parts (`~` approximate), seconds for identification + adaptation, "
         "accepted grasps, and of the 10 best: held / placed / START_COLLISION.", "",
         "| object | fits | view | mode | status | parts | s | accepted | held | placed | start coll. |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        for view in VIEWS:
            for mode in MODES:
                e = r[f"{view}/{mode}"]
                s = e["sim"] or {}
                parts = " + ".join(("~" if p["approximate"] else "") + p["primitive"] for p in e["parts"]) or "-"
                L.append(f"| {Path(r['object']).stem} | {'yes' if r['fits'] else 'no'} | {view} | {mode} | "
                         f"{e['status']} | {parts} | {e['seconds']:.2f}{' (built)' if e['built'] else ''} | "
                         f"{e['accepted']} | {s.get('held', '-')} | {s.get('placed', '-')} | "
                         f"{s.get('start_collision', '-')} |")
    L += ["", "Pooled over the objects that fit the gripper:", "", _pool_table(pool)]
    return "\n".join(L) + "\n"


def _pool_table(pool: dict) -> str:
    L = ["| view | mode | objects with an accepted grasp | identified completely | 10-best trials | held | "
         "placed | start in collision | median s |", "|---|---|---|---|---|---|---|---|---|"]
    for key, p in pool.items():
        view, mode = key.split("/")
        med = "-" if p["median_s"] is None else f"{p['median_s']:.2f}"
        held = rate_ci(p["held"], p["trials"], p["held_95"])
        usable = f"{pct(p['with_grasp'] / p['objects'], 0)} %" if p["objects"] else "n/a"
        start = p["start_collision"] if not p["trials"] else \
            f"{p['start_collision']}/{p['trials']} ({pct(p['start_collision'] / p['trials'])} %)"
        L.append(f"| {view} | {mode} | {p['with_grasp']}/{p['objects']} ({usable}) | "
                 f"{p['identified']}/{p['objects']} | {p['trials']} | {held} | "
                 f"{rate_ci(p['placed'], p['trials'], p['placed_95'])} | {start} | {med} |")
    return "\n".join(L)


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    if not Path(cfg.objects_dir).is_dir():
        print(f"e09: --objects-dir {cfg.objects_dir} is not a folder", file=sys.stderr)
        return 2
    if cfg.unseen_margin is not None and not (math.isfinite(cfg.unseen_margin) and 0 <= cfg.unseen_margin <= 0.1):
        print(f"e09: --unseen-margin must be in [0, 0.1] m (0: off), got {cfg.unseen_margin!r}", file=sys.stderr)
        return 2
    map_cfg = map_config(cfg.coarse_db)
    db = experiment_database(cfg.db, out, map_cfg, threads=cfg.threads)
    db_start = database_record(db)
    rows, figs = [], {}
    for name in object_names(cfg):
        row, f = run_object(name, db, cfg, out)
        rows.append(row)
        figs[name] = f
    pool = pooled(rows)
    pool_sep = pooled(rows, "sim_separated") if cfg.separation_mm > 0 else None
    splits = {"development": pooled([r for r in rows if not r["held_out"]]),
              "held_out": pooled([r for r in rows if r["held_out"]])}
    for key in ("full/robust", "single/robust", "full/paper"):
        figure(figs, out / f"clouds_{key.replace('/', '_')}.png", key)
    (out / "table.md").write_text(write_table(rows, pool))
    data = {"config": cfg, "pooled": pool, "pooled_separated": pool_sep, "splits": splits, "objects": rows,
            "gripper": {"max_opening": db.gripper.max_opening, "approach_clearance": db.gripper.approach_clearance},
            "database": {"start": db_start, "end": database_record(db)}}
    print(run.write(out, data, readme_section))
    write_json(out / "results.json", run.summary(data))
    print(f"results in {out}")
    return 0


def _timing_line(fit: list[dict]) -> str:
    """Median identification time and median identification + adaptation time per mode
    (runs that built a new FS map left out of the latter)."""
    out = []
    for key in ("full/paper", "full/robust", "single/paper", "single/robust"):
        ident = [o[key]["identify_s"] for o in fit]
        total = [o[key]["seconds"] for o in fit if not o[key]["built"]]
        adapted = (f"{np.median(total):.2f} s with adaptation ({len(total)} runs without a build)" if total
                   else "every run built a new FS map (no adaptation time without one)")
        out.append(f"{key.replace('/', ', ')}: {np.median(ident):.2f} s identification, {adapted}")
    return "; ".join(out)


_RANK_TEXT = {"robust": "robust: clearance to the observed cloud under wrist pose error", "paper": "the paper's grade"}


def _outcome_line(fit: list[dict]) -> str:
    """The trial outcomes pooled per view in robust mode (where the failures go)."""
    out = []
    for key in ("full/robust", "single/robust"):
        counts: dict[str, int] = {}
        for o in fit:
            for k, v in ((o[key]["sim"] or {}).get("counts") or {}).items():
                counts[k] = counts.get(k, 0) + v
        out.append(f"{key.split('/')[0]}: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    return "; ".join(out)


def _separated_line(s: dict) -> str:
    """The 10 best at least a pose apart (non-maximum suppression), robust mode."""
    cfg, out = s["config"], []
    for key in ("full/robust", "single/robust"):
        p = s["pooled_separated"][key]
        out.append(f"{'full clouds' if key.startswith('full') else 'single views'} "
                   f"{rate_ci(p['placed'], p['trials'], p['placed_95'])} placed, "
                   f"{p['start_collision']} START_COLLISION")
    return (f"The same maps' {cfg['top']} best with non-maximum suppression (`graspsim.maps.separation`: each "
            f"grasp point at least {cfg['separation_mm']:g} mm or the wrist {cfg['separation_deg']:g} deg from every "
            f"better one kept), robust mode: " + "; ".join(out) + ". The table above is the plain 10 best.")


#: issue 33's goals, robust mode: (usable maps, ten best placed, START_COLLISION share at most)
GOALS = {"full/robust": (0.95, 0.95, 0.02), "single/robust": (0.90, 0.90, None)}


def _splits_text(s: dict) -> str:
    """The development and held-out meshes apart (robust mode), against issue 33's goals."""
    L = ["Robust mode, the development meshes and the held-out third apart (held out: CRC-32 of the path "
         "divisible by 3, fixed before any tuning), against issue 33's goals (full clouds: usable maps >= 95 %, "
         "ten best placed >= 95 %, START_COLLISION <= 2 % of attempts; single views: >= 90 % / >= 90 %):", "",
         "| meshes | view | usable maps | ten best placed | START_COLLISION | goals met |", "|---|---|---|---|---|---|"]
    for split, pool in s["splits"].items():
        for key, (g_use, g_place, g_sc) in GOALS.items():
            p = pool[key]
            if not p["objects"]:
                continue
            use, n = p["with_grasp"] / p["objects"], p["trials"]
            place = p["placed"] / n if n else 0.0
            sc = p["start_collision"] / n if n else 0.0
            met = use >= g_use and place >= g_place and (g_sc is None or sc <= g_sc)
            L.append(f"| {split.replace('_', '-')} ({p['objects']}) | {key.split('/')[0]} | "
                     f"{p['with_grasp']}/{p['objects']} ({pct(use, 0)} %) | "
                     f"{rate_ci(p['placed'], n, p['placed_95'])} | {p['start_collision']}/{n} ({pct(sc)} %) | "
                     f"{'yes' if met else 'no'} |")
    return "\n".join(L)


def _margin_text(cfg: dict) -> str:
    """How the run's single views were planned against their unseen back (runs before the
    option record none)."""
    if "unseen_margin" not in cfg:
        return ""
    m = cfg["unseen_margin"]
    if m is None:
        from graspsim.planning.adapt import DEFAULT_UNSEEN_MARGIN

        return (", single views with `graspsim adapt`'s default unseen margin "
                f"(robust mode: {DEFAULT_UNSEEN_MARGIN:g} m)")
    return ", single views without the unseen margin (`--unseen-margin 0`)" if m == 0 else \
        f", single views with `--unseen-margin {m:g}`"


def _table_text(cfg: dict) -> str:
    t = cfg.get("table")
    if t is None:  # runs before the public path: the table known at z = 0
        return "planned with the table known"
    return "planned with `--table auto` (the object's lowest point, as a user gives it)" if t == "auto" else \
        f"planned with the table at {t} m (`--table {t}`)"


def readme_section(s: dict) -> str:
    """The README's E09 paragraph (see ``experiments/report.py``)."""
    objs, pool, cfg = s["objects"], s["pooled"], s["config"]
    fit = [o for o in objs if o["fits"]]
    g = s["gripper"]
    load = s["machine"]["load_avg_start"], s["machine"]["load_avg_end"]
    public = "table" in cfg  # runs through the public path (issue 33) record their table
    rest = {"stable": "on its most probable stable face (trimesh's stable poses)",
            "physics": "as physics rests it (put down, then stepped in MuJoCo until at rest)"}.get(
        cfg.get("rest"), "as the simulator rests it")
    path = (", through the public path (`graspsim adapt` -> map file -> `graspsim trial --mesh`: "
            "`graspsim.planning.adapt.adapt_cloud`, `graspsim.sim.mapsim.simulate_map`)") if public else ""
    surface = cfg.get("mesh_model") == "surface"
    best = (f"The adapted map's {cfg['top']} best grasps (`trial --top {cfg['top']} --rank {cfg['rank']}"
            f"{' --mesh-model surface' if surface else ''}`: {_RANK_TEXT[cfg['rank']]}) lifted and placed in MuJoCo "
            "against the true mesh standing where the cloud was"
            + (" (simulated as its own surface, a prism per face: cavities kept)" if surface else "")
            + "; ") if public else (
        f"The adapted map's {cfg['top']} best accepted grasps by the planner's ranking "
        f"({_RANK_TEXT[cfg.get('rank', 'robust')]}) lifted and placed in MuJoCo against the true mesh; ")
    L = [f"`{s['command']}`: {len(objs)} meshes, each resting on a table {rest}, at a random yaw; "
         f"a full cloud ({1000 * cfg['resolution']:g} mm spacing) and a single view, both with "
         f"{1000 * cfg['noise']:g} mm noise, {_table_text(cfg)}"
         + _margin_text(cfg)
         + f", in paper and robust mode{path}. "
         f"{len(fit)} of {len(objs)} fit the gripper (rule: the shortest edge of the mesh's minimum-volume box is "
         f"at most the opening less the clearance, {1000 * (g['max_opening'] - 2 * g['approach_clearance']):.0f} mm). "
         + best +
         "START_COLLISION counts as a failure; *held*: lifted and carried (success or PLACE_FAILED: a round "
         "object may roll off after release), *placed*: success. Median s: identification + adaptation per "
         "object, runs that built a new FS map left out.",
         "", _pool_table(pool), ""]
    L.append(f"Outcomes of the 10-best trials in robust mode: {_outcome_line(fit)}.")
    if s.get("splits"):
        L += ["", _splits_text(s), ""]
    if s.get("pooled_separated"):
        L += ["", _separated_line(s), ""]
    L.append("")
    miss = {k: [Path(o["object"]).stem for o in fit if o[k]["accepted"] == 0] for k in ("full/robust", "single/robust")}
    L.append(f"Robust mode, no accepted grasp: full cloud {', '.join(miss['full/robust']) or 'none'}; "
             f"single view {', '.join(miss['single/robust']) or 'none'}. Medians: {_timing_line(fit)}. "
             f"Load average {load[0][0]:.1f} at the start, {load[1][0]:.1f} at the end, on "
             f"{s['machine']['cpus']} cores shared with other work." + database_note(s))
    return "\n".join(L) + "\n"


def headline(s: dict) -> str:
    """The README's headline line (see ``experiments/report.py``): robust mode through the
    public path, full clouds and single views, development and held-out meshes apart."""
    parts = []
    for split, pool in s["splits"].items():
        cells = []
        for key, what in (("full/robust", "full clouds"), ("single/robust", "single views")):
            p = pool[key]
            cells.append(f"{what} {p['with_grasp']}/{p['objects']} usable, "
                         f"{rate_ci(p['placed'], p['trials'])} of the 10 best placed, "
                         f"{p['start_collision']} START_COLLISION")
        label = {"development": "Development", "held_out": "Held out"}.get(split, split)
        parts.append(f"{label} ({pool['full/robust']['objects']} meshes): " + "; ".join(cells))
    return (f"{len(s['objects'])} everyday and random meshes, each resting on a table, through `graspsim adapt "
            "--table auto` and `graspsim trial --top 10 --mesh` (1 mm noise; single views with their camera as "
            "viewpoint): " + ". ".join(parts) + ".")


if __name__ == "__main__":
    raise SystemExit(main())
