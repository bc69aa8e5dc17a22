"""E09's failed grasps judged against the true mesh: what went wrong, grouped by mechanism.

Reads an E09 output folder (``experiments/e09_everyday_objects.py --out RUN``: its
``config.json``, ``results.json``, ``maps/`` and ``meshes/``), regenerates each object's
clouds from the run's config (E09's ``object_views``: the same seed, the same clouds), and
for every robust-mode map's simulated grasps that failed measures at the planned wrist pose
and opening (the map's row, its robust score's extra opening), against the true mesh as it
stood (the clouds' frame):

* the finger samples inside the true mesh (> 1 mm), split into those in space the camera
  did not see (single views: behind the observed surface along the rays, ``ViewDepth``) and
  those it saw; the deepest one; how far they lie from the observed points and from the
  fitted primitives' surface samples;
* the finger samples below the table (z < 0).

Mechanisms (one per failed grasp): ``start: unseen side`` (the finger in the true mesh only
where the view did not see), ``start: seen side, off the cloud`` (in the true mesh where the
view saw, yet > 3 mm from every observed point: a thin part or an edge the sampling missed),
``start: seen side, at the cloud`` (at observed points: the robust score let it through),
``start: table``, ``start: model only`` (nothing of the true mesh in the fingers at the planned
pose: the simulation's convex parts), and for the others the trial's outcome, marked ``true mesh
wider than planned`` where the true mesh between the pads spans more than 6 mm beyond the planned
contact width along the closing axis (the back went on past the fit). An object with
no accepted grasp counts as ``no usable map``, with its parts.

    python experiments/study_e09_failures.py --run /work/runs/e09gen/before-el20
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import opt, start, write_json

log = logging.getLogger("study_e09_failures")

INSIDE = 0.001  # [m] a finger sample this deep inside the true mesh counts as inside
NEAR = 0.003  # [m] a sample this near an observed point lies "at the cloud"
WIDER = 0.006  # [m] the true mesh between the pads this much wider than the planned contact width: "wider"


@dataclass(frozen=True)
class Config:
    run: str = opt("", "an E09 output folder (development meshes only)")
    views: tuple[str, ...] = opt(("full", "single"), "the views to judge", choices=("full", "single"))


def finger_samples(gripper, T: np.ndarray, opening: float, n=(7, 5, 9)) -> np.ndarray:
    """The finger boxes' grids of samples in the cloud frame at wrist pose ``T``, pad gap ``opening``."""
    b = gripper.collision_boxes()
    out = []
    for name, c, h, s in zip(b.names, b.centers, b.half_extents, b.x_sign):
        if name.startswith("finger"):
            g = np.stack(np.meshgrid(*[np.linspace(-hh, hh, k) for hh, k in zip(h, n)], indexing="ij"),
                         -1).reshape(-1, 3) + c
            g[:, 0] += s * 0.5 * opening
            out.append(g @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(out)


def judge(gmap, rows, outcome, mesh, cloud, viewpoint) -> list[dict]:
    """One record per failed row: its mechanism and measures (module docstring)."""
    import trimesh
    from scipy.spatial import cKDTree

    from graspsim.maps._robust_geometry import object_points
    from graspsim.maps.occlusion import ViewDepth
    from graspsim.maps.robust import executed_width
    from graspsim.sim import TrialOutcome
    from graspsim.sim.mapsim import map_gripper
    from graspsim.transforms import make_transform, quat_to_matrix

    g = map_gripper(gmap)
    T_co = gmap.meta.placement.T_cloud_obj
    prim = object_points(gmap.meta, 0.003)
    prim = prim @ T_co[:3, :3].T + T_co[:3, 3] if len(prim) else prim
    tree_cloud = cKDTree(cloud)
    tree_prim = cKDTree(prim) if len(prim) else None
    view = ViewDepth(cloud, viewpoint) if viewpoint is not None else None
    S = trimesh.sample.sample_surface_even(mesh, 20000, seed=0)[0]
    out = []
    for row, o in zip(rows, outcome):
        o = TrialOutcome(int(o))
        T = T_co @ make_transform(quat_to_matrix(gmap.wrist_quat[row].astype(float)),
                                  gmap.wrist_position[row].astype(float))
        opening = float(g.pregrasp_opening(np.asarray([executed_width(gmap, [row])[0]]))[0])
        P = finger_samples(g, T, opening)
        d = trimesh.proximity.signed_distance(mesh, P)  # > 0 inside
        inside = d > INSIDE
        occ = view.occluded(P) if view is not None else np.zeros(len(P), bool)
        d_cloud = tree_cloud.query(P)[0]
        d_prim = tree_prim.query(P)[0] if tree_prim is not None else np.full(len(P), np.inf)
        r = {"row": int(row), "outcome": o.label, "opening_mm": 1000 * opening,
             "robust": float(gmap.robust[row]), "in_true": int(inside.sum()),
             "in_true_unseen": int((inside & occ).sum()), "depth_mm": 1000 * float(max(d.max(), 0.0)),
             "below_table": int((P[:, 2] < -INSIDE).sum())}
        if inside.any():
            r["inside_to_cloud_mm"] = 1000 * float(d_cloud[inside].min())
            r["inside_to_primitives_mm"] = 1000 * float(d_prim[inside].min())
        if view is not None:  # the planned contacts: hidden from the camera? the closing axis against the sight line
            C = gmap.contacts[row].astype(float) @ T_co[:3, :3].T + T_co[:3, 3]
            r["contacts_unseen"] = int(view.occluded(C).sum())
            r["contact_to_cloud_mm"] = 1000 * float(tree_cloud.query(C)[0].max())
            sight = C.mean(axis=0) - view.viewpoint
            r["closing_sight_cos"] = float(abs(T[:3, 0] @ sight) / np.linalg.norm(sight))
        if o != TrialOutcome.START_COLLISION:  # what of the true mesh lies between the pads (wrist frame)
            W = np.linalg.inv(T)
            Sw = S @ W[:3, :3].T + W[:3, 3]
            between = ((np.abs(Sw[:, 1]) <= 0.5 * g.finger_size[1]) & (Sw[:, 2] >= g.jaw_base_z)
                       & (Sw[:, 2] <= g.fingertip_z) & (np.abs(Sw[:, 0]) <= 0.5 * opening + 0.002))
            r["planned_width_mm"] = 1000 * float(gmap.width[row])
            r["true_between"] = int(between.sum())
            if between.any():
                x = Sw[between]
                r["true_width_mm"] = 1000 * float(np.ptp(x[:, 0]))
                r["true_below_tip_mm"] = 1000 * float(g.fingertip_z - x[:, 2].max())
        if o == TrialOutcome.SUCCESS:
            m = "success"
        elif o == TrialOutcome.START_COLLISION:
            if inside.any():
                seen = inside & ~occ
                if not seen.any():
                    m = "start: unseen side"
                elif d_cloud[seen].min() > NEAR:
                    m = "start: seen side, off the cloud"
                else:
                    m = "start: seen side, at the cloud"
            elif r["below_table"]:
                m = "start: table"
            else:
                m = "start: model only"
        elif r.get("true_width_mm", 0.0) > r["planned_width_mm"] + 1000 * WIDER:
            m = f"{o.label}: true mesh wider than planned"
        else:
            m = o.label
        r["mechanism"] = m
        r["failed"] = o != TrialOutcome.SUCCESS
        out.append(r)
    return out


def run(cfg: Config) -> dict:
    import e09_everyday_objects as e09
    import trimesh

    from graspsim.maps.io import load_map, read_sim_results

    root = Path(cfg.run)
    rc = json.loads((root / "config.json").read_text())
    ecfg = e09.Config(**{k: tuple(v) if isinstance(v, list) else v for k, v in rc.items()
                         if k in e09.Config.__dataclass_fields__})
    res = json.loads((root / "results.json").read_text())
    rows_out, groups, every = [], {}, []
    for obj in res["objects"]:
        name = obj["object"]
        if e09.held_out(name):
            raise ValueError(f"{name} is a held-out mesh: judge development meshes only")
        if not obj["fits"]:
            continue
        stem = e09._file_stem(name)
        mesh = trimesh.load(root / "meshes" / f"{stem}.stl", force="mesh")
        cl = None
        for view in cfg.views:
            e = obj[f"{view}/robust"]
            key = f"{view}"
            if e["accepted"] == 0 or not e.get("sim"):
                groups.setdefault(key, {}).setdefault("no usable map", []).append(Path(name).stem)
                continue
            if cl is None:
                cl = e09.object_views(name, ecfg)[3]
            path = root / "maps" / f"{stem}.{view}.robust.h5"
            gmap = load_map(path)
            sim = read_sim_results(path)
            rows = np.flatnonzero(np.asarray(sim["simulated"], bool))
            recs = judge(gmap, rows, np.asarray(sim["outcome"])[rows], mesh, cl[view],
                         cl["camera"] if view == "single" else None)
            for r in recs:
                if not r["failed"]:
                    continue
                r.update(object=Path(name).stem, view=view,
                         parts="+".join(p["primitive"] for p in e["parts"]))
                groups.setdefault(key, {}).setdefault(r["mechanism"], []).append(Path(name).stem)
                log.info("%-12s %-6s %-34s %s", Path(name).stem, view, r["mechanism"],
                         {k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()
                          if k not in ("object", "view", "mechanism")})
            rows_out += [r for r in recs if r["failed"]]
            every += [{**r, "object": Path(name).stem, "view": view} for r in recs]
    counts = {v: {m: {"n": len(o), "objects": dict(sorted({x: o.count(x) for x in o}.items()))}
                  for m, o in sorted(gr.items())} for v, gr in groups.items()}
    return {"run": str(root), "run_config": rc, "counts": counts, "failures": rows_out, "trials": every}


def readme_section(s: dict) -> str:
    L = [f"Failures of `{s['run']}` (robust mode) by mechanism:", ""]
    for view, gr in s["counts"].items():
        L.append(f"- {view}: " + "; ".join(f"{m} {c['n']} ({', '.join(f'{k} {v}' for k, v in c['objects'].items())})"
                                           for m, c in gr.items()))
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    cfg, out, rec = start(Config, __file__, argv, __doc__)
    if not cfg.run or not (Path(cfg.run) / "results.json").is_file():
        print(f"study_e09_failures: --run must be an E09 output folder with results.json, got {cfg.run!r}",
              file=sys.stderr)
        return 2
    s = run(cfg)
    print(rec.write(out, s, readme_section))
    write_json(out / "failures.json", s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
